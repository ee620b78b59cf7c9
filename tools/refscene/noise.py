# The Monte Carlo noise of a rendered truth: two renders of one scene with different seeds give the
# per-pixel and per-facet relative noise of pano.exr, and the sample count that reaches a target;
# one render gives an estimate from adjacent pixels inside one face (--adjacent).
# SPDX-License-Identifier: BSD-3-Clause
"""Run with Debian's python3 (numpy, OpenImageIO), no Blender:

    /usr/bin/python3 tools/refscene/noise.py DIR_A DIR_B [--samples N] [--target 0.005] [--block 6]
    /usr/bin/python3 tools/refscene/noise.py --adjacent DIR [--samples N] [--target 0.005]

DIR_A and DIR_B: render.py outputs of the same scene and sample count, different --seed.
Noise of one render = std(a - b) / sqrt(2), relative to the mean of (a + b) / 2, on the grey
value (mean of R, G, B):
  model     over every pixel whose ray hits the model (diffcol > 0), edges included;
  interior  over pixels whose diffcol equals all 8 neighbours' (inside one face);
  facet     over means of B x B interior blocks (a facet of about B^2 pixels: what one albedo sees).
--adjacent DIR: one render. For pairs of horizontally adjacent interior pixels of one face, the
robust spread (1.4826 MAD / sqrt 2) of their relative difference, for pano.exr, diffdir + diffind
and diffind alone (the light varies slowly inside a face, the noise from pixel to pixel; about
0.47 % on sample_data/two_planes against 0.38-0.67 % from a second seed).
With --samples N the script also prints the samples each needs for --target by the 1/sqrt(N) law.
"""
import sys

import numpy as np
import OpenImageIO as oiio


def read(path):
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or buf.has_error:
        sys.exit("noise: %s: cannot read: %s" % (path, buf.geterror()))
    return px[..., :3].astype(np.float64)


def interior(col):
    ok = np.any(col > 0, axis=-1)
    p = np.pad(col, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = col.shape[:2]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ok &= np.all(np.abs(p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] - col) < 1e-3, axis=-1)
    return ok


def rel_noise(a, b):
    return float(np.std(a - b) / np.sqrt(2) / np.mean(0.5 * (a + b)))


def adjacent_noise(d):
    """Per-pixel relative noise of one render from horizontally adjacent interior pixels."""
    col = read(d + "/pano_diffcol.exr")
    inner = interior(col)
    pair = inner[:, :-1] & inner[:, 1:]
    out = []
    for name, img in (("pano", read(d + "/pano.exr")),
                      ("diffdir+diffind", read(d + "/pano_diffdir.exr") + read(d + "/pano_diffind.exr")),
                      ("diffind", read(d + "/pano_diffind.exr"))):
        g = img.mean(axis=-1)
        a, b = g[:, :-1][pair], g[:, 1:][pair]
        keep = (a + b) > 0
        r = (a - b)[keep] / (0.5 * (a + b)[keep])
        out.append((name, int(keep.sum()), float(1.4826 * np.median(np.abs(r - np.median(r))) / np.sqrt(2))))
    return out


def main(argv):
    if argv and argv[0] == "--adjacent":
        if len(argv) < 2:
            sys.exit(__doc__)
        samples = float(argv[argv.index("--samples") + 1]) if "--samples" in argv else None
        target = float(argv[argv.index("--target") + 1]) if "--target" in argv else 0.005
        for name, n, v in adjacent_noise(argv[1]):
            line = "%-16s %7d pairs  relative noise %.4f" % (name, n, v)
            if samples:
                line += "  -> %.0f samples for %.3g" % (samples * (v / target) ** 2, target)
            print(line)
        return
    args, samples, target, block = [], None, 0.005, 6
    i = 0
    while i < len(argv):
        if argv[i] in ("--samples", "--target", "--block") and i + 1 < len(argv):
            v = float(argv[i + 1])
            if argv[i] == "--samples":
                samples = v
            elif argv[i] == "--target":
                target = v
            else:
                block = int(v)
            i += 2
        else:
            args.append(argv[i])
            i += 1
    if len(args) != 2:
        sys.exit(__doc__)
    a, b = (read(d + "/pano.exr").mean(axis=-1) for d in args)
    col = read(args[0] + "/pano_diffcol.exr")
    model = np.any(col > 0, axis=-1)
    inner = interior(col)
    h, w = (s // block for s in inner.shape)
    blocks = inner[:h * block, :w * block].reshape(h, block, w, block).all(axis=(1, 3))
    # A block counts as one facet when it is interior and all its pixels share one diffcol value.
    cb = col[:h * block, :w * block].reshape(h, block, w, block, 3)
    blocks &= (np.ptp(cb, axis=(1, 3)) < 1e-3).all(axis=-1)

    def bmean(x):
        return x[:h * block, :w * block].reshape(h, block, w, block).mean(axis=(1, 3))
    rows = [("model", model.sum(), rel_noise(a[model], b[model])),
            ("interior", inner.sum(), rel_noise(a[inner], b[inner])),
            ("facet %dx%d" % (block, block), blocks.sum(), rel_noise(bmean(a)[blocks], bmean(b)[blocks]))]
    for name, n, v in rows:
        line = "%-12s %7d values  relative noise %.4f" % (name, n, v)
        if samples:
            line += "  -> %.0f samples for %.3g" % (samples * (v / target) ** 2, target)
        print(line)


if __name__ == "__main__":
    main(sys.argv[1:])
