#!/usr/bin/env python3
"""A stage of every rank whose file rank 0 alone cannot write (the other ranks did their share
and wait): under `mpirun --oversubscribe -np 2` every rank must stop with a non-zero status, in
seconds, and rank 0 must name the file. Before pipeline/stage.c agreed on the failure, rank 0
went to the stage's last barrier while the other rank was in its CPU-time exchange: Open MPI
aborted on the mismatched collectives (a truncation error) and rank 0's message was lost.

For each --block STAGE:FILE: the sample runs once as one process (the earlier stages' files),
FILE in the work folder is replaced by a directory (the atomic rename onto it fails), then
rhoscan-STAGE runs under mpirun with a deadline of --deadline seconds.
"""
import argparse, os, shutil, subprocess, sys, tempfile


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--config', required=True)
    ap.add_argument('--mpirun', default='mpirun')
    ap.add_argument('--block', action='append', required=True, help='STAGE:FILE rank 0 cannot write')
    ap.add_argument('--deadline', type=float, default=120)
    a = ap.parse_args()
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1',
               OMPI_MCA_mpi_yield_when_idle='1')
    top = tempfile.mkdtemp(prefix='rhoscan_mpi_fail_')
    work = os.path.join(top, 'work')
    setwork = ['--set', 'pipeline.workdir=' + work]
    failures = []
    try:
        rc = subprocess.call([os.path.join(a.bin, 'rhoscan'), 'run', a.config, '--force', '--quiet'] + setwork,
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if rc != 0:
            sys.exit('FAIL: the one-process run of %s exited %d' % (a.config, rc))
        for block in a.block:
            stage, name = block.split(':', 1)
            target = os.path.join(work, name)
            if not os.path.exists(target):
                sys.exit('FAIL: the one-process run wrote no %s' % name)
            os.remove(target)
            os.mkdir(target)
            cmd = [a.mpirun, '--oversubscribe', '-np', '2', os.path.join(a.bin, 'rhoscan-' + stage), '--quiet',
                   a.config] + setwork
            try:
                p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   timeout=a.deadline)
            except subprocess.TimeoutExpired:
                failures.append('%s: still running after %.0f s with %s blocked (a rank waits forever)'
                                % (stage, a.deadline, name))
                continue
            out = p.stdout.decode(errors='replace')
            if p.returncode == 0:
                failures.append('%s: exited 0 although %s could not be written' % (stage, name))
            elif name not in out:
                failures.append('%s: exited %d without naming %s:\n%s' % (stage, p.returncode, name, out[-2000:]))
            else:
                print('%s: exited %d, naming %s' % (stage, p.returncode, name))
            os.rmdir(target)
    finally:
        shutil.rmtree(top, ignore_errors=True)
    if failures:
        sys.exit('FAIL:\n' + '\n'.join(failures))
    print('PASS: every blocked stage stopped on every rank')


if __name__ == '__main__':
    main()
