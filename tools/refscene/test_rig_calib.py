# Cross-check of the generator's rig (rigsim.py: lens model, its inverse, rig.yaml) against rhoscan's
# own (calib/rig.c, stitch.c): frames made by rigsim from a known sky must stitch back into that sky.
# SPDX-License-Identifier: BSD-3-Clause
"""Run: /usr/bin/python3 tools/refscene/test_rig_calib.py --bin BUILD_DIR   (ctest refscene_rig_calib)

Frames of the ladybug5 preset are filled the way render.py fills them (every pixel undistorted
by rigsim, then looked up), but from an analytic sky instead of a Cycles render, so no Blender
is needed; rhoscan-calib stitches them with the rig.yaml that rigsim writes. The stitched
panorama must match the analytic sky: a wrong pixel-centre, rotation or distortion convention on
either side shows as a shift or a smear far above the threshold.
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rigsim   # noqa: E402


def sky(d):
    """A smooth sky with detail down to about 10 degrees, any direction array (..., 3)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    v = 1.0 + 0.35 * np.sin(3 * x + 2 * y + 1) * np.cos(2 * z) + 0.2 * np.sin(7 * x - 5 * y + 4 * z) + 0.6 * z
    return np.stack([v, 0.8 * v + 0.1 * x, 0.6 * v + 0.1 * z], axis=-1)


def write_exr(path, img):
    h, w, c = img.shape
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(w, h, c, oiio.FLOAT))
    out.write_image(img.astype(np.float32))
    out.close()


def main(argv):
    if "--bin" not in argv:
        sys.exit("usage: test_rig_calib.py --bin BUILD_DIR")
    calib = os.path.join(argv[argv.index("--bin") + 1], "rhoscan-calib")
    if not os.access(calib, os.X_OK):
        sys.exit("test_rig_calib: %s: not found or not executable" % calib)
    cams = rigsim.ladybug5([256, 320], 130.0, rigsim.LADYBUG5["dist"], 0.0)
    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "rig.yaml"), "w") as f:
            f.write(rigsim.rig_yaml(cams))
        frames = []
        for k, c in enumerate(cams):
            a, b, ok = rigsim.frame_rays(c)
            dc = np.stack([a, b, np.ones_like(a)], axis=-1)
            dc /= np.linalg.norm(dc, axis=-1)[..., None]
            dr = dc @ np.array(c["R"]).reshape(3, 3).T          # camera -> rig
            img = np.where(ok[..., None], sky(dr), 0.0)
            frames.append("cam_%d.exr" % k)
            write_exr(os.path.join(d, frames[-1]), img)
        w = 512
        with open(os.path.join(d, "calib.ini"), "w") as f:
            f.write("[pipeline]\nworkdir = work\n[rig]\nfile = rig.yaml\nframes = %s\nwidth = %d\ngain = false\n"
                    % (" ".join(frames), w))
        run = subprocess.run([calib, os.path.join(d, "calib.ini")], capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit("test_rig_calib: rhoscan-calib failed (%d): %s" % (run.returncode, run.stderr))
        pano = oiio.ImageBuf(os.path.join(d, "work", "pano_stitched.exr")).get_pixels(oiio.FLOAT)[..., :3]
    h = w // 2
    r, c = np.mgrid[0:h, 0:w].astype(float)

    def pano_dirs(col, row):       # docs/DESIGN.md, section Frames
        phi, theta = math.pi * (1 - 2 * (col + 0.5) / w), math.pi * (row + 0.5) / h
        return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    truth = sky(pano_dirs(c, r))
    theta = math.pi * (r + 0.5) / h
    covered = np.isfinite(pano).all(-1) & (pano.sum(-1) > 0)
    area = float((covered * np.sin(theta)).sum() / np.sin(theta).sum())     # share of the sphere
    err = np.abs(pano - truth)[covered]
    rel = float(err.mean() / np.abs(truth[covered]).mean())
    psnr = 10 * math.log10(float(truth[covered].max()) ** 2 / float((err ** 2).mean()))
    # For scale: the error that half a panorama pixel of shift would give on the same pixels.
    half_pixel_rel = float(np.abs(sky(pano_dirs(c + 0.5, r)) - truth)[covered].mean() / np.abs(truth[covered]).mean())
    print("refscene_rig_calib: %.1f %% of the sphere covered, mean relative error %.5f (half a pixel's shift: "
          "%.5f), PSNR %.1f dB" % (100 * area, rel, half_pixel_rel, psnr))
    if not (area > 0.88 and rel < half_pixel_rel / 4 and psnr > 50):
        sys.exit("test_rig_calib: the stitched rig frames do not reproduce the sky (expected more than 88 %% of the "
                 "sphere covered, mean relative error < %.5f, a quarter of a half-pixel shift's, PSNR > 50 dB)"
                 % (half_pixel_rel / 4))


if __name__ == "__main__":
    main(sys.argv[1:])
