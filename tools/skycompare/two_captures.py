#!/usr/bin/env python3
"""Albedo error with one capture against two captures (issue 8, part 2): writes docs/SKY-CAPTURES.md.

usage: two_captures.py --bin BUILD --shared SHARED --out docs/SKY-CAPTURES.md --work DIR \
           --pair NAME INSIDE_DIR OUTSIDE_DIR [--pair ...]

Each pair's two folders are tools/refscene outputs of the same scene and sky (tools/skycompare/
courtyard.json and courtyard_outside.json: the same boxes and environment, the camera inside and
outside the courtyard); pairs differ in their Cycles samples, so the tables show which differences
stand above the render's noise. For each pair rhoscan runs once from the inside render's scan
(ingest, mesh, observe), then
irradiance and reflectance with [sky] fill = model: with the inside capture alone, and with the
outside panorama added as [capture.outside] (its sky fills what the inside camera cannot see), and
with the true sky (env.exr as [sky] panorama) as the reference. The shared evaluator
(SHARED/tools/eval_albedo.py) gives the area-weighted mean relative albedo error over interior
facets, per part and overall.
"""
import argparse, json, os, shutil, sys

from sky_compare import run   # one way to run a stage and log it, shared with sky_compare.py


def pose(sdir):
    t = json.load(open(os.path.join(sdir, 'truth.json')))
    rot = ' '.join('%.17g' % (0 if abs(v) < 1e-12 else v) for row in t['camera_rotation_local_to_world'] for v in row)
    return t, ' '.join('%.17g' % v for v in t['camera_position']), rot


def check_same_scene(tin, tout):
    """The two renders must differ only in the camera (and sampling)."""
    for k in ('parts', 'env', 'sun', 'scanner_position'):
        if tin.get(k) != tout.get(k):
            sys.exit('FAIL: the inside and outside renders differ in %s' % k)


WHY = """## What the tables show

- Two captures lower the error on the scanned mesh and on the exact geometry, with every seed,
  whenever the outside panorama is rendered with as many samples as the inside one. The gain is
  largest on the sunlit wall_north, which sees the ground beyond the low south wall: one capture
  fills that with the ground model (level ground in full sun out to the horizon), while the
  outside camera saw the render's ground as it is, which ends 20 m out where the sky file's own
  ground takes over.
- With an outside panorama of 16 samples (the pair named so), two captures are worse than one on
  the scan with every seed, so the gather's noise is not the cause. Its sun is: 2.6 % brighter
  than the sky file's (the "sun's flux" line). A sun of a few pixels at some 10^4 times the sky
  carries the camera's anti-aliasing noise, and the merged map takes the mean of both captures'
  suns, which raises E_sky on the sunlit walls by about 1 %. Earlier versions of this page had
  only that pair.
- On the scan, the true sky is not the lowest row. The scan lacks the ground beyond the low
  south wall: on the exact mesh, 6 % of wall_east's kernel (0.125 of 2.11 sr, from
  transport.ply) points at it. On the scan those rays read the sky map below the horizon, and
  env.exr holds the sky file's photographed ground there, not the scene's. The captures show the
  scene's ground, from afar (one capture: the ground model) or as seen from outside.
  tools/skycompare/irradiance_by_part.py measures it against Cycles' passes: on the scan,
  wall_east's E_sky + G is 1.6 % low with the true sky, 0.2 % high with one capture.

"""


HOW = """## How several captures are merged (sky/skyenv.c)

- Every capture's sky pixels (rays from its position that miss the model, usable values) are
  spread onto the map of the first capture ([capture]); a sky panorama ([sky] panorama) still
  overrides every direction it sees.
- Each further capture ([capture.NAME]) is brought to the first capture's exposure by the
  per-channel median ratio over the sky both see (bright pixels left out).
- Where several captures see a direction, the value is their weighted mean. A capture's weight
  there is the solid angle of its pixels times how directly it saw the direction:
  - a sky pixel next to the model's silhouette in that capture is a mixed pixel (part wall, part
    sky, plus the panorama's filter footprint): weight 0.02 at 1 pixel from a facet pixel, 0.2 at
    2 pixels, 1 further out;
  - a capture whose pixel is larger than the map pixel (a coarser panorama) has weight scaled by
    map pixel solid angle / its pixel solid angle (at most 1): it saw the direction blurred.
  A clean view of the first capture (weight 1) therefore dominates, and a clean view of another
  capture replaces the first capture's mixed silhouette pixels.
- What no capture saw is filled (`[sky] fill`), from the merged measured sky.
"""


EXACT_EDGE_M = 0.45   # longest facet edge of the exact mesh: about 10^5 facets for the courtyard


def subdivide(shared, truth_ply, out_ply, max_edge):
    """truth.ply's triangles split at their longest edge until every edge is at most max_edge;
    written as a binary PLY mesh. Returns the facet count."""
    import numpy as np
    sys.path.insert(0, os.path.join(shared, 'tools'))
    from plyio import read_ply, faces_of
    t = read_ply(truth_ply)
    V = np.stack([t['vertex'][c] for c in 'xyz'], 1).astype(float)
    index, verts, tris = {}, [], []

    def vid(p):
        k = tuple(np.round(p, 9))
        if k not in index:
            index[k] = len(verts)
            verts.append(k)
        return index[k]
    stack = [(V[a], V[b], V[c]) for a, b, c in faces_of(t)]
    while stack:
        a, b, c = stack.pop()
        e = [np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)]
        j = int(np.argmax(e))
        if e[j] <= max_edge:
            tris.append((vid(a), vid(b), vid(c)))
        elif j == 0:
            m = (a + b) / 2
            stack += [(a, m, c), (m, b, c)]
        elif j == 1:
            m = (b + c) / 2
            stack += [(a, b, m), (a, m, c)]
        else:
            m = (c + a) / 2
            stack += [(a, b, m), (m, b, c)]
    rec = np.zeros(len(tris), dtype=[('n', 'u1'), ('i', '<i4', 3)])
    rec['n'] = 3
    rec['i'] = np.array(tris)
    with open(out_ply + '.tmp', 'wb') as f:
        f.write(('ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n'
                 'property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n'
                 % (len(verts), len(tris))).encode())
        f.write(np.array(verts, dtype='<f4').tobytes())
        f.write(rec.tobytes())
    os.replace(out_ply + '.tmp', out_ply)
    return len(tris)


def median_radiance_noise(albedo_ply, shared):
    """Median radiance_sigma_rel over observed, estimable facets: the render's own noise in L."""
    import numpy as np
    sys.path.insert(0, os.path.join(shared, 'tools'))
    from plyio import read_ply
    fp = read_ply(albedo_ply)['face']
    sel = (fp['observed'] > 0) & (fp['estimable'] > 0)
    return float(np.median(fp['radiance_sigma_rel'][sel])) if sel.any() else float('nan')


def sun_flux_ratio(pano, env):
    """The sun's flux in a capture over that in env.exr (the sky alone, same orientation), summed
    over env.exr's pixels above 50 x the median of its upper half. A sun of a few pixels at 10^4
    times the sky carries the camera's anti-aliasing noise: 2.6 % at 16 samples here."""
    import numpy as np
    from irradiance_by_part import image   # one EXR reader for the skycompare tools
    e, p = image(env)[:, :3], image(pano)[:, :3]
    if e.shape != p.shape:
        return float('nan')
    lum = e.mean(1)
    sun = lum > 50 * np.median(lum[:lum.size // 2])   # rows first: the first half is the upper one
    return float(p[sun].mean(1).sum() / e[sun].mean(1).sum())


def compare(a, inside, rhoscan, log, wdir, base, second, true_sky, first_stages):
    """One capture, two captures and the true sky from the same mesh and observation (work folder
    wdir/work), each with every seed of a.seeds; returns per run (label, interior error, per-part
    errors, irradiance metrics, median noise of L) of the first seed, and the other seeds' interior
    errors."""
    os.makedirs(wdir, exist_ok=True)
    cfg1, cfg2 = os.path.join(wdir, 'one.ini'), os.path.join(wdir, 'two.ini')
    open(cfg1, 'w').write(base)
    open(cfg2, 'w').write(base + second)
    work = os.path.join(wdir, 'work')
    if not (a.reuse and os.path.exists(os.path.join(work, 'observe.ply'))):
        for stage in first_stages:
            run([rhoscan, 'run', '--only', stage, cfg1], log)
    res = []
    for label, cfg, sets in (('one capture (inside)', cfg1, []), ('two captures (inside + outside)', cfg2, []),
                             ('true sky', cfg1, true_sky)):
        tag = label.split(' ')[0]
        other_seeds = []
        # The first seed's run is the row; the others only move the gather's own Monte Carlo noise,
        # so their interior errors say which differences between rows stand above it.
        for seed in reversed(a.seeds):
            for stage in ('irradiance', 'reflectance'):
                run([rhoscan, 'run', '--only', stage, cfg, '--set', 'sky.fill=model',
                     '--set', 'irradiance.seed=%d' % seed] + sets, log)
            ej = os.path.join(wdir, 'eval_%s_seed%d.json' % (tag, seed))
            run([sys.executable, os.path.join(a.shared, 'tools', 'eval_albedo.py'), os.path.join(inside, 'truth.ply'),
                 os.path.join(work, 'albedo.ply'), '--json', ej], log)
            ev = json.load(open(ej))
            if seed != a.seeds[0]:
                other_seeds.append(ev['interior']['mean_rel'])
        shutil.copy(os.path.join(work, 'albedo.ply'), os.path.join(wdir, 'albedo_%s.ply' % tag))
        irr = json.load(open(os.path.join(work, 'irradiance.json')))
        im = irr.get('metrics', irr)
        parts = {int(p): v['mean_rel'] for p, v in ev['parts'].items() if v}
        res.append((label, ev['interior']['mean_rel'], parts, im,
                    median_radiance_noise(os.path.join(work, 'albedo.ply'), a.shared), other_seeds[::-1]))
        print('%s, %s: interior mean %.4f' % (os.path.basename(wdir), label, ev['interior']['mean_rel']))
    return res


def run_pair(a, rhoscan, log, name, inside, outside):
    """The six runs of one pair (scan and exact geometry, each with one capture, two and the true
    sky); returns the part names, the pair's heading and [(title, results)] for write_tables."""
    tin, cam_in, rot_in = pose(inside)
    tout, cam_out, rot_out = pose(outside)
    check_same_scene(tin, tout)
    wdir = os.path.join(a.work, name)
    base = ('[pipeline]\nworkdir = work\n[ingest]\nscan = %s\n[capture]\npanorama = %s\nposition = %s\nrotation = %s\n'
            % (os.path.join(inside, 'scan.ptx'), os.path.join(inside, 'pano.exr'), cam_in, rot_in))
    second = ('[capture.outside]\npanorama = %s\nposition = %s\nrotation = %s\n'
              % (os.path.join(outside, 'pano.exr'), cam_out, rot_out))
    pos = [float(v) for v in cam_in.split()]
    true_sky = ['--set', 'sky.panorama=' + os.path.join(inside, 'env.exr'),
                '--set', 'sky.position=%.9g %.9g %.9g' % (pos[0], pos[1], pos[2] + 1000), '--set', 'sky.rotation=' + rot_in]
    scanned = compare(a, inside, rhoscan, log, os.path.join(wdir, 'scan'), base, second, true_sky,
                      ('ingest', 'mesh', 'observe'))
    # The same three runs on the scene's own boxes, finely triangulated: what the captures give when
    # the model holds everything the walls see (the scan misses the ground beyond the low wall).
    exact_ply = os.path.join(wdir, 'exact_mesh.ply')
    if not (a.reuse and os.path.exists(exact_ply)):
        print('exact mesh: %d facets' % subdivide(a.shared, os.path.join(inside, 'truth.ply'), exact_ply, EXACT_EDGE_M))
    exact_base = base.replace('[ingest]\nscan = %s\n' % os.path.join(inside, 'scan.ptx'),
                              '[mesh]\ninput_mesh = %s\n' % exact_ply)
    exact = compare(a, inside, rhoscan, log, os.path.join(wdir, 'exact'), exact_base, second, true_sky,
                    ('mesh', 'observe'))
    names = [p['name'] for p in tin['parts']]
    env = os.path.join(inside, 'env.exr')
    head = ('## %s: inside %s, outside %s Cycles samples per pixel, outside camera %s m south of the south wall\n\n'
            'The sun\'s flux in each panorama over that in env.exr: inside %.3f, outside %.3f.\n\n'
            % (name, tin.get('samples', '?'), tout.get('samples', '?'),
               '%.0f' % abs(tout['camera_position'][1] - tin['parts'][-1]['min'][1]) if 'wall_south' in names else 'some',
               sun_flux_ratio(os.path.join(inside, 'pano.exr'), env), sun_flux_ratio(os.path.join(outside, 'pano.exr'), env)))
    return names, head, (('Scanned mesh (what the pipeline runs on)', scanned),
                         ('Exact geometry (the scene\'s boxes, edges at most %.2f m)' % EXACT_EDGE_M, exact))


def write_tables(fh, names, head, tables):
    fh.write(head)
    for title, res in tables:
        fh.write('### %s\n\n' % title)
        fh.write('| run | interior error | ' + ' | '.join(names) + ' | map pixels from the 2nd capture | '
                 'pixels filled | share of E_sky filled | median noise of L | interior error, other seeds |\n')
        fh.write('| --- | --- | ' + ' | '.join('---' for _ in names) + ' | --- | --- | --- | --- | --- |\n')
        for label, interior, parts, im, noise, others in res:
            fh.write('| %s | %.2f %% | %s | %s | %s | %.1f %% | %.2f %% | %s |\n' % (
                label, 100 * interior, ' | '.join('%.2f %%' % (100 * parts[i]) if i in parts else '-'
                                                 for i in range(len(names))),
                im.get('sky_other_capture_pixels', 0), im.get('filled_pixels', '-'),
                100 * im.get('sky_filled_share', 0), 100 * noise,
                ', '.join('%.2f %%' % (100 * e) for e in others) or '-'))
        diffs = [100 * (t - o) for o, t in zip([res[0][1]] + res[0][5], [res[1][1]] + res[1][5])]
        fh.write('\nTwo captures against one, per seed: %s points (%s).\n\n'
                 % (', '.join('%+.2f' % d for d in diffs),
                    'lower with every seed' if max(diffs) < 0 else 'not lower with every seed'))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--shared', required=True)
    ap.add_argument('--out', required=True)
    ap.add_argument('--work', required=True)
    ap.add_argument('--pair', nargs=3, action='append', required=True, metavar=('NAME', 'INSIDE', 'OUTSIDE'),
                    help='a name, the render with the camera inside the courtyard, the same scene with it outside')
    ap.add_argument('--seeds', default='1,7,1234',
                    help='comma-separated [irradiance] seeds; the first gives the tables, the others the spread')
    ap.add_argument('--reuse', action='store_true', help='keep the mesh and observation of an earlier run')
    a = ap.parse_args()
    a.seeds = [int(v) for v in a.seeds.split(',')]
    os.makedirs(a.work, exist_ok=True)
    log = os.path.join(a.work, 'run.log')
    rhoscan = os.path.join(a.bin, 'rhoscan')
    pairs = [run_pair(a, rhoscan, log, name, inside, outside) for name, inside, outside in a.pair]
    with open(a.out + '.tmp', 'w') as fh:
        fh.write('# Sky from two captures: albedo error with one and with two panoramas\n\n'
                 'Generated by `tools/skycompare/two_captures.py --bin BUILD --shared SHARED --out '
                 'docs/SKY-CAPTURES.md --work DIR --pair NAME COURTYARD COURTYARD_OUT ...` (do not edit by '
                 'hand), from tools/refscene renders of tools/skycompare/courtyard.json (camera inside the '
                 'courtyard) and courtyard_outside.json (the same scene and sky, camera outside the south '
                 'wall), each pair at its own Cycles samples. Every run uses `[sky] fill = model` and starts from the '
                 'same mesh and observation: the inside render\'s scan, or the scene\'s own boxes split into facets; '
                 '"two captures" adds the outside panorama as `[capture.outside]`; "true sky" gives the environment '
                 'alone (env.exr) as `[sky] panorama`. Errors: the shared evaluator\'s area-weighted mean relative '
                 'albedo error over interior facets (`eval_albedo.py`), overall and per part, with the gather\'s seed '
                 '([irradiance] seed) %s; the other seeds\' interior errors show the gather\'s own noise. '
                 '"median noise of L" '
                 'is the median `radiance_sigma_rel` of the observed facets: the render\'s own noise in what '
                 'each facet\'s albedo divides.\n\n' % a.seeds[0])
        for names, head, tables in pairs:
            write_tables(fh, names, head, tables)
        fh.write(WHY)
        fh.write('\n' + HOW)
    os.replace(a.out + '.tmp', a.out)
    print('wrote ' + a.out)


if __name__ == '__main__':
    main()
