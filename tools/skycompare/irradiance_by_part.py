#!/usr/bin/env python3
"""E_sky, G and E_sky + G of a run against Cycles' passes, per part of a tools/refscene scene.

usage: irradiance_by_part.py --shared SHARED SCENE_DIR WORK_DIR [WORK_DIR...]

SCENE_DIR is a tools/refscene output (truth.ply, pano_diffdir.exr, pano_diffind.exr); each
WORK_DIR is a run's work folder on that scene's camera (albedo.ply, facet_id.exr). As in
rhoscan-eval, the truth per facet is the mean over the facet's pixels of pi DiffDir (E_sky) and
pi DiffInd (G), channel means; facets seen on at least 4 pixels and estimable count, weighted by
their pixels. Printed per part: the mean relative error and the bias (ratio of the weighted sums
minus 1) of each, and the truth's interreflected share. Parts come from the nearest point of
truth.ply within 0.15 m of each facet's centroid (sky_compare.match_truth, the shared
evaluator's matching).

Cycles counts light from surfaces in DiffInd, rhoscan counts light from the sky map (including
the ground beyond the model, held there) in E_sky: a model that lacks geometry the scene has
shows E_sky high and G low by the same light, while E_sky + G stays right.
"""
import argparse, os, sys

import numpy as np


def image(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        sys.exit('FAIL: cannot read %s' % path)
    return px.reshape(-1, px.shape[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--shared', required=True)
    ap.add_argument('scene')
    ap.add_argument('work', nargs='+')
    a = ap.parse_args()
    sys.path.insert(0, os.path.join(a.shared, 'tools'))
    from plyio import read_ply, faces_of
    from sky_compare import MATCH_M, match_truth   # the facet-to-truth matching sky_compare uses
    truth = read_ply(os.path.join(a.scene, 'truth.ply'))
    dd = np.pi * image(os.path.join(a.scene, 'pano_diffdir.exr'))[:, :3].mean(1)
    di = np.pi * image(os.path.join(a.scene, 'pano_diffind.exr'))[:, :3].mean(1)
    for work in a.work:
        res = read_ply(os.path.join(work, 'albedo.ply'))
        fp = res['face']
        rv = np.stack([res['vertex'][c] for c in 'xyz'], 1)
        cen = rv[np.array(faces_of(res))].mean(1)
        dist, tf = match_truth(a.shared, truth, cen)
        part = np.where(dist < MATCH_M, truth['face']['part'][tf], -1)
        ids = image(os.path.join(work, 'facet_id.exr'))[:, 0]
        if ids.size != dd.size:
            sys.exit('FAIL: %s/facet_id.exr is not the size of the scene\'s passes' % work)
        nf = len(cen)
        seen = (ids >= 0) & (ids < nf) & np.isfinite(dd) & np.isfinite(di)
        f = ids[seen].astype(int)
        n = np.bincount(f, minlength=nf)
        t_sky = np.bincount(f, dd[seen], nf) / np.maximum(n, 1)
        t_g = np.bincount(f, di[seen], nf) / np.maximum(n, 1)
        e_sky = sum(fp['irradiance_sky_' + c] for c in 'rgb') / 3
        e_g = sum(fp['irradiance_inter_' + c] for c in 'rgb') / 3
        ok = (n >= 4) & (fp['estimable'] > 0) & np.isfinite(e_sky + e_g)
        print(work)
        for p in sorted(set(part[ok]) - {-1}):
            m = ok & (part == p)
            w = n[m]

            def err(est, tru):
                return (np.sum(np.abs(est - tru) / np.maximum(tru, 1e-9) * w) / w.sum(),
                        np.sum(est * w) / np.sum(tru * w) - 1)
            rows = (err(e_sky[m], t_sky[m]), err(e_g[m], t_g[m]), err(e_sky[m] + e_g[m], t_sky[m] + t_g[m]))
            share = np.sum(t_g[m] * w) / np.sum((t_sky[m] + t_g[m]) * w)
            print('  part %d (%d facets): E_sky %.1f %% (bias %+.1f %%)  G %.1f %% (bias %+.1f %%)  '
                  'E_sky + G %.1f %% (bias %+.1f %%)  interreflected %.0f %%'
                  % (p, m.sum(), 100 * rows[0][0], 100 * rows[0][1], 100 * rows[1][0], 100 * rows[1][1],
                     100 * rows[2][0], 100 * rows[2][1], 100 * share))


if __name__ == '__main__':
    main()
