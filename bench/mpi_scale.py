#!/usr/bin/env python3
"""mpi_scale: the costly stage programs of an MPI build (cmake -DRHOSCAN_MPI=ON) on one bench
work folder, as one process without mpirun and under `mpirun --oversubscribe -np K` for every K
of --ranks; prints per stage the CPU seconds (user + system) of every rank and their total, the
total's ratio to the one process, the peak RSS of every rank, and the `mpi` record of the
stage's JSON (bytes and messages through common/par.c at rank 0; for render also per sweep of
the forward solve). Then checks that every output file is the same for every K: PLY, EXR and
PNG byte for byte, JSON without the keys that are no result (tests/playback/digests.py, and the
`mpi` record). docs/BENCHMARKS.md, section MPI ranks.

    rhoscan-bench --facets 100000 --rows scale --truth-factor 1 --work BENCH
    bench/mpi_scale.py --bin build-mpi --work BENCH/facets_100000 [--ranks 1,2,3,4] [--out DIR]

Each run gets a fresh copy of the folder's inputs (the scene, panorama, mesh and config), so the
runs never read one another's outputs; only the JSON of each run is kept, the rest is deleted
after its digests are taken (at 10^6 facets transport.ply alone is 444 MB a run). Exit status 1
when an output differs between runs. Every process runs under nice -n 10.
"""
import argparse, json, os, shutil, subprocess, sys, tempfile, time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'tests', 'playback'))
import digests  # noqa: E402

digests.VOLATILE.add('mpi')  # ranks, threads per rank, bytes exchanged: the host's, not the result's

# What rhoscan-bench writes before the stages; everything else in the folder is a stage's output.
INPUTS = ('config.ini', 'scene.ply', 'pano.exr', 'mesh.ply', 'mesh.json')
# The bench's `scale` row (bench/bench.c, SWEEP): the sample counts its figures are taken at.
SCALE_ROW = ('irradiance.samples=64', 'irradiance.sky_samples=64', 'irradiance.sun_samples=16',
             'reflectance.method=interreflection')
# /usr/bin/time per rank into PREFIX.RANK (Open MPI names the rank in the environment).
TIMED = 'exec /usr/bin/time -f "%U %S %M %e" -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"'


def run_stage(a, stage, work, ranks, logdir, env):
    """Runs one stage program; returns [(cpu_s, peak_mb), ...] per rank and its wall seconds."""
    prefix = os.path.join(logdir, '%s.time' % stage)
    cmd = ['nice', '-n', '10']
    if ranks:
        cmd += [a.mpirun, '--oversubscribe', '-np', str(ranks)]
    cmd += ['sh', '-c', TIMED, prefix, os.path.join(a.bin, 'rhoscan-' + stage), '--quiet']
    for s in list(SCALE_ROW) + a.set:
        cmd += ['--set', s]
    cmd.append(os.path.join(work, 'config.ini'))
    t0 = time.time()
    with open(os.path.join(logdir, stage + '.log'), 'w') as log:
        rc = subprocess.call(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    wall = time.time() - t0
    if rc != 0:
        sys.stdout.write(open(os.path.join(logdir, stage + '.log')).read()[-3000:])
        sys.exit('mpi_scale: %s exited %d: %s' % (stage, rc, ' '.join(cmd)))
    per_rank = []
    for r in range(ranks or 1):
        user, system, rss_kb, _ = open('%s.%d' % (prefix, r)).read().split()[-4:]
        per_rank.append((float(user) + float(system), float(rss_kb) / 1024.0))
    return per_rank, wall


def mpi_record(work, stage):
    """The scalar figures of the stage JSON's `mpi` record, and its forward solve's sweeps."""
    try:
        doc = json.load(open(os.path.join(work, stage + '.json')))
    except (OSError, ValueError):
        return {}, None
    rec = {k: v for k, v in doc.get('mpi', {}).items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    sweeps = doc.get('forward_iterations')
    # The forward solve exchanges L once per sweep and once more for the last gather.
    return rec, (sweeps + 1 if isinstance(sweeps, int) else None)


def fresh_copy(src, dst):
    os.makedirs(dst)
    for name in INPUTS:
        if not os.path.exists(os.path.join(src, name)):
            sys.exit('mpi_scale: %s: no %s (expected a folder written by rhoscan-bench)' % (src, name))
        shutil.copy(os.path.join(src, name), dst)


def clear_outputs(work):
    for name in os.listdir(work):
        if not name.endswith(('.json', '.time', '.log')) and name not in INPUTS:
            p = os.path.join(work, name)
            shutil.rmtree(p) if os.path.isdir(p) else os.remove(p)


def fmt_mb(b):
    return '%.2f MB' % (b / 1e6)


def memory(a):
    """Bytes per facet of the replicated state, from the folder's own irradiance run."""
    rc = subprocess.call([os.path.join(a.bin, 'rhoscan-facet-bytes'), os.path.join(a.work, 'mesh.ply')])
    if rc != 0:
        return rc
    irr = json.load(open(os.path.join(a.work, 'irradiance.json')))
    nf = int(subprocess.check_output(['sh', '-c', "sed -n 's/^element face //p' \"$0\" | head -1",
                                      os.path.join(a.work, 'mesh.ply')]).decode())
    occ = irr.get('occluders', {})
    rows = [('free-space map (occluders grid_mb)', occ.get('grid_mb', 0) * 1048576.0),
            ('K in memory (kernel_entries x 12)', irr['kernel_entries'] * 12.0),
            ('transport.ply on disk', os.path.getsize(os.path.join(a.work, 'transport.ply'))),
            ('irradiance stage peak RSS', irr['peak_rss_mb'] * 1048576.0)]
    for what, b in rows:
        print('%-34s %14.0f bytes %9.1f bytes/facet' % (what, b, b / nf))
    print('free-space grid %s cells of %.3f m; %d kernel entries (%.2f a facet, %d facets gathered); '
          '%.4g rays (%.1f a gathered facet)' % ('x'.join(str(g) for g in occ.get('grid', [])), occ.get('cell_m', 0),
                                                  irr['kernel_entries'], irr['kernel_entries'] / nf,
                                                  irr['facets_gathered'], irr['rays'],
                                                  irr['rays'] / max(irr['facets_gathered'], 1)))
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--bin', required=True, help='the MPI build folder (rhoscan-STAGE programs)')
    ap.add_argument('--work', required=True, help='a folder rhoscan-bench wrote (WORK/facets_N)')
    ap.add_argument('--ranks', default='1,2,3,4')
    ap.add_argument('--stages', default='observe,irradiance,reflectance,render')
    ap.add_argument('--mpirun', default='mpirun')
    ap.add_argument('--out', help='where the runs go (default: a temporary folder, removed)')
    ap.add_argument('--set', action='append', default=[], help='section.key=value for every run')
    ap.add_argument('--memory', action='store_true',
                    help='only bytes per facet: rhoscan-facet-bytes on the folder\'s mesh, and the free-space '
                    'map, kernel and peak memory from its irradiance.json (run nothing else)')
    a = ap.parse_args()
    if a.memory:
        return memory(a)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1',
               OMPI_MCA_mpi_yield_when_idle='1', OMP_WAIT_POLICY='passive')
    stages = a.stages.split(',')
    top = a.out or tempfile.mkdtemp(prefix='rhoscan_mpi_scale_')
    runs = [('one process', 0)] + [('-np %s' % k, int(k)) for k in a.ranks.split(',')]
    table = {}  # (run, stage) -> (per_rank, wall, mpi record, sweeps)
    outputs = {}
    try:
        for label, ranks in runs:
            work = os.path.join(top, 'np%d' % ranks if ranks else 'single')
            if os.path.exists(work):
                shutil.rmtree(work)
            fresh_copy(a.work, work)
            for stage in stages:
                per_rank, wall = run_stage(a, stage, work, ranks, work, env)
                rec, sweeps = mpi_record(work, stage)
                table[label, stage] = (per_rank, wall, rec, sweeps)
                print('%-12s %-12s CPU %s s, wall %.1f s' % (label, stage, ' + '.join('%.2f' % c for c, _ in per_rank),
                                                            wall), flush=True)
            outputs[label] = digests.digest_folder(work, [(work, 'WORK')])
            clear_outputs(work)
    finally:
        if not a.out:
            shutil.rmtree(top, ignore_errors=True)

    print('\nCPU seconds (user + system) per rank; total; ratio to one process; peak RSS per rank:')
    print('| stage | run | CPU s per rank | total | ratio | peak RSS MB per rank | wall s |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    for stage in stages:
        base = sum(c for c, _ in table['one process', stage][0])
        for label, _ in runs:
            per_rank, wall, _, _ = table[label, stage]
            total = sum(c for c, _ in per_rank)
            print('| %s | %s | %s | %.2f | %.2f x | %s | %.1f |' % (
                stage, label, ', '.join('%.2f' % c for c, _ in per_rank), total, total / base if base else 0,
                ', '.join('%.0f' % m for _, m in per_rank), wall))
    print('\nThe `mpi` record of each stage JSON (rank 0: payload bytes sent + received, messages):')
    print('| stage | run | bytes | messages | per sweep of the forward solve |')
    print('| --- | --- | --- | --- | --- |')
    for stage in stages:
        for label, ranks in runs[1:]:
            _, _, rec, sweeps = table[label, stage]
            b, m = rec.get('rank0_bytes', 0), rec.get('rank0_messages', 0)
            per = ('%s, %.1f messages (%d sweeps)' % (fmt_mb(b / sweeps), m / sweeps, sweeps)
                   if sweeps and stage == 'render' else '')
            print('| %s | %s | %s | %d | %s |' % (stage, label, fmt_mb(b), m, per))

    want = outputs['one process']
    problems = []
    for label, got in outputs.items():
        for name in sorted(set(want) | set(got)):
            if want.get(name) != got.get(name):
                problems.append('%s: %s %s' % (label, name, 'differs' if name in got and name in want
                                                else 'missing' if name in want else 'extra'))
    print('\n%d output files compared between the one process and %s' % (len(want), ', '.join(l for l, _ in runs[1:])))
    if problems:
        print('\n'.join(problems))
        print('DIFFER: %d files' % len(problems))
        return 1
    print('IDENTICAL: every output file the same for every run')
    return 0


if __name__ == '__main__':
    sys.exit(main())
