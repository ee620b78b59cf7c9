# Splits the triangles of a rendered scene's truth.ply so that the closed truth mesh can be given
# to rhoscan as [mesh] input_mesh: truth.ply has 12 triangles per box (metres to tens of metres
# across), and input_mesh is used as it is, so every facet would be a whole box face (cloister_sunset:
# 96 facets, 31.9 % interior error, against 12.3 % on the scan). Each triangle is bisected at its
# longest edge until that edge spans at most --pixels panorama pixels seen from the camera
# (truth.json's camera_position; the pipeline's own [mesh] pixels_per_facet rule), clamped to
# [--min-edge, --max-edge]. The result keeps the part's albedo and index per face and stays closed
# as a surface (no gaps: split points lie on the parent's edges; neighbours split differently meet
# in T-junctions, which light cannot pass).
# SPDX-License-Identifier: BSD-3-Clause
"""usage: fine_truth.py SCENE_DIR OUT.ply [--pixels 6] [--min-edge 0.05] [--max-edge 4]"""
import argparse
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)


def read_truth_ply(path):
    """(verts, faces): faces as (i, j, k, r, g, b, part) from the generator's ascii truth.ply."""
    with open(path, encoding="ascii") as f:
        lines = f.read().split("\n")
    nv = nf = None
    k = 0
    while lines[k] != "end_header":
        w = lines[k].split()
        if w[:2] == ["element", "vertex"]:
            nv = int(w[2])
        if w[:2] == ["element", "face"]:
            nf = int(w[2])
        k += 1
    if nv is None or nf is None:
        raise ValueError("%s: expected vertex and face elements" % path)
    body = lines[k + 1:]
    verts = [tuple(float(x) for x in body[i].split()[:3]) for i in range(nv)]
    faces = []
    for i in range(nf):
        w = body[nv + i].split()
        if w[0] != "3":
            raise ValueError("%s: face %d: expected a triangle" % (path, i))
        faces.append((int(w[1]), int(w[2]), int(w[3]), float(w[4]), float(w[5]), float(w[6]), int(w[7])))
    return verts, faces


def _dist_point_triangle(p, a, b, c):
    """Distance from p to triangle abc (closest point by Ericson's regions)."""
    ab = [b[i] - a[i] for i in range(3)]
    ac = [c[i] - a[i] for i in range(3)]
    ap = [p[i] - a[i] for i in range(3)]
    dot = lambda u, v: u[0] * v[0] + u[1] * v[1] + u[2] * v[2]  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        q = a
    else:
        bp = [p[i] - b[i] for i in range(3)]
        d3, d4 = dot(ab, bp), dot(ac, bp)
        cp = [p[i] - c[i] for i in range(3)]
        d5, d6 = dot(ab, cp), dot(ac, cp)
        vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
        if d3 >= 0 and d4 <= d3:
            q = b
        elif d6 >= 0 and d5 <= d6:
            q = c
        elif vc <= 0 and d1 >= 0 and d3 <= 0:
            t = d1 / (d1 - d3)
            q = [a[i] + t * ab[i] for i in range(3)]
        elif vb <= 0 and d2 >= 0 and d6 <= 0:
            t = d2 / (d2 - d6)
            q = [a[i] + t * ac[i] for i in range(3)]
        elif va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            q = [b[i] + t * (c[i] - b[i]) for i in range(3)]
        else:
            s = va + vb + vc
            v, w = vb / s, vc / s
            q = [a[i] + ab[i] * v + ac[i] * w for i in range(3)]
    return math.sqrt(sum((p[i] - q[i]) ** 2 for i in range(3)))


def split(verts, faces, camera, pixels=6.0, width=1024, min_edge=0.05, max_edge=4.0):
    """Longest-edge bisection until every edge is within the target at the triangle's distance."""
    px = 2.0 * math.pi / width
    out_v, index = [], {}

    def vid(p):
        key = tuple(round(x, 6) for x in p)
        if key not in index:
            index[key] = len(out_v)
            out_v.append(p)
        return index[key]

    out_f = []
    for (i, j, k, r, g, b, part) in faces:
        stack = [(verts[i], verts[j], verts[k])]
        while stack:
            a, bb, c = stack.pop()
            edges = [(math.dist(a, bb), 0), (math.dist(bb, c), 1), (math.dist(c, a), 2)]
            longest, which = max(edges)
            d = _dist_point_triangle(camera, a, bb, c)
            target = min(max_edge, max(min_edge, pixels * px * d))
            if longest <= target:
                out_f.append((vid(a), vid(bb), vid(c), r, g, b, part))
                continue
            t = [a, bb, c]
            p, q, o = t[which], t[(which + 1) % 3], t[(which + 2) % 3]
            m = tuple((p[n] + q[n]) / 2 for n in range(3))
            stack.append((p, m, o))
            stack.append((m, q, o))
    return out_v, out_f


def write_ply(path, verts, faces):
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="ascii") as f:
        f.write("ply\nformat ascii 1.0\ncomment fine_truth.py: truth.ply split for [mesh] input_mesh\n"
                "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
                "element face %d\nproperty list uchar int vertex_indices\nproperty float red\n"
                "property float green\nproperty float blue\nproperty int part\nend_header\n"
                % (len(verts), len(faces)))
        for v in verts:
            f.write("%.6f %.6f %.6f\n" % v)
        for (i, j, k, r, g, b, part) in faces:
            f.write("3 %d %d %d %.6g %.6g %.6g %d\n" % (i, j, k, r, g, b, part))
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--pixels", type=float, default=6.0)
    ap.add_argument("--min-edge", type=float, default=0.05)
    ap.add_argument("--max-edge", type=float, default=4.0)
    a = ap.parse_args()
    try:
        t = json.load(open(os.path.join(a.scene, "truth.json")))
        verts, faces = read_truth_ply(os.path.join(a.scene, "truth.ply"))
    except (OSError, ValueError, KeyError) as e:
        print("fine_truth: %s" % e, file=sys.stderr)
        return 1
    width = t.get("pano_size", [1024, 512])[0] if isinstance(t.get("pano_size"), list) else 1024
    v, f = split(verts, faces, t["camera_position"], a.pixels, width, a.min_edge, a.max_edge)
    try:
        write_ply(a.out, v, f)
    except OSError as e:
        print("fine_truth: %s: %s" % (a.out, e.strerror), file=sys.stderr)
        return 2
    print("fine_truth: %d -> %d triangles, %d vertices" % (len(faces), len(f), len(v)), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
