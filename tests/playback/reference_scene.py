#!/usr/bin/env python3
"""Playback of a Cycles reference scene (../shared/reference/NAME) end to end from its scan.

Runs `rhoscan run` with method interreflection, then `--set reflectance.method=direct` (which
must rerun only reflectance and render), measures both with the shared evaluator, compares the
per-facet E_sky and G with Cycles' pi * DiffDir and pi * DiffInd in the camera view, and asserts:
  - interreflection: area-weighted mean relative albedo error over observed facets inside one
    truth part <= --max-error (default 0.05), no non-finite albedo;
  - coverage (observed and estimable share of the model area the camera sees) >= 0.95;
  - interreflection is better than direct (interior mean error).
Exit 0 on success, 1 on failure, 77 (skip) when the shared data is absent and CI is not set.
"""
import argparse, json, os, shutil, subprocess, sys, tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import digests  # noqa: E402


def skip_or_fail(msg):
    if os.environ.get('CI') == 'true':
        print('FAIL: ' + msg + ' (CI=true requires it)'); sys.exit(1)
    print('SKIP: ' + msg); sys.exit(77)


def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise RuntimeError(buf.geterror())
    return buf.get_pixels(oiio.FLOAT)


def read_faces(path):
    sys.path.insert(0, os.path.join(ARGS.shared, 'tools'))
    from plyio import read_ply
    return read_ply(path)['face']


def evaluate(scene_dir, albedo_ply, out_json):
    tool = os.path.join(ARGS.shared, 'tools', 'eval_albedo.py')
    r = subprocess.run([sys.executable, tool, os.path.join(scene_dir, 'truth.ply'), albedo_ply,
                        '--json', out_json, '--dataset', scene_dir], capture_output=True, text=True)
    print(r.stdout.strip())
    if r.returncode != 0:
        print(r.stderr)
        return None
    return json.load(open(out_json))


def check_texture(scene_dir, work, tmp):
    """The texture in the camera's view against Cycles' albedo pass, per pixel (issue 22's
    targets): median relative error over the building <= 3 %, in cast shadow <= 5 %, in the band
    around shadow edges <= 6 %; no step at shadow edges (the band's sun side and shadow side
    show the truth's mean within 2 % of each other); the pattern reproduced (correlation with the
    truth at least 0.95, and higher than the facets' colours)."""
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = os.path.join(tmp, 'texture_eval.json')
    r = subprocess.run([sys.executable, os.path.join(src, 'tools', 'eval', 'texture_eval.py'), '--bin', ARGS.bin,
                        '--scene', scene_dir, '--work', work, '--json', out, '--facets'])
    if r.returncode != 0:
        print('FAIL: texture_eval.py exited %d' % r.returncode)
        return False
    t = json.load(open(out))
    tex, fac = t['texture'], t['facets']
    ok = True
    for key, bound in (('all', 0.03), ('shadow', 0.05), ('shadow_edge_band', 0.06)):
        if tex[key]['median'] is not None and tex[key]['median'] > bound:
            print('FAIL: texture median error %s %.4f > %.2f' % (key, tex[key]['median'], bound)); ok = False
    a, b = tex['band_bias_sun_side'], tex['band_bias_shadow_side']
    if a is not None and b is not None and abs(a - b) > 0.02:
        print('FAIL: a step at shadow edges: the band shows %+.4f on the sun side, %+.4f in shadow' % (a, b)); ok = False
    if not (tex['pattern_correlation'] >= 0.95 and tex['pattern_correlation'] > fac['pattern_correlation']):
        print('FAIL: texture correlation with the truth %.4f (facets %.4f)' % (tex['pattern_correlation'],
                                                                             fac['pattern_correlation'])); ok = False
    return ok


def compare_irradiance(scene_dir, work):
    """Pixel-count-weighted mean relative error of per-facet E_sky vs pi*DiffDir, G vs pi*DiffInd,
    and E_sky + G vs pi*(DiffDir + DiffInd), over facets the camera sees on at least 4 pixels."""
    ids = read_exr(os.path.join(work, 'facet_id.exr'))[:, :, 0].astype(np.int64)
    dd = read_exr(os.path.join(scene_dir, 'pano_diffdir.exr'))[:, :, :3].mean(2) * np.pi
    di = read_exr(os.path.join(scene_dir, 'pano_diffind.exr'))[:, :, :3].mean(2) * np.pi
    f = read_faces(os.path.join(work, 'albedo.ply'))
    esky = np.stack([f['irradiance_sky_' + c] for c in 'rgb'], 1).mean(1)
    g = np.stack([f['irradiance_inter_' + c] for c in 'rgb'], 1).mean(1)
    m = ids >= 0
    n = np.bincount(ids[m], minlength=len(esky))
    t_dir = np.bincount(ids[m], weights=dd[m], minlength=len(esky)) / np.maximum(n, 1)
    t_ind = np.bincount(ids[m], weights=di[m], minlength=len(esky)) / np.maximum(n, 1)
    sel = (n >= 4) & (f['estimable'] > 0)
    w = n[sel]
    def rel(a, b):
        return float((np.abs(a[sel] - b[sel]) / np.maximum(b[sel], 1e-9) * w).sum() / w.sum())
    def bias(a, b):
        return float((a[sel] * w).sum() / (b[sel] * w).sum() - 1)
    out = {'facets': int(sel.sum()), 'esky_rel': rel(esky, t_dir), 'esky_bias': bias(esky, t_dir),
           'g_rel': rel(g, t_ind), 'g_bias': bias(g, t_ind),
           'total_rel': rel(esky + g, t_dir + t_ind), 'total_bias': bias(esky + g, t_dir + t_ind)}
    print('irradiance vs Cycles over %(facets)d facets: E_sky mean rel %(esky_rel).4f (bias %(esky_bias)+.4f), '
          'G mean rel %(g_rel).4f (bias %(g_bias)+.4f), E_sky+G mean rel %(total_rel).4f (bias %(total_bias)+.4f)' % out)
    return out


def main():
    global ARGS
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--shared', default=os.environ.get('RHOSCAN_SHARED_DIR', ''))
    ap.add_argument('--scene', required=True)
    ap.add_argument('--max-error', type=float, default=0.05)
    ap.add_argument('--min-coverage', type=float, default=0.95)
    ap.add_argument('--keep', help='work folder to keep (default: a temporary one)')
    ap.add_argument('--set', action='append', default=[], help='extra section.key=value')
    ap.add_argument('--digests', help='compare every output of both runs with these digests (digests.py)')
    ap.add_argument('--record-digests', action='store_true', help='write --digests instead')
    ap.add_argument('--texture', action='store_true',
                    help='also measure albedo.glb per pixel against pano_diffcol.exr (tools/eval/texture_eval.py) '
                         'and hold it to the targets of issue 22')
    ARGS = ap.parse_args()
    # Normalised: the records name files by the path the config gives, and the digests must not
    # depend on how the shared folder was reached (CMake's default is SOURCE/../shared).
    scene_dir = os.path.normpath(os.path.abspath(os.path.join(ARGS.shared, 'reference', ARGS.scene)))
    if not ARGS.shared or not os.path.isdir(scene_dir):
        skip_or_fail('reference scene %s is missing' % scene_dir)
    tmp = ARGS.keep or tempfile.mkdtemp(prefix='rhoscan-ref-')
    os.makedirs(tmp, exist_ok=True)
    truth = json.load(open(os.path.join(scene_dir, 'truth.json')))
    rot = ' '.join('%.17g' % v for row in truth['camera_rotation_local_to_world'] for v in row)
    pos = ' '.join('%.17g' % v for v in truth['camera_position'])
    cfg = os.path.join(tmp, 'scene.ini')
    with open(cfg, 'w') as fh:
        fh.write('[pipeline]\nworkdir = work\n[ingest]\nscan = %s\n[capture]\npanorama = %s\nposition = %s\n'
                 'rotation = %s\n' % (os.path.join(scene_dir, 'scan.ptx'), os.path.join(scene_dir, 'pano.exr'),
                                      pos, rot))
    work = os.path.join(tmp, 'work')
    rhoscan = os.path.join(ARGS.bin, 'rhoscan')
    sets = sum([['--set', s] for s in ARGS.set], [])
    ok = True
    r = subprocess.run([rhoscan, 'run', cfg] + sets)
    if r.returncode != 0:
        print('FAIL: rhoscan run exited %d' % r.returncode); sys.exit(1)
    places = [(work, '$WORK'), (tmp, '$RUN'), (scene_dir, '$SCENE')]
    outputs = digests.digest_folder(work, places) if ARGS.digests else {}
    inter = evaluate(scene_dir, os.path.join(work, 'albedo.ply'), os.path.join(tmp, 'eval_interreflection.json'))
    irr = compare_irradiance(scene_dir, work)
    shutil.copy(os.path.join(work, 'albedo.ply'), os.path.join(tmp, 'albedo_interreflection.ply'))
    if ARGS.texture and not check_texture(scene_dir, work, tmp):
        ok = False
    r = subprocess.run([rhoscan, 'run', cfg, '--set', 'reflectance.method=direct'] + sets,
                       capture_output=True, text=True)
    sys.stderr.write(r.stderr)
    if r.returncode != 0:
        print('FAIL: rhoscan run (direct) exited %d' % r.returncode); sys.exit(1)
    for stage in ('ingest', 'mesh', 'observe', 'irradiance'):
        if 'skipped stage %s' % stage not in r.stderr:
            print('FAIL: changing the method reran %s' % stage); ok = False
    if ARGS.digests:
        outputs.update(digests.digest_folder(work, places, prefix='direct/'))
        for problem in digests.check(outputs, ARGS.digests, ARGS.record_digests):
            print('FAIL: ' + problem); ok = False
    direct = evaluate(scene_dir, os.path.join(work, 'albedo.ply'), os.path.join(tmp, 'eval_direct.json'))
    if inter is None or direct is None:
        print('FAIL: the evaluator failed'); sys.exit(1)
    ei, ed = inter['interior']['mean_rel'], direct['interior']['mean_rel']
    print('RESULT %s: interreflection interior mean %.4f (all %.4f, p95 %.4f), direct %.4f (all %.4f); '
          'coverage %.3f' % (ARGS.scene, ei, inter['all']['mean_rel'], inter['interior']['p95_rel'], ed,
                              direct['all']['mean_rel'], inter['coverage']))
    for p, s in sorted(inter['parts'].items()):
        d = direct['parts'].get(p)
        if s:
            print('  part %s: interreflection %.4f, direct %s' % (p, s['mean_rel'], '%.4f' % d['mean_rel'] if d else '-'))
    json.dump({'interreflection': inter, 'direct': direct, 'irradiance': irr},
              open(os.path.join(tmp, 'summary.json'), 'w'), indent=1)
    if ei > ARGS.max_error:
        print('FAIL: interreflection error %.4f > %.4f' % (ei, ARGS.max_error)); ok = False
    if not ei < ed:
        print('FAIL: interreflection (%.4f) is not better than direct (%.4f)' % (ei, ed)); ok = False
    if inter['coverage'] < ARGS.min_coverage:
        print('FAIL: coverage %.3f < %.3f' % (inter['coverage'], ARGS.min_coverage)); ok = False
    if not ARGS.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    print('PASS' if ok else 'FAIL')
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
