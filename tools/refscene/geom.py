# Geometry of the reference scenes that needs no Blender: polygons with holes triangulated by ear
# clipping, extruded into closed outward-oriented solids, PLY/OBJ mesh readers, a watertightness check.
# SPDX-License-Identifier: BSD-3-Clause
"""Pure Python (no numpy, no Blender), so that CI tests it.

A solid is (verts, tris): verts a list of (x, y, z) floats, tris a list of (i, j, k) vertex
indices wound counter-clockwise seen from outside (docs/DESIGN.md, section Frames).
"""
import math
import struct


class GeomError(Exception):
    """A polygon or mesh file that cannot be turned into triangles; the caller adds the key."""


# ---------------------------------------------------------------- 2D polygons

def signed_area(loop):
    """The signed area (counter-clockwise positive) of a closed 2D loop."""
    s = 0.0
    for i in range(len(loop)):
        x0, y0 = loop[i]
        x1, y1 = loop[(i + 1) % len(loop)]
        s += x0 * y1 - x1 * y0
    return 0.5 * s


def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_cross(p, q, r, s):
    """True when the closed segments pq and rs share a point (touching counts)."""
    d1, d2 = _cross(r, s, p), _cross(r, s, q)
    d3, d4 = _cross(p, q, r), _cross(p, q, s)
    if ((d1 > 0) != (d2 > 0) and d1 != 0 and d2 != 0) and ((d3 > 0) != (d4 > 0) and d3 != 0 and d4 != 0):
        return True

    def on(a, b, c, d):
        return d == 0 and min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])
    return on(r, s, p, d1) or on(r, s, q, d2) or on(p, q, r, d3) or on(p, q, s, d4)


def _pt(p):
    return "(%g, %g)" % (p[0], p[1])


def _point_in_loop(pt, loop):
    """Even-odd test; points on the boundary count as outside for no particular side."""
    x, y = pt
    inside = False
    for i in range(len(loop)):
        x0, y0 = loop[i]
        x1, y1 = loop[(i + 1) % len(loop)]
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def check_polygon(outline, holes):
    """Raises GeomError unless the loops are simple, do not touch each other and every hole lies
    inside the outline. An opening that reaches the outline's edge belongs in the outline."""
    loops = [outline] + list(holes)
    for n, loop in enumerate(loops):
        name = "outline" if n == 0 else "holes[%d]" % (n - 1)
        if len(loop) < 3:
            raise GeomError("%s has %d points: expected at least 3" % (name, len(loop)))
        if abs(signed_area(loop)) <= 1e-12:
            raise GeomError("%s encloses no area" % name)
        for i in range(len(loop)):
            if loop[i] == loop[(i + 1) % len(loop)]:
                raise GeomError("%s: points %d and %d coincide at %s: expected distinct neighbours"
                                % (name, i, (i + 1) % len(loop), _pt(loop[i])))
    edges = []
    for n, loop in enumerate(loops):
        for i in range(len(loop)):
            edges.append((n, i, loop[i], loop[(i + 1) % len(loop)], len(loop)))
    for a in range(len(edges)):
        na, ia, p, q, la = edges[a]
        for b in range(a + 1, len(edges)):
            nb, ib, r, s, lb = edges[b]
            if na == nb and (ib == (ia + 1) % la or ia == (ib + 1) % lb):
                continue          # neighbours in one loop share their common point
            if _segments_cross(p, q, r, s):
                wa = "outline" if na == 0 else "holes[%d]" % (na - 1)
                wb = "outline" if nb == 0 else "holes[%d]" % (nb - 1)
                raise GeomError("%s edge %d %s-%s and %s edge %d %s-%s touch or cross: expected simple loops "
                                "that do not touch (an opening that reaches the edge belongs in the outline)"
                                % (wa, ia, _pt(p), _pt(q), wb, ib, _pt(r), _pt(s)))
    for n, hole in enumerate(holes):
        if not _point_in_loop(hole[0], outline):
            raise GeomError("holes[%d] (first point %s) lies outside the outline" % (n, _pt(hole[0])))
        for m, other in enumerate(holes):
            if m != n and _point_in_loop(hole[0], other):
                raise GeomError("holes[%d] lies inside holes[%d]: expected separate holes" % (n, m))


def _bridge_holes(pts, outer, holes):
    """Joins each hole to the outer loop by a pair of coincident edges (Eberly, "Triangulation by
    ear clipping", 2002), holes with the largest x first. outer is counter-clockwise, holes
    clockwise; all are lists of indices into pts. Returns one loop of indices (bridge points
    repeat)."""
    loop = list(outer)
    for hole in sorted(holes, key=lambda h: -max(pts[i][0] for i in h)):
        m_pos = max(range(len(hole)), key=lambda k: (pts[hole[k]][0], -pts[hole[k]][1]))
        mx, my = pts[hole[m_pos]]
        # The nearest point where the ray from M toward +x meets the loop: a vertex or an edge.
        hit, hit_x = None, math.inf
        for k in range(len(loop)):
            a, b = pts[loop[k]], pts[loop[(k + 1) % len(loop)]]
            if (a[1] - my) * (b[1] - my) > 0:
                continue
            if a[1] == my or b[1] == my:
                for v, kk in ((a, k), (b, (k + 1) % len(loop))):
                    if v[1] == my and mx < v[0] < hit_x:
                        hit_x, hit = v[0], ("v", kk)
                continue
            x = a[0] + (my - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            if mx < x < hit_x:
                hit_x, hit = x, ("e", k)
        if hit is None:
            raise GeomError("a hole could not be joined to the outline")
        if hit[0] == "v":
            p_idx = loop[hit[1]]
        else:
            ka, kb = hit[1], (hit[1] + 1) % len(loop)
            p_idx = loop[ka] if pts[loop[ka]][0] > pts[loop[kb]][0] else loop[kb]
            # A reflex vertex inside the triangle M, I, P would make the bridge cross the loop:
            # take the one seen at the smallest angle from the ray instead.
            tri = ((mx, my), (hit_x, my), pts[p_idx])
            best = None
            for kk in range(len(loop)):
                v = pts[loop[kk]]
                if loop[kk] == p_idx or _cross(pts[loop[kk - 1]], v, pts[loop[(kk + 1) % len(loop)]]) > 0:
                    continue
                if _in_triangle(v, *tri) or _in_triangle(v, tri[0], tri[2], tri[1]):
                    key = (abs(v[1] - my) / max(math.hypot(v[0] - mx, v[1] - my), 1e-300), v[0] - mx)
                    if best is None or key < best[0]:
                        best = (key, loop[kk])
            if best is not None:
                p_idx = best[1]
        # A point that bridges already repeats: join at the copy whose corner opens toward M.
        cands = [k for k in range(len(loop)) if loop[k] == p_idx]
        p_pos = cands[0]
        for k in cands:
            if _in_wedge((mx, my), pts[loop[k - 1]], pts[p_idx], pts[loop[(k + 1) % len(loop)]]):
                p_pos = k
                break
        ring = hole[m_pos:] + hole[:m_pos] + [hole[m_pos]]
        loop = loop[:p_pos + 1] + ring + loop[p_pos:]
    return loop


def _in_wedge(p, prev, v, nxt):
    """p inside the interior angle at v of a counter-clockwise loop."""
    if _cross(prev, v, nxt) >= 0:          # convex corner
        return _cross(prev, v, p) > 0 and _cross(v, nxt, p) > 0
    return not (_cross(prev, v, p) <= 0 and _cross(v, nxt, p) <= 0)


def _in_triangle(p, a, b, c):
    """p inside or on the counter-clockwise triangle abc."""
    return _cross(a, b, p) >= 0 and _cross(b, c, p) >= 0 and _cross(c, a, p) >= 0


def triangulate_polygon(outline, holes=()):
    """Triangles (index triples into outline + holes, concatenated) covering the polygon, each
    counter-clockwise in the plane. The outline and holes may be given in either direction."""
    check_polygon(outline, holes)
    pts = [tuple(map(float, p)) for p in outline]
    outer = list(range(len(outline)))
    if signed_area(outline) < 0:
        outer.reverse()
    hole_idx = []
    for h in holes:
        idx = list(range(len(pts), len(pts) + len(h)))
        pts += [tuple(map(float, p)) for p in h]
        if signed_area(h) > 0:
            idx.reverse()
        hole_idx.append(idx)
    loop = _bridge_holes(pts, outer, hole_idx) if hole_idx else outer
    return _ear_clip(pts, loop), pts


def _ear_clip(pts, loop):
    tris = []
    loop = list(loop)
    scale = max(max(abs(c) for c in pts[i]) for i in loop) or 1.0
    eps = 1e-12 * scale * scale
    while len(loop) > 3:
        n = len(loop)
        found = None
        degenerate = None
        for k in range(n):
            ia, ib, ic = loop[k - 1], loop[k], loop[(k + 1) % n]
            a, b, c = pts[ia], pts[ib], pts[ic]
            cr = _cross(a, b, c)
            if cr <= eps:
                if abs(cr) <= eps and degenerate is None and a != c:
                    degenerate = k
                continue
            blocked = False
            for j in loop:
                v = pts[j]
                if v == a or v == b or v == c:
                    continue
                if _in_triangle(v, a, b, c):
                    blocked = True
                    break
            if not blocked:
                found = k
                break
        if found is None:
            if degenerate is None:
                raise GeomError("no ear left to cut: the polygon is not simple")
            # A straight run of points: drop the middle one with a zero-area triangle, which
            # keeps the cap's edges those of the side walls (no T-junctions).
            found = degenerate
        k = found
        tris.append((loop[k - 1], loop[k], loop[(k + 1) % n]))
        del loop[k]
    tris.append(tuple(loop))
    return tris


# ---------------------------------------------------------------- solids

def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _cross3(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


PLANES = {  # name -> (u axis, v axis); the normal is u x v
    "xy": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "yz": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "zx": ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
    "xz": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),    # a wall facing -y, outline in (x, z)
    "yx": ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),
    "zy": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
}


def extrude(outline, holes, origin, u_axis, v_axis, depth):
    """The solid swept by the polygon (outline minus holes, 2D coordinates along u_axis and
    v_axis from origin, metres) along n = u x v by depth (negative: along -n). u and v are
    normalised; they must be perpendicular. Returns (verts, tris, area)."""
    u, v = _unit(u_axis), _unit(v_axis)
    n = _cross3(u, v)
    flat, pts = triangulate_polygon(outline, holes)
    loops, start = [], 0
    for loop in [outline] + list(holes):
        idx = list(range(start, start + len(loop)))
        start += len(loop)
        # Walk every loop with the solid on its left: outline counter-clockwise, holes clockwise.
        if (signed_area(loop) > 0) != (len(loops) == 0):
            idx.reverse()
        loops.append(idx)
    m = len(pts)
    verts = []
    for off in (0.0, depth):
        for (a, b) in pts:
            verts.append(tuple(origin[k] + a * u[k] + b * v[k] + off * n[k] for k in range(3)))
    tris = []
    for (i, j, k) in flat:
        tris.append((i, k, j))              # the cap at origin faces -n
        tris.append((m + i, m + j, m + k))  # the cap at depth faces +n
    for idx in loops:
        for s in range(len(idx)):
            i, j = idx[s], idx[(s + 1) % len(idx)]
            tris.append((i, j, m + j))
            tris.append((i, m + j, m + i))
    if depth < 0:
        tris = [(a, c, b) for (a, b, c) in tris]
    area = sum(_cross(pts[i], pts[j], pts[k]) for (i, j, k) in flat) * 0.5
    return verts, tris, area


def mesh_check(verts, tris):
    """(closed, consistent, volume): closed when every edge has exactly two triangles, consistent
    when they run it in opposite directions; volume is the signed enclosed volume (positive for
    outward triangles), meaningful only when closed and consistent."""
    directed = {}
    for t in tris:
        for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            directed[e] = directed.get(e, 0) + 1
    closed = all(directed.get((b, a), 0) >= 1 for (a, b) in directed)
    consistent = all(c == 1 for c in directed.values())
    vol = 0.0
    for (i, j, k) in tris:
        a, b, c = verts[i], verts[j], verts[k]
        vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
    return closed and consistent, consistent, vol / 6.0


# ---------------------------------------------------------------- mesh files

PLY_TYPES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
             "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
             "float": "f", "float32": "f", "double": "d", "float64": "d"}


def read_ply(path):
    """(verts, polygons) of an ASCII or binary PLY: vertex x y z and face vertex_indices (or
    vertex_index); other elements and properties are skipped."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise GeomError("not a PLY file (expected 'ply' ... 'end_header')")
    body = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    for line in header:
        w = line.split()
        if not w or w[0] in ("ply", "comment", "obj_info"):
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property" and elements:
            if w[1] == "list":
                elements[-1][2].append((w[4], "list", w[2], w[3]))
            else:
                elements[-1][2].append((w[2], w[1]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise GeomError("PLY format %s: expected ascii or binary" % fmt)
    for _, _, props in elements:
        for p in props:
            for t in p[1:] if p[1] != "list" else p[2:]:
                if t not in PLY_TYPES:
                    raise GeomError("PLY property type %s is not known" % t)
    verts, polys = [], []
    if fmt == "ascii":
        words = data[body:].split()
        pos = 0
        for name, count, props in elements:
            for _ in range(count):
                rec = {}
                for p in props:
                    if p[1] == "list":
                        k = int(words[pos])
                        rec[p[0]] = [int(x) for x in words[pos + 1:pos + 1 + k]]
                        pos += 1 + k
                    else:
                        rec[p[0]] = float(words[pos])
                        pos += 1
                _take(name, rec, verts, polys)
        return verts, polys
    order = "<" if fmt == "binary_little_endian" else ">"
    pos = body
    for name, count, props in elements:
        for _ in range(count):
            rec = {}
            for p in props:
                if p[1] == "list":
                    (k,) = struct.unpack_from(order + PLY_TYPES[p[2]], data, pos)
                    pos += struct.calcsize(PLY_TYPES[p[2]])
                    f = order + "%d%s" % (k, PLY_TYPES[p[3]])
                    rec[p[0]] = list(struct.unpack_from(f, data, pos))
                    pos += struct.calcsize(f)
                else:
                    f = order + PLY_TYPES[p[1]]
                    (rec[p[0]],) = struct.unpack_from(f, data, pos)
                    pos += struct.calcsize(f)
            _take(name, rec, verts, polys)
    return verts, polys


def _take(name, rec, verts, polys):
    if name == "vertex":
        if not all(k in rec for k in "xyz"):
            raise GeomError("PLY vertex element without x, y, z")
        verts.append((float(rec["x"]), float(rec["y"]), float(rec["z"])))
    elif name == "face":
        idx = rec.get("vertex_indices", rec.get("vertex_index"))
        if idx is None:
            raise GeomError("PLY face element without vertex_indices")
        polys.append([int(i) for i in idx])


def read_obj(path):
    """(verts, polygons) of a Wavefront OBJ: v and f lines (v, v/vt, v//vn, v/vt/vn, negative
    indices relative to the end); everything else is skipped."""
    verts, polys = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            w = line.split()
            if not w:
                continue
            try:
                if w[0] == "v":
                    verts.append((float(w[1]), float(w[2]), float(w[3])))
                elif w[0] == "f":
                    poly = []
                    for tok in w[1:]:
                        i = int(tok.split("/")[0])
                        poly.append(i - 1 if i > 0 else len(verts) + i)
                    polys.append(poly)
            except (ValueError, IndexError):
                raise GeomError("line %d: %r: expected 'v x y z' or 'f i j k ...'" % (lineno, line.strip()))
    return verts, polys


def mesh_triangles(verts, polys):
    """Triangles of the polygons (n > 3: projected on the plane of their Newell normal and ear
    clipped); polygons with out-of-range indices raise, degenerate ones are dropped.
    Returns (tris, dropped)."""
    tris, dropped = [], 0
    for n, poly in enumerate(polys):
        if len(poly) < 3 or any(not 0 <= i < len(verts) for i in poly):
            raise GeomError("face %d %s: expected at least 3 indices of the %d vertices" % (n, poly, len(verts)))
        if len(set(poly)) != len(poly):
            dropped += 1
            continue
        if len(poly) == 3:
            tris.append(tuple(poly))
            continue
        nrm = [0.0, 0.0, 0.0]
        for k in range(len(poly)):
            a, b = verts[poly[k]], verts[poly[(k + 1) % len(poly)]]
            nrm[0] += (a[1] - b[1]) * (a[2] + b[2])
            nrm[1] += (a[2] - b[2]) * (a[0] + b[0])
            nrm[2] += (a[0] - b[0]) * (a[1] + b[1])
        ax = max(range(3), key=lambda k: abs(nrm[k]))
        i0, i1 = [(1, 2), (2, 0), (0, 1)][ax]
        flat = [(verts[i][i0], verts[i][i1]) for i in poly]
        if nrm[ax] < 0:
            flat = [(y, x) for (x, y) in flat]     # keep the winding counter-clockwise in 2D
        try:
            sub, _ = triangulate_polygon(flat)
        except GeomError:
            dropped += 1
            continue
        ccw = signed_area(flat) > 0
        for (i, j, k) in sub:
            tris.append((poly[i], poly[j], poly[k]) if ccw else (poly[i], poly[k], poly[j]))
    return tris, dropped
