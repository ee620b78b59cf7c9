#!/usr/bin/python3
# cut_views: pinhole views cut from equirectangular panoramas for COLMAP, with each view's rotation
# into its panorama's frame written to views.txt (the file the calib stage's [colmap] views reads).
"""For each panorama PANO.exr, cuts N views around the horizon (90 deg field of view by default,
pitched down a little so that the ground's texture is in them) as 8-bit sRGB PNGs named
OUTDIR/images/PANO_vK.png, with bilinear lookup in the convention of docs/DESIGN.md,
section Frames.

The view camera is COLMAP's PINHOLE (x right, y down, z forward; pixel centres at 0.5, so the
principal point is (size / 2, size / 2)) with f = size / 2 / tan(fov / 2). views.txt:
    NAME PANORAMA R00 R01 ... R22
R takes the view camera's frame to the panorama's local frame (row-major); the view's centre is
the panorama's. OUTDIR/views.txt and OUTDIR/camera.txt sit beside images/ (COLMAP reads every
file of its image folder); camera.txt holds the intrinsics as COLMAP's --ImageReader.camera_params wants them.

Usage: cut_views.py OUTDIR PANO.exr... [--views 8] [--size 512] [--fov 90] [--pitch -10]
"""
import argparse
import math
import os
import sys

import numpy as np
import OpenImageIO as oiio


def read_exr(path):
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise SystemExit("cut_views.py: %s: cannot open: %s" % (path, oiio.geterror()))
    img = inp.read_image(oiio.FLOAT)
    inp.close()
    return np.asarray(img)[:, :, :3]


def cam_to_local(yaw_deg, pitch_deg):
    """Columns: the camera's right, down and forward axes in the panorama's local frame."""
    a, b = math.radians(yaw_deg), math.radians(pitch_deg)
    fwd = np.array([math.cos(b) * math.cos(a), math.cos(b) * math.sin(a), math.sin(b)])
    right = np.array([math.sin(a), -math.cos(a), 0.0])
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd], axis=1)


def bilinear(img, col, row):
    """Samples img at continuous pixel coordinates (pixel centres at integers), wrapping in azimuth."""
    h, w = img.shape[:2]
    c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
    fc, fr = (col - c0)[..., None], (row - r0)[..., None]
    r0c, r1c = np.clip(r0, 0, h - 1), np.clip(r0 + 1, 0, h - 1)
    c0w, c1w = c0 % w, (c0 + 1) % w
    return ((1 - fr) * ((1 - fc) * img[r0c, c0w] + fc * img[r0c, c1w])
            + fr * ((1 - fc) * img[r1c, c0w] + fc * img[r1c, c1w]))


def srgb8(x):
    x = np.clip(x, 0, 1)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(y * 255).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir")
    ap.add_argument("panoramas", nargs="+")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--fov", type=float, default=90.0)
    ap.add_argument("--pitch", type=float, default=-10.0)
    a = ap.parse_args()
    imgdir = os.path.join(a.outdir, "images")
    os.makedirs(imgdir, exist_ok=True)
    f = a.size / 2 / math.tan(math.radians(a.fov) / 2)
    cx = a.size / 2
    jj, ii = np.meshgrid(np.arange(a.size) + 0.5, np.arange(a.size) + 0.5)   # x (column), y (row)
    ray = np.stack([(jj - cx) / f, (ii - cx) / f, np.ones_like(jj)], axis=-1)
    lines = ["# cut_views.py: NAME PANORAMA R00..R22 (view camera x right, y down, z forward -> panorama local)"]
    for pano_path in a.panoramas:
        label = os.path.splitext(os.path.basename(pano_path))[0]
        img = read_exr(pano_path)
        h, w = img.shape[:2]
        exposure = 0.18 / max(float(np.median(img)), 1e-12)   # one exposure per panorama, like one camera
        for k in range(a.views):
            rot = cam_to_local(360.0 * k / a.views, a.pitch)
            d = ray @ rot.T
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            phi = np.arctan2(d[..., 1], d[..., 0])
            theta = np.arccos(np.clip(d[..., 2], -1, 1))
            u, v = (1 - phi / math.pi) / 2, theta / math.pi
            view = bilinear(img, u * w - 0.5, v * h - 0.5)
            name = "%s_v%d.png" % (label, k)
            out = oiio.ImageOutput.create(os.path.join(imgdir, name))
            out.open(os.path.join(imgdir, name), oiio.ImageSpec(a.size, a.size, 3, oiio.UINT8))
            out.write_image(srgb8(view * exposure))
            out.close()
            lines.append("%s %s %s" % (name, label, " ".join("%.17g" % x for x in rot.ravel())))
    with open(os.path.join(a.outdir, "views.txt"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    with open(os.path.join(a.outdir, "camera.txt"), "w") as fh:
        fh.write("%.17g,%.17g,%.17g,%.17g\n" % (f, f, cx, cx))
    return 0


if __name__ == "__main__":
    sys.exit(main())
