#!/usr/bin/env python3
"""Does the sky-fill uncertainty cover the error the fill causes? Appends a section to a markdown file.

usage: fill_check.py --shared SHARED --scene NAME --filled ALBEDO.ply --true-sky ALBEDO.ply --out SKY.md

ALBEDO.ply files are rhoscan's albedo.ply from the same work folder (same mesh), once with the sky
filled ([sky] fill = model or row) and once with the true sky as [sky] panorama. Their per-facet
relative albedo difference (mean over channels) is the error the fill causes (plus the gather's
Monte Carlo noise, which differs between the runs); the uncertainty it is checked against is the
fill's and both runs' Monte Carlo noise, sqrt(irradiance_sky_sigma^2 + irradiance_mc_sigma^2 (filled)
+ irradiance_mc_sigma^2 (true sky)) / (E_sky + G), all from the two albedo.ply files.
"""
import argparse, os, sys

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--shared', required=True)
    ap.add_argument('--scene', required=True)
    ap.add_argument('--filled', required=True)
    ap.add_argument('--true-sky', required=True)
    ap.add_argument('--out', required=True)
    a = ap.parse_args()
    sys.path.insert(0, os.path.join(a.shared, 'tools'))
    from plyio import read_ply
    f, t = read_ply(a.filled)['face'], read_ply(a.true_sky)['face']
    sel = (f['estimable'] > 0) & (t['estimable'] > 0)
    af = np.stack([f['albedo_' + c] for c in 'rgb'], 1)[sel]
    at = np.stack([t['albedo_' + c] for c in 'rgb'], 1)[sel]
    diff = (np.abs(af - at) / np.maximum(at, 1e-6)).mean(1)
    lum = lambda p, n: 0.2126 * p[n + '_r'] + 0.7152 * p[n + '_g'] + 0.0722 * p[n + '_b']
    E = np.maximum(lum(f, 'irradiance_sky') + lum(f, 'irradiance_inter'), 1e-30)
    sig = (np.sqrt(f['irradiance_sky_sigma'] ** 2 + f['irradiance_mc_sigma'] ** 2 + t['irradiance_mc_sigma'] ** 2)
           / E)[sel]
    filled = f['sky_filled'][sel]
    lines = ['\n## Fill error against the fill uncertainty: %s\n' % a.scene,
             'Per estimable facet: the relative albedo change from the true sky to the filled sky, against the '
             'fill and Monte Carlo part of the uncertainty (`tools/skycompare/fill_check.py`).\n',
             '| facets | share | median change | 80th pct change | median fill+MC sigma | covered at 1 sigma | at 2 sigma |',
             '| --- | --- | --- | --- | --- | --- | --- |']
    for name, m in (('sky_filled < 0.1 % (Monte Carlo noise mostly)', filled < 0.001),
                    ('all', np.ones_like(diff, bool)), ('sky_filled > 5 %', filled > 0.05),
                    ('sky_filled > 20 %', filled > 0.2), ('sky_filled > 50 %', filled > 0.5)):
        if m.sum() == 0:
            continue
        lines.append('| %s | %.0f %% | %.2f %% | %.2f %% | %.2f %% | %.0f %% | %.0f %% |' % (
            name, 100 * m.mean(), 100 * np.median(diff[m]), 100 * np.percentile(diff[m], 80),
            100 * np.median(sig[m]), 100 * (diff[m] <= sig[m]).mean(), 100 * (diff[m] <= 2 * sig[m]).mean()))
    with open(a.out, 'a') as fh:
        fh.write('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
