"""Minimal PLY reader for the tests (ascii and binary little/big endian) -> dict of numpy arrays.
Face lists of equal length come back as a 2D array under their own name."""
import numpy as np

_T = {'char': 'i1', 'int8': 'i1', 'uchar': 'u1', 'uint8': 'u1', 'short': 'i2', 'int16': 'i2',
      'ushort': 'u2', 'uint16': 'u2', 'int': 'i4', 'int32': 'i4', 'uint': 'u4', 'uint32': 'u4',
      'float': 'f4', 'float32': 'f4', 'double': 'f8', 'float64': 'f8'}


def read_ply(path):
    data = open(path, 'rb').read()
    end = data.index(b'end_header') + len(b'end_header')
    end = data.index(b'\n', end) + 1
    fmt, elements = None, []
    for line in data[:end].decode('ascii', 'replace').splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == 'format':
            fmt = w[1]
        elif w[0] == 'element':
            elements.append((w[1], int(w[2]), []))
        elif w[0] == 'property':
            elements[-1][2].append((w[4], _T[w[2]], _T[w[3]]) if w[1] == 'list' else (w[2], _T[w[1]]))
    body, out = data[end:], {}
    if fmt == 'ascii':
        toks, pos = body.split(), 0
        for name, n, props in elements:
            cols = {p[0]: [] for p in props}
            for _ in range(n):
                for p in props:
                    if len(p) == 3:
                        k = int(toks[pos]); cols[p[0]].append([int(t) for t in toks[pos + 1:pos + 1 + k]]); pos += k + 1
                    else:
                        cols[p[0]].append(float(toks[pos])); pos += 1
            out[name] = {k: np.array(v) for k, v in cols.items()}
        return out
    e = '<' if fmt == 'binary_little_endian' else '>'
    pos = 0
    for name, n, props in elements:
        fields = []                              # lists: fixed length 3 (triangles)
        for p in props:
            if len(p) == 3:
                fields += [(p[0] + '_n', e + p[1]), (p[0], e + p[2], (3,))]
            else:
                fields.append((p[0], e + p[1]))
        dt = np.dtype(fields)
        arr = np.frombuffer(body, dt, count=n, offset=pos)
        pos += n * dt.itemsize
        out[name] = {p[0]: arr[p[0]] for p in props}
    return out
