#!/usr/bin/python3
"""texture_eval: the per-pixel evaluator of issue 22, part 5. Renders albedo.glb's texture into the
camera's panorama with rhoscan-texview (its own GLB reader and ray tracer, none of the texture
stage's code) and compares it with Cycles' albedo pass pano_diffcol.exr beside the scene.

  texture_eval.py --bin BUILD --scene SCENE_DIR --work WORKDIR [--json OUT] [--facets] [--parts]

Pixels: building pixels are those where pano_diffcol.exr is non-zero (the sky's is 0); a hole
is a building pixel where the asset has no surface. Per pixel relative error
|texture - diffcol|_1 / |diffcol|_1 over the channels. Classes from pano_diffdir.exr's
luminance D: in shadow where D < 0.4 x the largest D within 30 px (in sun otherwise); the
shadow-edge band: pixels within 1 px of a pixel of the other class (3 px wide). --facets
compares albedo.ply's per-facet colours in the same way (facet_id.exr), for scale. --parts adds
the figures per part of the truth (each pixel's part from its centre's ray against truth.ply's
triangles, `part` property; names from truth.json), under "parts" in the JSON.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np


def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise RuntimeError(buf.geterror())
    return buf.get_pixels(oiio.FLOAT)


def classes(diffdir, building):
    from scipy import ndimage
    d = diffdir[:, :, :3] @ np.array([0.2126, 0.7152, 0.0722])
    d = np.where(building, d, 0)
    local = ndimage.maximum_filter(d, size=61, mode='wrap')
    shadow = building & (d < 0.4 * local)
    sun = building & ~shadow
    k = np.ones((3, 3), bool)
    band = building & ((ndimage.binary_dilation(sun, k) & shadow) | (ndimage.binary_dilation(shadow, k) & sun))
    band = building & ndimage.binary_dilation(band, k)
    return sun, shadow, band


def stats(rel, mask):
    v = rel[mask]
    if not v.size:
        return {'pixels': 0, 'median': None, 'mean': None}
    return {'pixels': int(v.size), 'median': float(np.median(v)), 'mean': float(np.mean(v)),
            'p90': float(np.percentile(v, 90))}


def step(img, diffcol, mask):
    """Mean albedo shown over mean true albedo on mask, minus 1 (a step at a shadow edge shows as
    the sun side and the shadow side of the band differing)."""
    t, d = img[mask].sum(), diffcol[mask].sum()
    return float(t / d - 1) if d > 0 else None


def figures(img, hit, diffcol, building, sun, shadow, band):
    rel = np.abs(img - diffcol).sum(axis=2) / np.maximum(diffcol.sum(axis=2), 1e-6)
    seen = building & hit
    a, b = img[seen].mean(axis=1), diffcol[seen].mean(axis=1)
    out = {'building_pixels': int(building.sum()), 'holes': int((building & ~hit).sum()),
           'hole_share': float((building & ~hit).sum() / max(building.sum(), 1)),
           'all': stats(rel, seen), 'sun': stats(rel, seen & sun), 'shadow': stats(rel, seen & shadow),
           'shadow_edge_band': stats(rel, seen & band),
           'band_bias_sun_side': step(img, diffcol, seen & band & sun),
           'band_bias_shadow_side': step(img, diffcol, seen & band & shadow),
           'pattern_correlation': float(np.corrcoef(a, b)[0, 1]) if a.size > 1 else None}
    return out


def pixel_parts(scene, truth, w, h):
    """Index of the truth part each pixel's centre ray meets first (-1: none), panorama convention
    of truth.json, by Moeller-Trumbore against every triangle of truth.ply."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..', 'tests',
                                    'playback'))
    from plyread import read_ply
    ply = read_ply(os.path.join(scene, 'truth.ply'))
    v = np.stack([ply['vertex'][c] for c in 'xyz'], axis=1).astype(np.float64)
    f = ply['face']['vertex_indices'].astype(np.int64)
    part = ply['face']['part'].astype(np.int64)
    c, r = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    az, pol = np.pi * (1 - 2 * c / w), np.pi * r / h
    d = np.stack([np.sin(pol) * np.cos(az), np.sin(pol) * np.sin(az), np.cos(pol)], axis=-1).reshape(-1, 3)
    d = d @ np.asarray(truth['camera_rotation_local_to_world'], dtype=np.float64).T
    o = np.asarray(truth['camera_position'], dtype=np.float64)
    best = np.full(len(d), np.inf)
    out = np.full(len(d), -1, dtype=np.int64)
    for k, (a, b, cc) in enumerate(v[f]):
        e1, e2 = b - a, cc - a
        p = np.cross(d, e2)
        det = p @ e1
        with np.errstate(divide='ignore', invalid='ignore'):
            inv = 1.0 / det
            s = o - a
            uu = (p @ s) * inv
            q = np.cross(s, e1)
            vv = (d @ q) * inv
            t = (q @ e2) * inv
        hit = (np.abs(det) > 1e-12) & (uu >= 0) & (vv >= 0) & (uu + vv <= 1) & (t > 1e-6) & (t < best)
        best[hit] = t[hit]
        out[hit] = part[k]
    return out.reshape(h, w)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--scene', required=True)
    ap.add_argument('--work', required=True)
    ap.add_argument('--json')
    ap.add_argument('--facets', action='store_true')
    ap.add_argument('--parts', action='store_true')
    a = ap.parse_args()
    truth = json.load(open(os.path.join(a.scene, 'truth.json')))
    diffcol = read_exr(os.path.join(a.scene, 'pano_diffcol.exr'))[:, :, :3].astype(np.float64)
    diffdir = read_exr(os.path.join(a.scene, 'pano_diffdir.exr'))
    h, w = diffcol.shape[:2]
    pos = ' '.join('%.17g' % v for v in truth['camera_position'])
    rot = ' '.join('%.17g' % v for v in np.asarray(truth['camera_rotation_local_to_world']).ravel())
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, 'view.exr')
        r = subprocess.run([os.path.join(a.bin, 'rhoscan-texview'), os.path.join(a.work, 'albedo.glb'), str(w), str(h),
                            pos, rot, out], capture_output=True, text=True)
        if r.returncode != 0:
            print(r.stderr)
            return 1
        view = read_exr(out)
    building = diffcol.sum(axis=2) > 0
    sun, shadow, band = classes(diffdir, building)
    res = {'scene': os.path.basename(os.path.normpath(a.scene)),
           'texture': figures(view[:, :, :3].astype(np.float64), view[:, :, 3] > 0.5, diffcol, building, sun, shadow,
                              band)}
    if a.facets:
        sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..', 'tests',
                                        'playback'))
        from plyread import read_ply
        ids = read_exr(os.path.join(a.work, 'facet_id.exr'))[:, :, 0].astype(np.int64)
        f = read_ply(os.path.join(a.work, 'albedo.ply'))['face']
        rho = np.stack([f['albedo_' + c] for c in 'rgb'], axis=1).astype(np.float64)
        img = np.where((ids >= 0)[:, :, None], rho[np.maximum(ids, 0)], 0)
        res['facets'] = figures(img, ids >= 0, diffcol, building, sun, shadow, band)
    if a.parts:
        pp = pixel_parts(a.scene, truth, w, h)
        tex = view[:, :, :3].astype(np.float64)
        hit = view[:, :, 3] > 0.5
        res['parts'] = {}
        for i, p in enumerate(truth['parts']):
            m = pp == i
            if not (m & building).any():
                continue
            name = p.get('name', 'part%d' % i)
            res['parts'][name] = {'texture': figures(tex, hit, diffcol, building & m, sun, shadow, band)}
            if a.facets:
                res['parts'][name]['facets'] = figures(img, ids >= 0, diffcol, building & m, sun, shadow, band)
    rows = [(res['scene'], k, res[k]) for k in ('texture', 'facets') if k in res]
    for name, d in res.get('parts', {}).items():
        rows += [('  ' + name, k, d[k]) for k in ('texture', 'facets') if k in d]
    for scene_name, k, t in rows:
        def pc(s):
            return '%5.2f %%' % (100 * s['median']) if s['median'] is not None else '   -   '
        print('%s %-8s median rel. error: all %s, sun %s, shadow %s, shadow-edge band %s; mean all %.2f %%; '
              'holes %.3f %%; band bias sun side %+.2f %%, shadow side %+.2f %%; correlation with the truth %.3f' %
              (scene_name, k, pc(t['all']), pc(t['sun']), pc(t['shadow']), pc(t['shadow_edge_band']),
               100 * (t['all']['mean'] or 0), 100 * t['hole_share'], 100 * (t['band_bias_sun_side'] or 0),
               100 * (t['band_bias_shadow_side'] or 0), t['pattern_correlation'] or 0))
    if a.json:
        with open(a.json, 'w') as fh:
            json.dump(res, fh, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
