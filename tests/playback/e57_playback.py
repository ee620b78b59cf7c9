#!/usr/bin/env python3
"""E57 playback: a shared reference scene's scan written to E57 (tools/e57write: the scan with its
pose and grid) runs through the whole pipeline and gives a byte-identical albedo.ply to the run
from its PTX. Then the scene's panorama, scaled below white and quantised to an 8-bit sRGB PNG,
is embedded in the E57 file as a spherical image with the camera's pose, and the run whose capture
is taken from it ([capture] panorama = FILE.e57, e57_image) must give the same albedo.ply as the
run given the same PNG, position and rotation as ordinary files (E57 images are 8-bit; real
captures keep the HDR panorama an EXR).
Exit 0 on success, 1 on failure, 77 (skip) when the shared data is absent and CI is not set.
"""
import argparse, json, math, os, shutil, subprocess, sys, tempfile


def skip_or_fail(msg):
    if os.environ.get('CI') == 'true':
        print('FAIL: ' + msg + ' (CI=true requires it)'); sys.exit(1)
    print('SKIP: ' + msg); sys.exit(77)


def run(rhoscan, tmp, name, scan, capture):
    work = os.path.join(tmp, name)
    cfg = os.path.join(tmp, name + '.ini')
    with open(cfg, 'w') as fh:
        fh.write('[pipeline]\nworkdir = %s\n[ingest]\nscan = %s\n[capture]\n%s' % (work, scan, capture))
    r = subprocess.run([rhoscan, 'run', cfg], capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        print('FAIL: rhoscan run (%s) exited %d' % (name, r.returncode)); sys.exit(1)
    return open(os.path.join(work, 'albedo.ply'), 'rb').read(), r.stderr


def quaternion(R):
    """w x y z of a rotation matrix (rows), as tools/e57write and the tests compute it."""
    tr = R[0][0] + R[1][1] + R[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1) * 2
        return [s / 4, (R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s]
    if R[0][0] > R[1][1] and R[0][0] > R[2][2]:
        s = math.sqrt(1 + R[0][0] - R[1][1] - R[2][2]) * 2
        return [(R[2][1] - R[1][2]) / s, s / 4, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s]
    if R[1][1] > R[2][2]:
        s = math.sqrt(1 + R[1][1] - R[0][0] - R[2][2]) * 2
        return [(R[0][2] - R[2][0]) / s, (R[0][1] + R[1][0]) / s, s / 4, (R[1][2] + R[2][1]) / s]
    s = math.sqrt(1 + R[2][2] - R[0][0] - R[1][1]) * 2
    return [(R[1][0] - R[0][1]) / s, (R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, s / 4]


def rotation(q):
    """The matrix (row-major, 9 numbers) the E57 reader makes of q (common/e57_xml.c, e57_pose),
    in the same floating-point operations, so that both runs get the same pose."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if n != 1:
        w, x, y, z = w / n, x / n, y / n, z / n
    return [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]


def write_png8(exr, png):
    """exr scaled so that its brightest pixel is 0.9, as 8-bit sRGB codes (none at 255)."""
    import numpy as np
    import OpenImageIO as oiio
    px = oiio.ImageBuf(exr).get_pixels(oiio.FLOAT)[:, :, :3]
    v = np.clip(px * (0.9 / px.max()), 0, 1)
    srgb = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    codes = np.clip(np.floor(srgb * 255 + 0.5), 0, 254).astype(np.uint8)
    out = oiio.ImageOutput.create(png)
    out.open(png, oiio.ImageSpec(codes.shape[1], codes.shape[0], 3, 'uint8'))
    out.write_image(codes)
    out.close()


def compare(a, b, what):
    if a != b:
        print('FAIL: %s: albedo.ply differs (%d and %d bytes)' % (what, len(a), len(b)))
        return False
    print('%s: albedo.ply identical (%d bytes)' % (what, len(a)))
    return True


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--shared', default=os.environ.get('RHOSCAN_SHARED_DIR', ''))
    ap.add_argument('--scene', default='two_planes_sky')
    ap.add_argument('--keep', help='work folder to keep (default: a temporary one)')
    args = ap.parse_args()
    scene = os.path.normpath(os.path.abspath(os.path.join(args.shared, 'reference', args.scene)))
    if not args.shared or not os.path.isdir(scene):
        skip_or_fail('reference scene %s is missing' % scene)
    tmp = args.keep or tempfile.mkdtemp(prefix='rhoscan-e57-')
    os.makedirs(tmp, exist_ok=True)
    truth = json.load(open(os.path.join(scene, 'truth.json')))
    rot = ' '.join('%.17g' % v for row in truth['camera_rotation_local_to_world'] for v in row)
    pos = ' '.join('%.17g' % v for v in truth['camera_position'])
    rhoscan = os.path.join(args.bin, 'rhoscan')
    ptx = os.path.join(scene, 'scan.ptx')
    e57 = os.path.join(tmp, 'scan.e57')
    r = subprocess.run([os.path.join(args.bin, 'e57write'), ptx, e57])
    if r.returncode != 0:
        print('FAIL: e57write exited %d' % r.returncode); sys.exit(1)
    capture = 'panorama = %s\nposition = %s\nrotation = %s\n' % (os.path.join(scene, 'pano.exr'), pos, rot)
    a, _ = run(rhoscan, tmp, 'ptx', ptx, capture)
    b, log = run(rhoscan, tmp, 'e57', e57, capture)
    ok = True
    if '(E57)' not in log:
        print('FAIL: the E57 run did not read the scan as E57'); ok = False
    ok &= compare(a, b, 'scan from E57 against PTX')

    # The panorama as an 8-bit spherical image in the E57 file, against the same PNG as a file.
    png = os.path.join(tmp, 'pano8.png')
    write_png8(os.path.join(scene, 'pano.exr'), png)
    q = quaternion(truth['camera_rotation_local_to_world'])
    e57img = os.path.join(tmp, 'scan_pano.e57')
    r = subprocess.run([os.path.join(args.bin, 'e57write'), '--image', png, '--image-name', 'pano', '--image-pose',
                        ' '.join('%.17g' % v for v in q + truth['camera_position']), ptx, e57img])
    if r.returncode != 0:
        print('FAIL: e57write --image exited %d' % r.returncode); sys.exit(1)
    rot_e57 = ' '.join('%.17g' % v for v in rotation(q))
    c, _ = run(rhoscan, tmp, 'png', e57img, 'panorama = %s\nposition = %s\nrotation = %s\n' % (png, pos, rot_e57))
    d, log = run(rhoscan, tmp, 'e57_pano', e57img, 'panorama = %s\ne57_image = pano\n' % e57img)
    if 'linearised with the sRGB curve' not in log:
        print('FAIL: the E57 capture did not warn that it used the sRGB curve'); ok = False
    ok &= compare(c, d, 'capture from the E57 image against the PNG and pose as files')
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    print('PASS' if ok else 'FAIL')
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
