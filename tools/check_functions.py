#!/usr/bin/env python3
"""Lists the functions of the libraries and stages longer than a limit (default 120 lines, from
the line that names the function to its closing brace), and fails when any is found outside
the ray-tracing kernels named in KERNELS: a function that long is several steps that want
names of their own. Relies on the layout .clang-format gives: a function's opening brace
alone on a line in column 0, its closing brace likewise.

Usage: tools/check_functions.py [--limit N] [--all] [ROOT]
"""
import argparse, os, re, subprocess, sys

# Inner loops where one body keeps the hot state in registers; splitting them costs speed.
KERNELS = {
    ('light/gather.c', 'gather_round'),
}
FOLDERS = ('common/', 'calib/', 'sky/', 'meshing/', 'light/', 'pipeline/', 'stages/')
NAME = re.compile(r'([A-Za-z_]\w*)\s*\(')


def functions(text):
    """(name, first line, last line) of each function definition (1-based)."""
    lines = text.split('\n')
    out = []
    for i, line in enumerate(lines):
        if line != '{' or i == 0:
            continue
        # the signature: back to the line that starts in column 0
        j = i - 1
        while j > 0 and (lines[j].startswith((' ', '\t')) or lines[j] == ''):
            j -= 1
        m = NAME.search(lines[j])
        if not m or lines[j].startswith(('#', '/*', ' *', 'typedef', 'struct', 'enum', 'union')):
            continue
        k = i + 1
        while k < len(lines) and lines[k] != '}':
            k += 1
        out.append((m.group(1), j + 1, k + 1))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--limit', type=int, default=120)
    ap.add_argument('--all', action='store_true', help='list the kernels too')
    ap.add_argument('root', nargs='?', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
    a = ap.parse_args()
    files = subprocess.run(['git', '-C', a.root, 'ls-files', '--cached', '--others', '--exclude-standard',
                            '*.c', '*.cpp'], capture_output=True, text=True, check=True).stdout.split()
    bad = 0
    for f in sorted(files):
        if not f.startswith(FOLDERS) or not os.path.exists(os.path.join(a.root, f)):
            continue
        for name, first, last in functions(open(os.path.join(a.root, f), errors='replace').read()):
            n = last - first + 1
            if n <= a.limit:
                continue
            kernel = (f, name) in KERNELS
            if kernel and not a.all:
                continue
            print('%s:%d: %s is %d lines%s' % (f, first, name, n, ' (kernel, allowed)' if kernel else ''))
            bad += not kernel
    print('check_functions: %d functions over %d lines outside the kernels' % (bad, a.limit))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
