#!/usr/bin/env python3
"""The MPI build (cmake -DRHOSCAN_MPI=ON) against itself: `rhoscan run CONFIG` as one process,
then under `mpirun --oversubscribe -np N` for every N of --ranks, each into a fresh work folder;
every output file must be the same byte for byte: PLY, EXR, PNG, GLB, OBJ and MTL as written,
JSON once the keys that are no result are taken out (tests/playback/digests.py: timings, rates,
peak memory, the fingerprint; and the `mpi` record of ranks and traffic) and the work folders'
paths replaced. report.html is left out: it shows the timings.

--split STAGE (repeatable) names a stage that must have split its work over the ranks: with
N > 1 its record (STAGE.json) must say it ran on every rank, each with CPU time of its own, and
--expect FILE (repeatable) a file the single process must have written: the comparison then
covers that stage's exchange (a rank's lost share changes rank 0's files) and not a rank-0-only
run of it.

Open MPI refuses root (CI runs as root) unless told twice; idle ranks yield the core instead of
polling (mpi_yield_when_idle), since N ranks share the test machine's cores.
"""
import argparse, json, os, shutil, subprocess, sys, tempfile, time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'playback'))
import digests  # noqa: E402

digests.VOLATILE.add('mpi')  # ranks, threads per rank, bytes exchanged: the host's, not the result's


def run(cmd, env, log):
    t0 = time.time()
    with open(log, 'w') as fh:
        rc = subprocess.call(cmd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    if rc != 0:
        sys.stdout.write(open(log).read()[-4000:])
        sys.exit('FAIL: %s exited %d' % (' '.join(cmd), rc))
    print('%.1f s: %s' % (time.time() - t0, ' '.join(cmd)))


ROW_STAGES = ('observe', 'render')  # split by the panorama's rows over the ranks


def rows_problems(work, ranks):
    """What is wrong with the rows each rank reported in the row-split stages' `mpi` record
    (pipeline/stage.c): every rank must have computed its own band of rs_par_range, the bands
    covering the panorama's rows once (a rank that skipped its rows, or a stage left on rank 0,
    shows here even when rank 0 alone would have written the same files)."""
    import OpenImageIO as oiio
    spec = oiio.ImageInput.open(os.path.join(work, 'facet_id.exr'))
    h = spec.spec().height
    spec.close()
    want = [h // ranks + (1 if r < h % ranks else 0) for r in range(ranks)]
    out = []
    for st in ROW_STAGES:
        path = os.path.join(work, st + '.json')
        if not os.path.exists(path):
            continue  # the sample's run did not reach the stage: the file comparison says so
        got = json.load(open(path)).get('mpi', {}).get('rows_per_rank')
        if got != want:
            out.append('-np %d: %s.json rows_per_rank %s, expected %s' % (ranks, st, got, want))
    return out

def check_split(work, stage, ranks):
    """STAGE.json of an N-rank run: the stage ran on every rank, each with CPU time of its own."""
    with open(os.path.join(work, stage + '.json')) as fh:
        mpi = json.load(fh).get('mpi', {})
    per = mpi.get('cpu_time_s_per_rank', [])
    if mpi.get('ran_on') != 'every rank' or len(per) != ranks or not all(c > 0 for c in per):
        sys.exit('FAIL: -np %d: %s did not split over the ranks (mpi record %s)' % (ranks, stage, mpi))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--config', required=True)
    ap.add_argument('--mpirun', default='mpirun')
    ap.add_argument('--ranks', default='1,2,3')
    ap.add_argument('--set', action='append', default=[], help='section.key=value for every run')
    ap.add_argument('--split', action='append', default=[], help='a stage that must run on every rank')
    ap.add_argument('--expect', action='append', default=[], help='a file the single run must write')
    a = ap.parse_args()
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1',
               OMPI_MCA_mpi_yield_when_idle='1')
    rhoscan = os.path.join(a.bin, 'rhoscan')
    top = tempfile.mkdtemp(prefix='rhoscan_mpi_')
    sets = []
    for s in a.set:
        sets += ['--set', s]
    try:
        works = {}
        row_problems = []
        for n in ['single'] + a.ranks.split(','):
            work = os.path.join(top, 'work_' + n)
            cmd = [rhoscan, 'run', a.config, '--force', '--set', 'pipeline.workdir=' + work] + sets
            if n != 'single':
                cmd = [a.mpirun, '--oversubscribe', '-np', n] + cmd
            run(cmd, env, os.path.join(top, n + '.log'))
            if n != 'single' and int(n) > 1:
                row_problems += rows_problems(work, int(n))
            works[n] = digests.digest_folder(work, [(work, 'WORK')])
            if n != 'single' and int(n) > 1:
                for stage in a.split:
                    check_split(work, stage, int(n))
        want = works.pop('single')
        if len(want) < 5:
            sys.exit('FAIL: the single-process run wrote only %d files' % len(want))
        missing = [f for f in a.expect if f not in want]
        if missing:
            sys.exit('FAIL: the single-process run did not write %s' % ', '.join(missing))
        problems = []
        for n, got in works.items():
            for name in sorted(set(want) | set(got)):
                if want.get(name) != got.get(name):
                    problems.append('-np %s: %s %s' % (n, name, 'differs' if name in got and name in want
                                                      else 'missing' if name in want else 'extra'))
        print('%d files compared for -np %s' % (len(want), a.ranks))
        problems += row_problems
        if problems:
            print('\n'.join(problems))
            sys.exit('FAIL: %d problems: files that differ from the single process, or rows split wrongly' % len(problems))
        print('PASS: every output identical for -np %s' % a.ranks)
    finally:
        shutil.rmtree(top, ignore_errors=True)


if __name__ == '__main__':
    main()
