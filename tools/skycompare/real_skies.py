#!/usr/bin/env python3
"""The sky fill on real HDR skies with a part of each hidden: a markdown table for docs/SKY.md.

usage: real_skies.py --bin BUILD SKY.hdr...

For each sky (equirectangular, world frame), two low sectors are hidden in turn: 120 degrees of
azimuth below 30 degrees elevation centred on the sun's azimuth (the sun, its glow and the bright
horizon beneath it hidden, as behind a courtyard's wing at sunset), and the same opposite the
sun. Each is filled by rows, by the model, and by the model told the sun's direction (the
truth's brightest pixel: what the solar position or the shadows' search give) (rhoscan-skyfill-eval, the irradiance stage's own
sky map code) and compared with the truth there: the hidden sky's light without the sun's disc
(2.5 degrees), the RMS log error per direction, and the mean and worst error of the hidden
sky's irradiance on vertical walls facing every way, as a share of the wall's whole sky E.
"""
import argparse, json, os, subprocess


def run(bin_dir, sky, extra):
    out = subprocess.run([os.path.join(bin_dir, 'rhoscan-skyfill-eval'), sky] + extra, capture_output=True,
                         text=True, check=True).stdout
    return json.loads(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('skies', nargs='+')
    a = ap.parse_args()
    print('| sky | hidden | method | light of the hidden sky | RMS log error | walls: mean error | worst |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    for sky in a.skies:
        probe = run(a.bin, sky, ['--hide', '0', '0', '-90'])
        saz = probe['truth_brightest_az_deg']
        for label, centre in (('by the sun', saz), ('opposite', saz + 180)):
            hide = ['--hide', '%.2f' % (centre - 60), '%.2f' % (centre + 60), '30']
            sun = ['--sun', '%.2f' % saz, '%.2f' % probe['truth_brightest_el_deg']]
            for method, extra in (('row', ['--fill', 'row']), ('model', []), ('model + sun direction', sun)):
                r = run(a.bin, sky, hide + extra)
                print('| %s | %s | %s | %+.1f %% | %.2f | %.1f %% | %+.1f %% |' %
                      (os.path.basename(sky), label, method, 100 * r['hidden_light_rel_without_disc'],
                       r['log_rms_without_disc'], 100 * r['wall_error_mean_abs'], 100 * r['wall_error_worst']))


if __name__ == '__main__':
    main()
