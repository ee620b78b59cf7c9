#!/usr/bin/env python3
"""Checks the include graph against the layers of docs/DESIGN.md (section Layers), lowest first:

    common  <-  calib, sky, meshing  <-  light  <-  pipeline  <-  stages/<stage>  <-  programs

A library folder includes only itself and the folders below it (calib, sky and meshing know
nothing of each other; a stage folder knows no other stage). Programs (tests/, bench/, tools/, every
stages/*/main.c and the driver stages/rhoscan.c) may include anything; no library includes
them. Every quoted include is written from the repository root and names a file that exists.
Between modules (x.c with x.h) there is no cycle.

Usage: tools/check_layers.py [ROOT]   (exit 0 when clean, 1 with one line per violation)
"""
import os, re, subprocess, sys

BELOW = {
    'common': set(),
    'calib': {'common'},
    'sky': {'common'},
    'meshing': {'common'},
    'light': {'common', 'sky'},
    'pipeline': {'common', 'calib', 'sky', 'meshing', 'light'},
    'stages': {'common', 'calib', 'sky', 'meshing', 'light', 'pipeline'},
}
PROGRAM_DIRS = ('tests/', 'bench/', 'tools/')
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def layer_of(path):
    """(layer, unit) of a source file: unit is what it may include freely (its own folder;
    a stage's folder); layer None for programs."""
    if path.startswith(PROGRAM_DIRS) or re.match(r'stages/[^/]+/main\.c$', path) or path == 'stages/rhoscan.c':
        return None, None
    top = path.split('/')[0]
    if top == 'stages':
        parts = path.split('/')
        unit = 'stages/' + parts[1] if len(parts) > 2 else 'stages'
        return 'stages', unit
    return (top, top) if top in BELOW else (None, None)


def allowed(src_layer, src_unit, dst):
    dst_layer, dst_unit = layer_of(dst)
    if dst_layer is None:
        return False, 'a program\'s file'
    if dst_unit == src_unit or dst_layer in BELOW[src_layer]:
        return True, ''
    if src_unit != 'stages' and dst_unit == 'stages' and src_layer == 'stages':
        return True, ''                         # stages/stages.h: the stage functions' declarations
    if src_unit == 'stages' and dst_layer == 'stages':
        return True, ''                         # the table knows every stage
    return False, 'layer %s' % (dst_unit if dst_layer == 'stages' else dst_layer)


def module_of(path):
    """x.c, x.h and x's private header (x_internal.h, x_priv.h) are one module."""
    return re.sub(r'_(internal|priv)$', '', os.path.splitext(path)[0])


def sources(root):
    out = subprocess.run(['git', '-C', root, 'ls-files', '--cached', '--others', '--exclude-standard',
                          '*.c', '*.h', '*.cpp'], capture_output=True, text=True, check=True).stdout.split()
    return [p for p in out if os.path.exists(os.path.join(root, p))]


def find_cycle(edges):
    """A cycle among modules as a list, or None (iterative depth-first search)."""
    state, stack_of = {}, {}
    for start in sorted(edges):
        if start in state:
            continue
        path, iters = [start], [iter(sorted(edges[start]))]
        state[start] = 1
        while path:
            nxt = next(iters[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                iters.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif nxt not in state:
                state[nxt] = 1
                path.append(nxt)
                iters.append(iter(sorted(edges.get(nxt, ()))))
    return None


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
    problems, edges = [], {}
    for src in sources(root):
        text = open(os.path.join(root, src), errors='replace').read()
        layer, unit = layer_of(src)
        module = module_of(src)
        for m in INCLUDE.finditer(text):
            inc = m.group(1)
            line = text.count('\n', 0, m.start()) + 1
            if not os.path.exists(os.path.join(root, inc)):
                problems.append('%s:%d: #include "%s": no such file from the repository root' % (src, line, inc))
                continue
            dst_module = module_of(inc)
            if dst_module != module:
                edges.setdefault(module, set()).add(dst_module)
            if layer is None:
                continue
            ok, why = allowed(layer, unit, inc)
            if not ok:
                problems.append('%s:%d: #include "%s": %s may not use %s' % (src, line, inc, unit, why))
    cycle = find_cycle(edges)
    if cycle:
        problems.append('include cycle: ' + ' -> '.join(cycle))
    for p in problems:
        print(p)
    print('check_layers: %d files, %d problems' % (len(sources(root)), len(problems)))
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
