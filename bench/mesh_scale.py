#!/usr/bin/python3
"""mesh_scale: inputs for the scan-to-mesh benchmark (bench/mesh_scale.sh): a simulated scan of a
box scene (a reference scene.json: parts as axis-aligned boxes, scanner position, elevation
range) cast analytically with 3 mm range noise, as an organized PTX of COLS x ROWS points and
as an unorganized, shuffled binary PLY of N valid points (world frame, scanner position printed).

usage: bench/mesh_scale.py SCENE.json OUTDIR [--ptx COLS ROWS] [--ply N]"""
import json, os, sys
import numpy as np

NOISE = 0.003


def cast(boxes, o, az, el, rng):
    """Scanner-frame hit points (nan where a ray escapes) of rays az x el (flattened, same shape)."""
    d = np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)], -1)
    with np.errstate(divide='ignore', invalid='ignore'):
        inv = 1.0 / d
        best = np.full(len(d), np.inf)
        for lo, hi in boxes:
            t1, t2 = (lo - o) * inv, (hi - o) * inv
            tn = np.nanmax(np.minimum(t1, t2), 1)
            tf = np.nanmin(np.maximum(t1, t2), 1)
            hit = (tf >= tn) & (tf > 0) & (tn > 1e-6)
            best = np.where(hit & (tn < best), tn, best)
    ok = np.isfinite(best)
    t = np.where(ok, best + rng.normal(0, NOISE, len(best)), 0.0)
    p = d * t[:, None]
    p[~ok] = np.nan
    return p


def main():
    args = sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    scene = json.load(open(args[0]))
    out = args[1]
    os.makedirs(out, exist_ok=True)
    boxes = [(np.array(p['min'], float), np.array(p['max'], float)) for p in scene['parts']]
    sc = scene['scanner']
    o = np.array(sc['position'], float)
    el0, el1 = [np.radians(x) for x in sc['elevation_deg']]
    rng = np.random.default_rng(1)
    if '--ptx' in args:
        i = args.index('--ptx')
        cols, rows = int(args[i + 1]), int(args[i + 2])
        path = os.path.join(out, 'scan_%dx%d.ptx' % (cols, rows))
        el = el0 + (el1 - el0) * np.arange(rows) / (rows - 1)
        with open(path, 'w') as f:
            f.write('%d\n%d\n%f %f %f\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n%f %f %f 1\n'
                    % (cols, rows, *o, *o))
            step = max(1, 200000 // rows)
            for c0 in range(0, cols, step):   # PTX: column by column, rows bottom to top
                c = np.arange(c0, min(cols, c0 + step))
                az = np.repeat(2 * np.pi * c / cols, rows)
                p = cast(boxes, o, az, np.tile(el, len(c)), rng)
                p = np.where(np.isnan(p), 0.0, p)
                inten = np.where(p[:, 0] == 0, 0.0, 0.5)
                f.write(('%.4f %.4f %.4f %.1f\n' * len(p)) % tuple(np.column_stack([p, inten]).ravel()))
        print(path, cols * rows, 'points')
    if '--ply' in args:
        n = int(args[args.index('--ply') + 1])
        pts, have, k = [], 0, 0
        while have < n:   # random directions over the scanner's field until n returns
            m = 2 * n
            az = rng.uniform(0, 2 * np.pi, m)
            el = np.arcsin(rng.uniform(np.sin(el0), np.sin(el1), m))
            p = cast(boxes, o, az, el, rng)
            p = p[~np.isnan(p[:, 0])] + o
            pts.append(p)
            have += len(p)
        xyz = np.concatenate(pts)[:n]
        path = os.path.join(out, 'cloud_%d.ply' % n)
        hdr = ('ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty double x\nproperty double y\n'
               'property double z\nend_header\n' % n)
        with open(path, 'wb') as f:
            f.write(hdr.encode() + xyz.astype('<f8').tobytes())
        print(path, n, 'points, scanner_position = %g %g %g' % tuple(o))


if __name__ == '__main__':
    main()
