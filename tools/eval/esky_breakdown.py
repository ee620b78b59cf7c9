#!/usr/bin/python3
# Breaks rhoscan-eval's E_sky figure (per-facet E_sky against pi DiffDir, pixel-weighted) down by
# cause: which facets carry the error, signed or not, lit or shaded, at silhouettes or inside.
# SPDX-License-Identifier: BSD-3-Clause
"""usage: tools/eval/esky_breakdown.py TRUTH_DIR WORKDIR [WORKDIR2]

Per facet seen on >= 4 pixels and estimable (as rhoscan-eval): est = mean RGB of irradiance_sky,
tru = mean over its pixels of pi DiffDir. Prints the metric (pixel-weighted mean |rel error|) and
its split: by truth part, by whether the facet has pixels next to another facet's truth part or
the sky (edge), by sun-lit / shaded (tru against the part's median), and the signed bias. With
WORKDIR2 (a second run on the same mesh, e.g. another seed or 4 x samples): the Monte Carlo part
of the figure from the difference of the two runs' E_sky.
"""
import os
import sys

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'tests', 'playback'))
from plyread import read_ply  # noqa: E402


def img(path):
    b = oiio.ImageBuf(path)
    return b.get_pixels(oiio.FLOAT)


def facet_stats(truth, work):
    ids = img(os.path.join(work, 'facet_id.exr'))[..., 0]
    dd = img(os.path.join(truth, 'pano_diffdir.exr'))[..., :3]
    dc = img(os.path.join(truth, 'pano_diffcol.exr'))[..., :3]
    irr = read_ply(os.path.join(work, 'irradiance.ply'))['face']
    alb = read_ply(os.path.join(work, 'albedo.ply'))['face']
    nf = len(irr['irradiance_sky_r'])
    esky = (irr['irradiance_sky_r'] + irr['irradiance_sky_g'] + irr['irradiance_sky_b']) / 3
    good = (alb['observed'] > 0) & (alb['estimable'] > 0)
    valid = (ids >= 0) & (ids < nf) & np.isfinite(dd.sum(-1))
    f = ids[valid].astype(np.int64)
    ddm = np.pi * dd[valid].mean(-1)
    n = np.bincount(f, minlength=nf).astype(float)
    sdd = np.bincount(f, ddm, minlength=nf)
    # edge facets: some pixel of the facet has a 4-neighbour of another albedo (another truth
    # part, or the sky), i.e. its truth pixels straddle a boundary the mesh may not follow
    key = np.round(dc.sum(-1), 4)
    diff = np.zeros(ids.shape, bool)
    for ax, sh in ((0, 1), (0, -1), (1, 1), (1, -1)):
        diff |= np.roll(key, sh, axis=ax) != key
    edge = np.bincount(f, diff[valid].astype(float), minlength=nf) > 0
    sel = (n >= 4) & good & np.isfinite(esky)
    m = read_ply(os.path.join(work, 'mesh.ply'))
    V = np.stack([m['vertex']['x'], m['vertex']['y'], m['vertex']['z']], 1)
    T = m['face']['vertex_indices'].astype(np.int64)
    nrm = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    nz = nrm[:, 2] / np.maximum(np.linalg.norm(nrm, axis=1), 1e-30)
    tru = np.where(n > 0, sdd / np.maximum(n, 1), 0)
    return dict(esky=esky, tru=tru, n=n, sel=sel, edge=edge, nf=nf, nz=nz)


def metric(s, mask):
    m = s['sel'] & mask
    w = s['n'][m]
    if w.sum() == 0:
        return float('nan'), float('nan'), 0.0
    rel = np.abs(s['esky'][m] - s['tru'][m]) / np.maximum(s['tru'][m], 1e-9)
    bias = (s['esky'][m] * w).sum() / (s['tru'][m] * w).sum() - 1
    return (rel * w).sum() / w.sum(), bias, w.sum()


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    truth, work = sys.argv[1], sys.argv[2]
    s = facet_stats(truth, work)
    W = s['n'][s['sel']].sum()
    total, bias, _ = metric(s, np.ones(s['nf'], bool))
    print('facets %d selected, %d pixels; E_sky rel %.4f bias %+.4f' % (s['sel'].sum(), W, total, bias))
    # contribution of each group to the total figure (pixel share x group mean)
    med = np.median(s['tru'][s['sel']])
    groups = [('edge (pixels next to another part or sky)', s['edge']), ('inside', ~s['edge']),
              ('lit (tru > median)', s['tru'] > med), ('shaded (tru <= median)', s['tru'] <= med),
              ('facing up (n_z > 0.5)', s['nz'] > 0.5), ('walls (|n_z| <= 0.5)', np.abs(s['nz']) <= 0.5),
              ('facing down (n_z < -0.5)', s['nz'] < -0.5),
              ('inside, not facing down', ~s['edge'] & (s['nz'] >= -0.5))]
    for name, mask in groups:
        r, b, w = metric(s, mask)
        print('  %-44s share %5.1f %%  rel %.4f  bias %+.4f  contributes %.4f' % (name, 100 * w / W, r, b, r * w / W))
    m = s['sel']
    rel = np.abs(s['esky'][m] - s['tru'][m]) / np.maximum(s['tru'][m], 1e-9)
    w = s['n'][m]
    order = np.argsort(rel)
    cw = np.cumsum((rel * w)[order][::-1]) / (rel * w).sum()
    k = np.searchsorted(cw, 0.5) + 1
    print('  half of the figure comes from the worst %d facets (%.1f %% of the pixels)' %
          (k, 100 * w[order][::-1][:k].sum() / w.sum()))
    print('  pixel-weighted median rel %.4f' % np.median(np.repeat(rel, w.astype(int))))
    # the same errors against the mean truth instead of each facet's own: shaded facets no
    # longer weigh 10 to 100 times more per unit of error than sunlit ones
    print('  sum |est - tru| w / sum tru w (relative L1 against the mean) %.4f' %
          ((np.abs(s['esky'][m] - s['tru'][m]) * w).sum() / (s['tru'][m] * w).sum()))
    # the truth's own noise: Cycles' per-pixel relative noise (README: 0.8 % on tower) over a
    # facet's n pixels, E|N(0, s)| = s sqrt(2 / pi)
    px_noise = float(os.environ.get('TRUTH_PIXEL_NOISE', '0.008'))
    print('  truth noise (%.2f %% per pixel) adds about %.4f to the figure' %
          (100 * px_noise, (np.sqrt(2 / np.pi) * px_noise / np.sqrt(w) * w).sum() / w.sum()))
    if len(sys.argv) > 3:
        s2 = facet_stats(truth, sys.argv[3])
        both = s['sel'] & s2['sel']
        d = np.abs(s['esky'][both] - s2['esky'][both]) / np.maximum(s['tru'][both], 1e-9)
        w = s['n'][both]
        print('  run 2: E_sky rel %.4f; mean |E1 - E2| / tru %.4f (the MC noise of one run is this / sqrt 2 '
              'when both have the same count)' % (metric(s2, np.ones(s2['nf'], bool))[0], (d * w).sum() / w.sum()))


if __name__ == '__main__':
    main()
