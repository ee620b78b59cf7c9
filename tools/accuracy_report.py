#!/usr/bin/env python3
# Generates docs/ACCURACY.md from rhoscan-eval's output: every sample dataset (and the shared
# Cycles references when present) run with the methods direct, paper and interreflection.
# SPDX-License-Identifier: BSD-3-Clause
"""usage: tools/accuracy_report.py --bin BUILD_DIR [--shared DIR] [--scenes DIR] [--keep DIR] [--only NAME ...]
                                 [--report-only]

For each dataset: `rhoscan run` with reflectance.method = interreflection, then direct (only
reflectance and render rerun), then paper on a mesh simplified to --paper-facets facets (the
dense K is O(m^2) memory and O(m^3) visibility; [reflectance] paper_max_facets refuses more);
each run is measured by `rhoscan-eval TRUTH WORK --out ...`. The evaluator's eval.json and
eval_error.png are kept under docs/accuracy/<dataset>-<method>.*, and docs/ACCURACY.md is
written from those files alone (--report-only rewrites it without running anything).

--scenes DIR: the project's own reference scenes (OWN_SCENES, tools/refscene/scenes/*.json) rendered
into DIR/<name>/ (a folder counts when it holds DIR/<name>/DONE). Each runs twice with the default
method, on the scan and on the closed truth mesh (`--set mesh.input_mesh=truth.ply` with
`mesh.input_refine=true`, which splits its whole box faces to the facet size a scan gets), so
that the table separates the geometry's share of the error from the method's; the figures go to
docs/accuracy/own-<name>-scan.json and own-<name>-truth_mesh.json. --keep DIR keeps the work folders.
"""
import argparse
import glob, json, os, shutil, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(ROOT, 'docs')
ACC = os.path.join(DOCS, 'accuracy')
METHODS = ('direct', 'paper', 'interreflection')

SAMPLES = [  # name, config, truth folder, what it tests
    ('two_planes', 'configs/two_planes.ini', 'sample_data/two_planes',
     "the paper's simulation: two perpendicular planes under a soft sky"),
    ('tower', 'configs/tower.ini', 'sample_data/tower',
     'a tower with a deep niche, an overhang and a cornice; the sun is in the panorama'),
    ('courtyard', 'configs/courtyard.ini', 'sample_data/courtyard',
     'bright walls (0.7-0.85) around a courtyard, low sun: interreflection carries about 40 % of the light. '
     'The camera stands inside and sees little of the sky the walls see: the sky model fills about 11 % of '
     'the gathered sky light (issue 8). Rendered at 2048 samples, 1.6 % truth noise per pixel; the first '
     'recording at 256 samples (4.5 %) scored 3.2 % with the same code (sample_data/courtyard/README.md). '
     '`direct` has no re-render figure where its '
     'albedo above 1 makes the forward solve diverge'),
]
REFERENCES = [
    ('two_planes_sky', 'the shared reference of the paper\'s simulation (1024 x 512, 256 samples)'),
    ('step_park', 'the shared reference: an L-shaped block with a canopy, a real low sun'),
]

OWN_SCENES = [  # name, scene JSON, what it tests (issue 28, part 5; tools/refscene/scenes/README.md)
    ('street_canyon', 'tools/refscene/scenes/street_canyon.json',
     'a street canyon 12 m wide; a sun 8 degrees up, hidden from the camera behind the opposite block, '
     'lights the top 4 m of one facade'),
    ('walkway_court', 'tools/refscene/scenes/walkway_court.json',
     'a courtyard with an L-shaped covered walkway (roof slab on pillars) along two sides'),
    ('portico', 'tools/refscene/scenes/portico.json', 'a porch 4.5 m deep on five columns under a leafy sky'),
    ('balcony_awning', 'tools/refscene/scenes/balcony_awning.json',
     'a facade with four balconies and a shop awning, a real sun in front'),
    ('piers', 'tools/refscene/scenes/piers.json', 'a wall with six piers and stepped buttresses, a low real sun'),
    ('tile_yard', 'tools/refscene/scenes/tile_yard.json',
     'a yard whose walls carry brick and tile patterns, striped by the sun shadows of a pergola and a canopy'),
]
OWN_RUNS = (('scan', 'scan'), ('truth_mesh', 'closed truth mesh'))


# Why E_sky misses 3 % on tower and step_park: measured with tools/eval/esky_breakdown.py on
# interreflection runs of the default configs (figures as of the commit that wrote this text).
ESKY_NOTE = [
    '## E_sky against pi DiffDir: step_park now meets 3 %, tower misses it for light beyond the mesh', '',
    'The issue asks E_sky within 3 % of pi DiffDir on open datasets, and E_sky + G against',
    'pi (DiffDir + DiffInd) where geometry outside the mesh bounces light. With the mesh stage\'s',
    'normal denoising (`[mesh] denoise`, on by default since d173ade) they gave two_planes 1.8 %,',
    'two_planes_sky 2.1 %, step_park 0.5 % (was 3.7 %), and tower 5.1 % (was 5.5 %) with E_sky + G',
    'at 1.5 %; the tables above now also pool the irradiance within planes (`[reflectance]',
    'pool_accuracy`) and count the ground model beyond the scan as sky (6.6 % on tower, 1.3 % total).',
    '`tools/eval/esky_breakdown.py TRUTH WORKDIR [WORKDIR2]` splits the',
    'figure (the pixel-weighted mean of |E_sky - pi DiffDir| / pi DiffDir per facet) by cause; the',
    'split below was measured before the denoising:', '',
    '| cause | tower | step_park |',
    '| --- | ---: | ---: |',
    '| the figure (8727 / 49705 facets), without denoising | 5.49 % | 3.73 % |',
    '| 4 x samples, sky_samples and sun_samples (Monte Carlo noise: what is left when it shrinks) '
    '| 5.45 % | 3.64 % |',
    '| `target_error = 0.01` (adaptive rounds, 8662 facets refined on tower) | 5.44 % | - |',
    '| truth noise (Cycles, 0.8 % per pixel over a facet\'s pixels), estimate | 0.19 pt | 0.19 pt |',
    '| facets facing down (2.5 % of the pixels): light from ground beyond the scanned mesh | 3.07 pt | 0 |',
    '| walls at part edges (3.3 % of pixels): a rounded corner mixes faces lit differently | 0.90 pt | 0.03 pt |',
    '| walls inside parts (5.1 %): the niche\'s side wall sees sky through the opposite wall, '
    'which the scan never saw | 0.60 pt | 0.07 pt |',
    '| facets facing up (89 % / 93 % of the pixels) | 0.91 pt | 3.63 pt |',
    '| step_park with the ground\'s vertices set to z = 0 (observe + irradiance rerun) | - | 0.44 % |',
    '| with `[mesh] denoise` (bilateral normal filter, creases kept; the default now) | 5.11 % | 0.54 % |',
    '',
    '- **Monte Carlo noise is not the cause**: four times the rays, or adaptive rounds until the',
    '  standard error is below 1 %, move the figures by less than 0.1 point.',
    '- **step_park: the mesh\'s normal noise under a low sun.** The sun stands 10.5 degrees high;',
    '  a facet tilted by delta changes its sun term by about delta cot(10.5 deg) = 5.4 delta. The',
    '  ground\'s facets (12 cm) carried 1.3 mm of vertical noise from the scan, 1.75 degrees of tilt',
    '  (RMS), and their E_sky errors followed the tilt\'s prediction with correlation 0.99. The mesh',
    '  stage now filters the normals (Zheng et al. 2011, with Sun et al. 2007\'s vertex update,',
    '  moves bounded by `denoise_max_move`), which takes E_sky to 0.5 % and the interior albedo',
    '  error from 1.75 % to 1.1 %.',
    '- **tower: the truth\'s split of direct and indirect light, and the scan\'s coverage.** Facets',
    '  that face down (the overhang\'s and the cornice\'s undersides, the niche\'s ceiling) see the',
    '  ground. The scanned ground spans x -7 to 9 m and stops at the tower; the Cycles slab spans',
    '  x -12 to 12 m, y -14 to 12 m, behind the tower too. Rays that pass the mesh there read the',
    '  ground from the sky map (its pixels below the horizon) and count as E_sky; in Cycles that is',
    '  DiffInd. This is the case the issue names for comparing E_sky + G with pi (DiffDir +',
    '  DiffInd): 1.5 % on tower. Without the down-facing facets E_sky alone is 2.5 %. The niche\'s',
    '  +x side wall was never scanned (no facet), so the wall facing it sees sky through the gap.',
    '  Since the ground model (docs/PIPELINE.md, "Ground beyond the scan"), the ground those rays',
    '  read is the scan\'s own ground albedo under the completed sky instead of a copy of the',
    '  camera\'s far ground: the overhang\'s albedo error went from 9.8 % to 5.3 % and the',
    '  cornice\'s from 46 % to 38 %, while the niche\'s lintel, which looks out through that gap,',
    '  went from 11.9 % to 14.2 % (sample_data/tower/expected.json). E_sky against pi DiffDir on',
    '  tower went from 5.1 % to 6.8 % with it: more of the down-facing facets\' light is counted as',
    '  sky, where Cycles counts DiffInd; E_sky + G stays at 1.5 %.',
    '',
]


def log(msg):
    print('accuracy_report: ' + msg, file=sys.stderr, flush=True)


def reference_config(tmp, scene_dir):
    t = json.load(open(os.path.join(scene_dir, 'truth.json')))
    rot = ' '.join('%.17g' % v for row in t['camera_rotation_local_to_world'] for v in row)
    pos = ' '.join('%.17g' % v for v in t['camera_position'])
    cfg = os.path.join(tmp, 'scene.ini')
    with open(cfg, 'w') as fh:
        fh.write('[pipeline]\nworkdir = work\n[ingest]\nscan = %s\n[capture]\npanorama = %s\nposition = %s\n'
                 'rotation = %s\n' % (os.path.join(scene_dir, 'scan.ptx'), os.path.join(scene_dir, 'pano.exr'),
                                      pos, rot))
    return cfg


def run_and_eval(a, label, cfg, truth, work, out, sets):
    """`rhoscan run CFG` into work with sets, then rhoscan-eval of it into out; eval.json's
    document, or None (logged) when either fails."""
    rhoscan, ev = os.path.join(a.bin, 'rhoscan'), os.path.join(a.bin, 'rhoscan-eval')
    log(label)
    r = subprocess.run([rhoscan, 'run', cfg, '--quiet', '--set', 'pipeline.workdir=' + work] + sets,
                       capture_output=True, text=True)
    if r.returncode != 0:
        log('%s: rhoscan run exited %d: %s' % (label, r.returncode, r.stderr.strip()[-400:]))
        return None
    os.makedirs(out, exist_ok=True)
    r = subprocess.run([ev, truth, work, '--out', out, '--quiet'], capture_output=True, text=True)
    if r.returncode not in (0, 1) or not os.path.exists(os.path.join(out, 'eval.json')):
        log('%s: rhoscan-eval exited %d: %s' % (label, r.returncode, r.stderr.strip()))
        return None
    return json.load(open(os.path.join(out, 'eval.json')))


def run_dataset(a, name, cfg, truth, tmp):
    """Runs the three methods and keeps rhoscan-eval's output for each in docs/accuracy."""
    os.makedirs(ACC, exist_ok=True)
    for method in METHODS:
        work = os.path.join(tmp, name + ('-paper' if method == 'paper' else ''))
        sets = ['--set', 'reflectance.method=' + method]
        if method == 'paper':
            sets += ['--set', 'mesh.facets=%d' % a.paper_facets]
        out = os.path.join(tmp, 'eval-%s-%s' % (name, method))
        doc = run_and_eval(a, '%s: %s' % (name, method), cfg, truth, work, out, sets)
        if doc is None:
            continue
        doc['run'] = {'method': method, 'facets': doc['facets_total'],
                      'settings': [s for s in sets if not s.startswith('pipeline.') and s != '--set']}
        for d in ('truth_dir', 'work_dir'):   # machine-specific paths do not belong in the docs
            doc[d] = os.path.relpath(doc[d], ROOT) if doc[d].startswith(ROOT) else os.path.basename(doc[d])
        json.dump(doc, open(os.path.join(ACC, '%s-%s.json' % (name, method)), 'w'), indent=1)
        shutil.copy(os.path.join(out, 'eval_error.png'), os.path.join(ACC, '%s-%s.png' % (name, method)))


def run_own_scene(a, name, scene, tmp):
    """One own scene, on the scan and on the closed truth mesh, default method."""
    os.makedirs(ACC, exist_ok=True)
    d = os.path.join(tmp, 'cfg-own-' + name)
    os.makedirs(d, exist_ok=True)
    cfg = reference_config(d, scene)
    for run, _ in OWN_RUNS:
        work = os.path.join(tmp, 'own-%s-%s' % (name, run))
        sets = []
        if run == 'truth_mesh':   # split to the facet size a scan gets: truth.ply's box faces are whole
            sets += ['--set', 'mesh.input_mesh=' + os.path.join(scene, 'truth.ply'), '--set', 'mesh.input_refine=true']
        out = os.path.join(tmp, 'eval-own-%s-%s' % (name, run))
        doc = run_and_eval(a, '%s: %s' % (name, run), cfg, scene, work, out, sets)
        if doc is None:
            continue
        truth = json.load(open(os.path.join(scene, 'truth.json')))
        doc['run'] = {'method': 'interreflection', 'mesh': run, 'facets': doc['facets_total'],
                      'samples': truth.get('samples')}
        for k in ('truth_dir', 'work_dir'):
            doc[k] = os.path.basename(doc[k])
        json.dump(doc, open(os.path.join(ACC, 'own-%s-%s.json' % (name, run)), 'w'), indent=1)
        shutil.copy(os.path.join(out, 'eval_error.png'), os.path.join(ACC, 'own-%s-%s.png' % (name, run)))
        if run == 'scan' and any('pattern' in p for p in truth.get('parts', [])):
            texture_figures(a, name, scene, cfg, work, doc['facets_total'])


def texture_figures(a, name, scene, cfg, work, facets):
    """A textured own scene (refscene `pattern` parts): texture_eval.py's per-pixel figures, per part
    too, at the default mesh (the scan run's work folder) and at ten times fewer facets, into
    docs/accuracy/texture-own-NAME.json and texture-own-NAME_coarse.json (the texture section)."""
    ev = os.path.join(ROOT, 'tools', 'eval', 'texture_eval.py')
    coarse = work + '-coarse'
    for suffix, w, label in (('', work, 'default mesh (%d facets)' % facets),
                             ('_coarse', coarse, '`[mesh] facets = %d` (ten times coarser)' % (facets // 10))):
        if suffix:
            r = subprocess.run([os.path.join(a.bin, 'rhoscan'), 'run', cfg, '--quiet', '--set', 'pipeline.workdir=' + w,
                                '--set', 'mesh.facets=%d' % (facets // 10)], capture_output=True, text=True)
            if r.returncode != 0:
                log('%s coarse: rhoscan run exited %d: %s' % (name, r.returncode, r.stderr.strip()[-400:]))
                return
        out = os.path.join(ACC, 'texture-own-%s%s.json' % (name, suffix))
        r = subprocess.run([sys.executable, ev, '--bin', a.bin, '--scene', scene, '--work', w, '--facets', '--parts',
                            '--json', out], capture_output=True, text=True)
        if r.returncode != 0:
            log('%s: texture_eval.py exited %d: %s' % (name, r.returncode, (r.stdout + r.stderr).strip()[-400:]))
            return
        d = json.load(open(out))
        samples = json.load(open(os.path.join(scene, 'truth.json'))).get('samples')
        d['label'] = '%s (own scene, %s samples), %s' % (name, samples, label)
        json.dump(d, open(out, 'w'), indent=1)


def own_section():
    """The own scenes' table (docs/accuracy/own-*.json), scan against the closed truth mesh."""
    have = [(n, j, w) for n, j, w in OWN_SCENES
            if any(os.path.exists(os.path.join(ACC, 'own-%s-%s.json' % (n, r))) for r, _ in OWN_RUNS)]
    if not have:
        return []
    lines = ['## Own scenes (issue 28)', '',
             'The project\'s own Cycles scenes of the kinds issue 28 found failing (tools/refscene/scenes,',
             'README there), one ground-level scan station each, rendered with tools/refscene and run with the',
             'default method twice: on the scan (an open shell: roof tops, slab tops and the backs of columns',
             'are never scanned) and on the closed truth mesh (`--set mesh.input_mesh=truth.ply` with',
             '`mesh.input_refine=true`, which splits its whole box faces to the facet size a scan gets; as whole',
             'faces cloister_sunset scored 31.9 % on 96 facets, split 6.8 %, shared evaluator). The',
             'difference between the two rows is the geometry\'s share of the error, the truth-mesh row the',
             'method\'s. Regenerate with `tools/accuracy_report.py --scenes DIR --only NAME ...` where DIR',
             'holds the rendered folders. *total*: E_sky + G against pi (DiffDir + DiffInd) as above (E_sky',
             'alone is left out: on walkway_court rhoscan-eval reported it as 10^4 to 10^6 %; not investigated).', '',
             '| scene | mesh | samples | facets | interior mean | interior median | interior p95 | interior bias '
             '| all mean | coverage | total |',
             '| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
    for n, _, _ in have:
        for run, label in OWN_RUNS:
            f = os.path.join(ACC, 'own-%s-%s.json' % (n, run))
            if not os.path.exists(f):
                lines.append('| %s | %s | did not run | | | | | | | | |' % (n, label))
                continue
            d = json.load(open(f))
            al = d['albedo']
            lines.append('| %s | %s | %s | %d | %s | %s | %s | %s | %s | %s | %s |' % (
                n, label, stat(d, 'run', 'samples') or '-', d['facets_total'],
                fmt(stat(al, 'interior', 'mean_rel')), fmt(stat(al, 'interior', 'median_rel')),
                fmt(stat(al, 'interior', 'p95_rel')), fmt(stat(al, 'interior', 'bias_rel'), True),
                fmt(stat(al, 'all', 'mean_rel')), fmt(stat(d, 'coverage', 'share')),
                fmt(stat(d, 'irradiance', 'total_rel'))))
    lines += ['', '| scene | what it tests |', '| --- | --- |']
    lines += ['| %s | %s |' % (n, w) for n, _, w in have]
    lines += ['']
    for n, _, _ in have:
        imgs = ['![%s %s](accuracy/own-%s-%s.png)' % (n, r, n, r) for r, _ in OWN_RUNS
                if os.path.exists(os.path.join(ACC, 'own-%s-%s.png' % (n, r)))]
        lines += ['%s (left to right: %s): %s' % (n, ', '.join(l for _, l in OWN_RUNS), ' '.join(imgs)), '']
    return lines


def fmt(v, signed=False):
    if v is None:
        return '-'
    return ('%+.1f %%' if signed else '%.1f %%') % (100 * v)


def stat(doc, *path):
    for k in path:
        if doc is None:
            return None
        doc = doc.get(k)
    return doc


def texture_section():
    """The texture's per-pixel figures (docs/accuracy/texture-*.json, written by
    tools/eval/texture_eval.py --json on a run's work folder)."""
    files = sorted(glob.glob(os.path.join(ACC, 'texture-*.json')))
    if not files:
        return []
    lines = ['## Texture per pixel: albedo.glb against the albedo pass', '',
             'tools/eval/texture_eval.py renders albedo.glb\'s texture through its UVs into the camera\'s '
             'panorama (rhoscan-texview: its own GLB reader and ray tracer) and compares it per pixel with '
             'Cycles\' pano_diffcol.exr: relative error |texture - truth|_1 / |truth|_1 over building pixels '
             '(diffcol > 0); *shadow*: pano_diffdir.exr\'s luminance below 0.4 x its largest value within '
             '30 px; *band*: pixels within 1 px of the other class (3 px wide); *holes*: building pixels where '
             'the asset has no surface (the mesh\'s, the same for the facets). *step*: mean texture over mean '
             'truth in the band, sun side and shadow side. *facets*: albedo.ply\'s per-facet colours in the '
             'same view, for scale. The issue asks of the texture median at most 3 % (all), 5 % (shadow), 6 % '
             '(band), holes at most 0.5 %. Regenerate a row with `texture_eval.py --bin build --scene SCENE '
             '--work WORKDIR --facets --json docs/accuracy/texture-NAME.json`, then `--report-only`.', '',
             '| run | what | median all | sun | shadow | band | mean all | holes | step sun / shadow side | '
             'correlation with the truth |',
             '| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: |']
    for f in files:
        d = json.load(open(f))
        name = d.get('label', os.path.basename(f)[len('texture-'):-len('.json')])
        for k in ('texture', 'facets'):
            t = d.get(k)
            if not t:
                continue
            med = [fmt(t[c]['median']) if t[c]['median'] is not None else '-' for c in
                   ('all', 'sun', 'shadow', 'shadow_edge_band')]
            lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s / %s | %.3f |' % (
                name, k, med[0], med[1], med[2], med[3], fmt(t['all']['mean']), fmt(t['hole_share']),
                fmt(t['band_bias_sun_side'], True) if t['band_bias_sun_side'] is not None else '-',
                fmt(t['band_bias_shadow_side'], True) if t['band_bias_shadow_side'] is not None else '-',
                t['pattern_correlation'] or 0))
    for f in files:
        d = json.load(open(f))
        if not d.get('parts'):
            continue
        name = d.get('label', os.path.basename(f)[len('texture-'):-len('.json')])
        lines += ['', 'Per part, %s (texture_eval.py --parts; median relative error, texture / facets; parts with '
                  'at least 1 %% of the building pixels):' % name, '',
                  '| part | pixels | all | sun | shadow | band | holes | correlation |',
                  '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
        for part, pd in d['parts'].items():
            t, fc = pd['texture'], pd.get('facets', {})
            if t['building_pixels'] < 0.01 * d['texture']['building_pixels']:
                continue

            def pair(c):
                return ' / '.join(fmt(x[c]['median']) if x and x[c]['median'] is not None else '-' for x in (t, fc))
            lines.append('| %s | %d | %s | %s | %s | %s | %s | %.3f / %.3f |' % (
                part, t['building_pixels'], pair('all'), pair('sun'), pair('shadow'), pair('shadow_edge_band'),
                fmt(t['hole_share']), t['pattern_correlation'] or 0, (fc or {}).get('pattern_correlation') or 0))
    return lines + ['']


def write_report(datasets):
    lines = [
        '# Accuracy against Cycles ground truth',
        '',
        'Generated by `tools/accuracy_report.py` from the output of `rhoscan-eval` (tools/eval); do not',
        'edit by hand. Regenerate with `/usr/bin/python3 tools/accuracy_report.py --bin build`',
        '(`--report-only` rewrites this page from docs/accuracy/*.json without running anything).',
        '',
        'How the figures are made (tools/eval/eval.h): each facet of the run takes the truth part that',
        'most of seven points spread over it land on (nearest truth triangle within 0.15 m); its error',
        'is the mean over R, G, B of |rho - rho_true| / rho_true. Figures are area-weighted over facets',
        'that are observed and estimable. *interior*: facets whose seven points all lie on one part;',
        '*all*: every matched facet (also those across part boundaries). *coverage*: the share of the',
        'model pixels in the camera view (truth DiffCol > 0) whose facet is observed and estimable, so',
        'that flagging hard facets away shows here. *E_sky* and *G*: per-facet irradiance against',
        'pi DiffDir and pi DiffInd, pixel-weighted over facets seen on at least 4 pixels; *total* is',
        'E_sky + G against pi (DiffDir + DiffInd), the fair figure where geometry outside the mesh (ground',
        'beyond the scan) bounces light, which rhoscan counts as sky and Cycles as indirect.',
        '*re-render*: synth.exr against pano.exr over the model pixels.',
        '',
        '*Concave* and *convex* parts: a truth part is concave when the scanned model fills at least',
        '20 % of its facets\' cosine-weighted hemisphere (its mean *enclosure*, 64 rays per facet against',
        'the run\'s mesh): there interreflection is a large share of the light and `direct`, which',
        'ignores it, overestimates albedo. `paper` (the dense K of the seed paper) runs on a mesh',
        'simplified to the facet count given in its row (`--set mesh.facets=N`), since',
        '[reflectance] paper_max_facets limits it; its figures are therefore on a coarser mesh.',
        '',
        'Error images (eval_error.png): per pixel of the camera view, the facet\'s error against the',
        'per-pixel truth albedo, blue 0 - cyan 5 % - green 10 % - yellow 15 % - red 20 % and above;',
        'magenta: model pixels whose facet is unobserved, not estimable or missing; grey: sky.',
        '',
    ]
    lines += ['## Summary', '',
              'Area-weighted mean relative albedo error, interior facets (all facets in brackets). The issue asks',
              'of `interreflection` at most 3 % interior and 5 % over all observed facets.', '',
              '| dataset | ' + ' | '.join(METHODS) + ' | interreflection meets 3 % / 5 % |',
              '| --- | ' + ' | '.join('---:' for _ in METHODS) + ' | --- |']
    for name, _ in datasets:
        row = []
        for m in METHODS:
            f = os.path.join(ACC, '%s-%s.json' % (name, m))
            d = json.load(open(f)) if os.path.exists(f) else None
            row.append('%s (%s)' % (fmt(stat(d, 'albedo', 'interior', 'mean_rel')), fmt(stat(d, 'albedo', 'all', 'mean_rel')))
                       if d else '-')
        f = os.path.join(ACC, '%s-interreflection.json' % name)
        d = json.load(open(f)) if os.path.exists(f) else None
        meets = '-' if d is None else 'yes' if (stat(d, 'albedo', 'interior', 'mean_rel') or 1) <= 0.03 and \
            (stat(d, 'albedo', 'all', 'mean_rel') or 1) <= 0.05 else 'no'
        if d is not None or any(c != '-' for c in row):
            lines.append('| %s | %s | %s |' % (name, ' | '.join(row), meets))
    lines.append('')
    lines += ESKY_NOTE
    for name, what in datasets:
        docs = {m: json.load(open(os.path.join(ACC, '%s-%s.json' % (name, m))))
                for m in METHODS if os.path.exists(os.path.join(ACC, '%s-%s.json' % (name, m)))}
        if not docs:
            continue
        lines += ['## %s' % name, '', what + '.', '']
        lines += ['| method | facets | interior mean | all mean | interior p95 | interior bias | concave parts '
                  '(interior mean, bias) | convex parts | coverage | E_sky | G | total | re-render |',
                  '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
        for m in METHODS:
            d = docs.get(m)
            if d is None:
                lines.append('| %s | did not run | | | | | | | | | | | |' % m)
                continue
            al = d['albedo']
            cc = stat(al, 'concave_parts', 'interior')
            cv = stat(al, 'convex_parts', 'interior')
            lines.append('| %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
                m + (' (%s)' % ' '.join(d['run']['settings'][1:]) if m == 'paper' else ''),
                d['facets_total'], fmt(stat(al, 'interior', 'mean_rel')), fmt(stat(al, 'all', 'mean_rel')),
                fmt(stat(al, 'interior', 'p95_rel')), fmt(stat(al, 'interior', 'bias_rel'), True),
                '%s, %s' % (fmt(cc['mean_rel']), fmt(cc['bias_rel'], True)) if cc else '-',
                '%s, %s' % (fmt(cv['mean_rel']), fmt(cv['bias_rel'], True)) if cv else '-',
                fmt(d['coverage']['share']), fmt(d['irradiance']['esky_rel']), fmt(d['irradiance']['g_rel']),
                fmt(d['irradiance']['total_rel']), fmt(d['synth']['rel_diff'])))
        ref = docs.get('interreflection') or next(iter(docs.values()))
        lines += ['', 'Per part (interior facets; enclosure and the truth\'s interreflection share '
                      'DiffInd / (DiffDir + DiffInd) from the interreflection run):', '',
                  '| part | truth albedo | enclosure | G share | concave | ' +
                  ' | '.join('%s mean (bias)' % m for m in METHODS) + ' |',
                  '| --- | --- | ---: | ---: | --- | ' + ' | '.join('---:' for _ in METHODS) + ' |']
        for p, pj in sorted(ref['parts'].items(), key=lambda kv: int(kv[0])):
            cells = []
            for m in METHODS:
                s = stat(docs.get(m), 'parts', p, 'interior')
                cells.append('%s (%s)' % (fmt(s['mean_rel']), fmt(s['bias_rel'], True)) if s else '-')
            lines.append('| %s | %s | %s | %s | %s | %s |' % (
                p, ', '.join('%.2f' % v for v in pj.get('truth_albedo', [])),
                '-' if pj['enclosure'] is None else '%.2f' % pj['enclosure'],
                fmt(pj['truth_interreflection_share']), 'yes' if pj['concave'] else 'no', ' | '.join(cells)))
        lines += ['', ' '.join('![%s %s](accuracy/%s-%s.png)' % (name, m, name, m)
                               for m in METHODS if m in docs), '',
                  'Images, left to right: ' + ', '.join(m for m in METHODS if m in docs) + '.', '']
    lines += own_section()
    lines += texture_section()
    text = '\n'.join(lines)
    tmp = os.path.join(DOCS, 'ACCURACY.md.tmp')
    with open(tmp, 'w') as fh:
        fh.write(text)
    os.replace(tmp, os.path.join(DOCS, 'ACCURACY.md'))
    log('wrote docs/ACCURACY.md')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--bin', default=os.path.join(ROOT, 'build'))
    ap.add_argument('--shared', default=os.environ.get('RHOSCAN_SHARED_DIR', os.path.join(os.path.dirname(ROOT), 'shared')))
    ap.add_argument('--only', nargs='*', help='dataset names to (re)run; the others keep their stored figures')
    ap.add_argument('--paper-facets', type=int, default=1500)
    ap.add_argument('--report-only', action='store_true')
    ap.add_argument('--scenes', help='folder of the rendered own scenes (OWN_SCENES), DIR/<name>/DONE')
    ap.add_argument('--keep', help='keep the work folders here instead of a temporary folder')
    a = ap.parse_args()
    datasets = [(n, w) for n, _, _, w in SAMPLES]
    refs = [(n, w) for n, w in REFERENCES if os.path.isdir(os.path.join(a.shared, 'reference', n))]
    if not a.report_only:
        tmp = os.path.abspath(a.keep) if a.keep else tempfile.mkdtemp(prefix='rhoscan-accuracy-')
        os.makedirs(tmp, exist_ok=True)
        try:
            for n, cfg, truth, _ in SAMPLES:
                if a.only is None or n in a.only:
                    run_dataset(a, n, os.path.join(ROOT, cfg), os.path.join(ROOT, truth), tmp)
            for n, _ in refs:
                if a.only is None or n in a.only:
                    scene = os.path.join(a.shared, 'reference', n)
                    d = os.path.join(tmp, 'cfg-' + n)
                    os.makedirs(d)
                    run_dataset(a, n, reference_config(d, scene), scene, tmp)
            for n, _, _ in OWN_SCENES if a.scenes else ():
                scene = os.path.abspath(os.path.join(a.scenes, n))
                if (a.only is None or n in a.only) and os.path.exists(os.path.join(scene, 'DONE')):
                    run_own_scene(a, n, scene, tmp)
        finally:
            if not a.keep:
                shutil.rmtree(tmp, ignore_errors=True)
    write_report(datasets + refs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
