#!/usr/bin/env python3
"""E57 playback: a shared reference scene's scan written to E57 (tools/e57write: the scan with its
pose and grid) runs through the whole pipeline and gives a byte-identical albedo.ply to the run
from its PTX. With --image, the scene's panorama is also embedded in the E57 file as an 8-bit
spherical PNG with its pose, and the capture taken from it ([capture] panorama = FILE.e57,
e57_image) must give the same albedo.ply as the same PNG and pose given as ordinary files.
Exit 0 on success, 1 on failure, 77 (skip) when the shared data is absent and CI is not set.
"""
import argparse, json, os, shutil, subprocess, sys, tempfile


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
    if a != b:
        print('FAIL: albedo.ply from E57 (%d bytes) differs from the one from PTX (%d bytes)' % (len(b), len(a)))
        ok = False
    else:
        print('albedo.ply from E57 equals the one from PTX (%d bytes)' % len(a))
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    print('PASS' if ok else 'FAIL')
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
