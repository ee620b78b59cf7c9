# Checks a rendered reference scene: the pass identity pano = diffcol * (diffdir + diffind),
# and optionally the difference to another rendering of the same scene (a reference or a re-seeded run).
# SPDX-License-Identifier: BSD-3-Clause
"""Run inside Blender (reads EXR through Blender's image loader, needs numpy):

    blender -b --factory-startup --python tools/refscene/check.py -- DIR [OTHER_DIR] [--block N]

Prints, for DIR:
  identity   on interior pixels (diffcol constant over the 3x3 neighbourhood, non-zero):
             median and 99th percentile of |pano - diffcol (diffdir + diffind)| / pano.
With OTHER_DIR (same scene, other samples or seed; images may differ in size only by an integer factor):
  pano       mean |a - b| / mean(b) per pixel over all pixels, on the model and on the sky;
  pano/N     the same after averaging N x N blocks (noise averages out, a wrong mapping does not);
  env        the same for env.exr;
  diffcol    largest difference (edges show a different pixel filter);
  part noise per part (diffcol colour classes): relative difference of the mean of
             diffdir + diffind, and per-pixel spread std(a - b) / mean / sqrt(2) (the noise of one run).
"""
import sys

import bpy
import numpy as np


def read_exr(path):
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)   # row 0 at the top


def block(a, n):
    h, w = a.shape[0] // n, a.shape[1] // n
    return a[:h * n, :w * n].reshape(h, n, w, n, -1).mean(axis=(1, 3))


def rel(a, b, mask=None):
    d = np.abs(a - b)
    if mask is not None:
        d, b = d[mask], b[mask]
    return float(d.mean() / max(np.abs(b).mean(), 1e-30))


def interior(col):
    """Pixels whose diffcol equals all 8 neighbours' and is non-zero (fully inside one facet)."""
    ok = np.any(col > 0, axis=-1)
    p = np.pad(col, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = col.shape[:2]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ok &= np.all(np.abs(p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] - col) < 1e-3, axis=-1)
    ok[0, :] = ok[-1, :] = False
    return ok


def check_identity(d):
    pano = read_exr(d + "/pano.exr")
    col = read_exr(d + "/pano_diffcol.exr")
    lit = read_exr(d + "/pano_diffdir.exr") + read_exr(d + "/pano_diffind.exr")
    m = interior(col)
    m &= np.all(pano > 1e-6, axis=-1)
    r = (np.abs(pano - col * lit) / np.maximum(pano, 1e-30))[m]
    print("identity: %d interior pixels, |pano - diffcol (diffdir + diffind)| / pano: "
          "median %.5f, p99 %.5f, max %.5f" % (m.sum(), np.median(r), np.percentile(r, 99), r.max()))


def downsize(a, shape):
    n = a.shape[0] // shape[0]
    return block(a, n) if n > 1 else a


def compare(d, o, nblock):
    pa, pb = read_exr(d + "/pano.exr"), read_exr(o + "/pano.exr")
    ca, cb = read_exr(d + "/pano_diffcol.exr"), read_exr(o + "/pano_diffcol.exr")
    shape = tuple(np.minimum(pa.shape[:2], pb.shape[:2]))
    pa, pb, ca, cb = (downsize(x, shape) for x in (pa, pb, ca, cb))
    model = np.any(cb > 0, axis=-1)
    print("pano: mean relative difference %.4f (model %.4f, sky %.4f)"
          % (rel(pa, pb), rel(pa, pb, model), rel(pa, pb, ~model)))
    print("pano/%d: %.4f (model %.4f, sky %.4f)" % (
        nblock, rel(block(pa, nblock), block(pb, nblock)),
        rel(block(pa, nblock), block(pb, nblock), block(model[..., None] * 1.0, nblock)[..., 0] == 1),
        rel(block(pa, nblock), block(pb, nblock), block(model[..., None] * 1.0, nblock)[..., 0] == 0)))
    ea, eb = read_exr(d + "/env.exr"), read_exr(o + "/env.exr")
    ea, eb = downsize(ea, shape), downsize(eb, shape)
    print("env: mean relative difference %.4f" % rel(ea, eb))
    print("diffcol: max difference %.4f, pixels differing by > 0.01: %d"
          % (np.abs(ca - cb).max(), int(np.any(np.abs(ca - cb) > 0.01, axis=-1).sum())))
    la = read_exr(d + "/pano_diffdir.exr") + read_exr(d + "/pano_diffind.exr")
    lb = read_exr(o + "/pano_diffdir.exr") + read_exr(o + "/pano_diffind.exr")
    la, lb = downsize(la, shape), downsize(lb, shape)
    inner = interior(cb) & interior(ca)
    colours = np.unique(np.round(cb[inner], 3), axis=0)
    for c in colours:
        m = inner & np.all(np.abs(cb - c) < 1e-3, axis=-1)
        if m.sum() < 100:
            continue
        a, b = la[m].sum(axis=-1), lb[m].sum(axis=-1)
        print("part albedo %s: %d px, mean irradiance/pi %.4f vs %.4f (rel. diff %.4f), "
              "per-pixel noise of one run %.4f" % (
                  tuple(c), m.sum(), a.mean(), b.mean(), abs(a.mean() - b.mean()) / b.mean(),
                  (a - b).std() / b.mean() / np.sqrt(2)))


def main():
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    nblock = 16
    if "--block" in args:
        k = args.index("--block")
        nblock = int(args[k + 1])
        del args[k:k + 2]
    if len(args) not in (1, 2):
        print("usage: blender -b --python check.py -- DIR [OTHER_DIR] [--block N]", file=sys.stderr)
        sys.exit(1)
    check_identity(args[0])
    if len(args) == 2:
        compare(args[0], args[1], nblock)


if __name__ == "__main__":
    main()
