#!/usr/bin/env python3
"""Playback of a recorded dataset in sample_data/: runs `rhoscan run CONFIG` into a fresh work
folder and checks the numbers against the dataset's expected.json:
  - metrics: each recorded value within its stated tolerance (absolute or relative);
  - albedo: per truth part (the truth.ply box a facet's centroid lies on), the area-weighted
    mean albedo of observed, estimable facets within `albedo_rel_tol` of the truth, and the
    area-weighted mean relative error below `max_mean_rel_error`;
  - no non-finite value in albedo.ply, every output file present;
  - with an "eval" object (max_error, max_error_all, min_coverage): rhoscan-eval's thresholds;
    its figures are available to "metrics" under "eval." (e.g. eval.albedo.interior.mean_rel).
With --record, writes the current metrics into expected.json instead (review the diff, and say
why in the commit that changes it).
"""
import argparse, json, math, os, shutil, subprocess, sys, tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from plyread import read_ply  # noqa: E402
import digests  # noqa: E402


def get(d, path):
    for k in path.split('.'):
        d = d[k]
    return d


def boxes_of(truth):
    """Truth parts as axis-aligned boxes (the reference scenes are boxes) with their albedo."""
    v = np.stack([truth['vertex'][c] for c in 'xyz'], 1)
    f = truth['face']
    idx = np.asarray(f['vertex_indices'])
    parts = {}
    for k in range(len(idx)):
        p = int(f['part'][k])
        pts = v[idx[k]]
        lo, hi, alb = parts.get(p, (pts.min(0), pts.max(0), None))
        parts[p] = (np.minimum(lo, pts.min(0)), np.maximum(hi, pts.max(0)),
                    np.array([f['red'][k], f['green'][k], f['blue'][k]]))
    return parts


def albedo_by_part(res, parts, margin):
    v = np.stack([res['vertex'][c] for c in 'xyz'], 1)
    f = res['face']
    tri = v[np.asarray(f['vertex_indices'])]
    cen = tri.mean(1)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    alb = np.stack([f['albedo_' + c] for c in 'rgb'], 1)
    good = (f['observed'] > 0) & (f['estimable'] > 0)
    out = {}
    for p, (lo, hi, truth) in parts.items():
        # every corner inside the box (grown by margin) and the centroid away from its edges
        inside = np.all((tri >= lo - margin) & (tri <= hi + margin), axis=(1, 2))
        sel = good & inside
        if sel.sum() == 0:
            continue
        w = area[sel]
        rel = (np.abs(alb[sel] - truth) / truth).mean(1)
        out[p] = {'facets': int(sel.sum()), 'truth': truth.tolist(),
                  'mean': ((alb[sel] * w[:, None]).sum(0) / w.sum()).tolist(),
                  'mean_rel_error': float((rel * w).sum() / w.sum())}
    return out, bool(np.all(np.isfinite(alb)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--config', required=True)
    ap.add_argument('--expected', required=True)
    ap.add_argument('--record', action='store_true')
    ap.add_argument('--keep')
    ap.add_argument('--digests', help='compare every output with these digests (digests.py)')
    ap.add_argument('--record-digests', action='store_true', help='write --digests instead')
    a = ap.parse_args()
    exp = json.load(open(a.expected))
    tmp = a.keep or tempfile.mkdtemp(prefix='rhoscan-playback-')
    work = os.path.join(tmp, 'work')
    # The config by its absolute path: the JSON records name it as given, and the digests must
    # not depend on the folder the test was started from.
    a.config = os.path.abspath(a.config)
    r = subprocess.run([os.path.join(a.bin, 'rhoscan'), 'run', a.config, '--set', 'pipeline.workdir=' + work])
    if r.returncode != 0:
        print('FAIL: rhoscan run exited %d' % r.returncode); return 1
    ok = True
    if a.digests:
        src = os.path.dirname(os.path.dirname(HERE))
        places = [(work, '$WORK'), (os.path.dirname(os.path.abspath(a.config)), '$CONFIGS'), (src, '$SRC')]
        for problem in digests.check(digests.digest_folder(work, places), a.digests, a.record_digests):
            print('FAIL: ' + problem); ok = False
    for name in exp['outputs']:
        if not os.path.exists(os.path.join(work, name)):
            print('FAIL: output %s missing' % name); ok = False
    metrics = json.load(open(os.path.join(work, 'metrics.json')))
    ev = exp.get('eval')
    if ev is not None:
        # rhoscan-eval against the dataset's truth: its thresholds, and its figures under the
        # path "eval." so that expected metrics can pin them (a worse result fails even when it
        # stays under the threshold).
        out = os.path.join(tmp, 'eval')
        cmd = [os.path.join(a.bin, 'rhoscan-eval'), os.path.dirname(os.path.abspath(a.expected)), work, '--out', out]
        for key, opt in (('max_error', '--max-error'), ('max_error_all', '--max-error-all'),
                         ('min_coverage', '--min-coverage')):
            if key in ev and not a.record:
                cmd += [opt, repr(ev[key])]
        r = subprocess.run(cmd)
        if r.returncode != 0:
            print('FAIL: rhoscan-eval exited %d (thresholds %s)' % (r.returncode, ev)); ok = False
        if os.path.exists(os.path.join(out, 'eval.json')):
            metrics['eval'] = json.load(open(os.path.join(out, 'eval.json')))
    truth = read_ply(os.path.join(os.path.dirname(a.expected), exp['truth']))
    res = read_ply(os.path.join(work, 'albedo.ply'))
    parts, finite = albedo_by_part(res, boxes_of(truth), exp.get('part_margin_m', 0.02))
    if not finite:
        print('FAIL: albedo.ply holds a non-finite albedo'); ok = False
    for p, s in sorted(parts.items()):
        print('part %d: %d facets, mean albedo %s (truth %s), mean relative error %.4f' % (
            p, s['facets'], np.round(s['mean'], 4).tolist(), np.round(s['truth'], 4).tolist(), s['mean_rel_error']))
    if a.record:
        for m in exp['metrics']:
            m['value'] = get(metrics, m['path'])
        exp['parts'] = {str(p): round(s['mean_rel_error'], 4) for p, s in parts.items()}
        json.dump(exp, open(a.expected, 'w'), indent=1)
        print('recorded into', a.expected)
        return 0
    for m in exp['metrics']:
        got = get(metrics, m['path'])
        want, tol = m['value'], m['tol']
        bad = got is None or (abs(got - want) > tol * abs(want) if m.get('relative') else abs(got - want) > tol)
        print('%s %s = %s (expected %s, tolerance %s%s)' % ('FAIL' if bad else 'ok  ', m['path'], got, want, tol,
                                                          ' relative' if m.get('relative') else ''))
        ok &= not bad
    for p, s in parts.items():
        if s['mean_rel_error'] > exp['max_mean_rel_error']:
            print('FAIL: part %d error %.4f > %.4f' % (p, s['mean_rel_error'], exp['max_mean_rel_error'])); ok = False
        rec = exp.get('parts', {}).get(str(p))
        if rec is not None and s['mean_rel_error'] > rec + exp['part_regression_tol']:
            print('FAIL: part %d error %.4f worse than recorded %.4f by more than %.4f' % (
                p, s['mean_rel_error'], rec, exp['part_regression_tol'])); ok = False
    if len(parts) < exp.get('min_parts', 1):
        print('FAIL: only %d parts have estimable facets' % len(parts)); ok = False
    if not a.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    print('PASS' if ok else 'FAIL')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
