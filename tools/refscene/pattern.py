# Procedural albedo patterns of textured parts (bricks with mortar, square tiles with joints, stripes):
# one definition, an expression tree, that numpy evaluates here and render.py turns into Cycles math nodes,
# so the true albedo at any surface point is known exactly without Blender.
# SPDX-License-Identifier: BSD-3-Clause
"""A part's "pattern" (see tools/refscene/README.md, "Textured parts"):

    {"type": "bricks", "plane": "xz", "origin": [0, 0, 0], "size": [0.3, 0.1], "mortar_m": 0.02,
     "bond": 0.5, "albedos": [[0.6, 0.3, 0.2], [0.45, 0.25, 0.18]], "mortar": [0.75, 0.72, 0.66]}

Coordinates u, v (metres) of a point P: u = (P - origin) . U, v = (P - origin) . V with U, V the
plane's axes (unit). A pattern gives every point an index k into its palette: albedos[0..n-1],
then the mortar (k = n). The part's albedo key is ignored for shading; truth.ply and the scan's
intensity carry the pattern's mean over one period.
"""
import math

import numpy as np


class PatternError(ValueError):
    """A bad pattern description; the message names the key and what was expected."""


# ---------------------------------------------------------------- expression tree
# A node is a float constant, a variable name ("x", "y", "z": the world point) or a tuple
# (op, a, b). Ops are the ones Blender's Math node has, with its semantics.

OPS = {
    "ADD": lambda a, b: a + b,
    "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "DIVIDE": lambda a, b: a / b,
    "FLOOR": lambda a, b: np.floor(a),
    "LESS_THAN": lambda a, b: (a < b).astype(np.float64),
    "MAXIMUM": lambda a, b: np.maximum(a, b),
    "COMPARE": lambda a, b: (np.abs(a - b) <= 0.5).astype(np.float64),   # epsilon 0.5: integers equal
}


def _op(name, a, b=0.0):
    return (name, a, b)


def add(a, b):
    return _op("ADD", a, b)


def sub(a, b):
    return _op("SUBTRACT", a, b)


def mul(a, b):
    return _op("MULTIPLY", a, b)


def div(a, b):
    return _op("DIVIDE", a, b)


def floor(a):
    return _op("FLOOR", a)


def mod(a, n):
    """a - n floor(a / n): in 0..n-1 for integer a of either sign (Blender 3.4's Modulo is fmod)."""
    return sub(a, mul(n, floor(div(a, n))))


def evaluate(node, env):
    """Evaluates a node with numpy; env maps "x", "y", "z" to arrays."""
    if isinstance(node, (int, float)):
        return float(node)
    if isinstance(node, str):
        return env[node]
    name, a, b = node
    return OPS[name](evaluate(a, env), evaluate(b, env))


# ---------------------------------------------------------------- patterns

TYPES = ("bricks", "tiles", "stripes")


def _check_rgb(v, where):
    if (not isinstance(v, list) or len(v) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0.0 <= x <= 1.0 for x in v)):
        raise PatternError("%s = %s: expected [r, g, b] in 0..1" % (where, v))
    return [float(x) for x in v]


def check(pat, where, planes):
    """Checks a pattern object; returns it normalised: type, u, v (unit axes), origin, size,
    mortar_m, bond, palette (n albedos then the mortar for bricks and tiles)."""
    if not isinstance(pat, dict):
        raise PatternError("%s: expected an object with type, plane, size, albedos" % where)
    typ = pat.get("type")
    if typ not in TYPES:
        raise PatternError("%s.type = %s: expected one of %s" % (where, pat.get("type"), ", ".join(TYPES)))
    plane = pat.get("plane", "xz")
    if isinstance(plane, str) and plane in planes:
        u, v = planes[plane]
    elif isinstance(plane, dict) and all(k in plane for k in ("u", "v")):
        u, v = plane["u"], plane["v"]
    else:
        raise PatternError("%s.plane = %s: expected one of %s or {\"u\": [x,y,z], \"v\": [x,y,z]}"
                           % (where, plane, ", ".join(sorted(planes))))
    u, v = _unit(u, where + ".plane.u"), _unit(v, where + ".plane.v")
    if abs(sum(a * b for a, b in zip(u, v))) > 1e-6:
        raise PatternError("%s.plane: u %s, v %s: expected perpendicular axes" % (where, u, v))
    origin = pat.get("origin", [0.0, 0.0, 0.0])
    if not (isinstance(origin, list) and len(origin) == 3 and all(_finite(x) for x in origin)):
        raise PatternError("%s.origin = %s: expected [x, y, z] (metres)" % (where, origin))
    nsize = 1 if typ == "stripes" else 2
    size = pat.get("size")
    if not (isinstance(size, list) and len(size) == nsize and all(_finite(x) and x > 0 for x in size)):
        raise PatternError("%s.size = %s: expected %d positive lengths (metres: %s)"
                           % (where, size, nsize, "stripe width" if nsize == 1 else "[along u, along v]"))
    albedos = pat.get("albedos")
    if not isinstance(albedos, list) or len(albedos) < 2:
        raise PatternError("%s.albedos = %s: expected a list of two or more [r, g, b]" % (where, albedos))
    palette = [_check_rgb(a, "%s.albedos[%d]" % (where, k)) for k, a in enumerate(albedos)]
    out = {"type": typ, "u": u, "v": v, "origin": [float(x) for x in origin], "size": [float(x) for x in size],
           "n": len(palette), "mortar_m": 0.0, "bond": 0.0}
    if typ != "stripes":
        m = pat.get("mortar_m")
        if not (_finite(m) and 0 < m < min(size)):
            raise PatternError("%s.mortar_m = %s: expected a joint width in metres, > 0 and < %g"
                               % (where, m, min(size)))
        out["mortar_m"] = float(m)
        palette.append(_check_rgb(pat.get("mortar"), where + ".mortar"))
        if typ == "bricks":
            bond = pat.get("bond", 0.5)
            if not (_finite(bond) and 0 <= bond < 1):
                raise PatternError("%s.bond = %s: expected the row offset as a fraction of a brick, 0 <= bond < 1"
                                   % (where, bond))
            out["bond"] = float(bond)
    out["palette"] = palette
    return out


def _finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _unit(a, where):
    if not (isinstance(a, (list, tuple)) and len(a) == 3 and all(_finite(x) for x in a)):
        raise PatternError("%s = %s: expected [x, y, z]" % (where, a))
    n = math.sqrt(sum(x * x for x in a))
    if n == 0:
        raise PatternError("%s = %s: expected a non-zero axis" % (where, a))
    return [float(x) / n for x in a]


def _coord(axis, origin):
    """(P - origin) . axis as a tree of x, y, z."""
    terms = [mul(sub(c, o), a) for c, o, a in zip("xyz", origin, axis) if a != 0.0]
    out = terms[0] if terms else 0.0
    for t in terms[1:]:
        out = add(out, t)
    return out


def _colour_index(col, row, n):
    """Which of the n albedos a brick or tile (integer col, row) takes: irregular, periodic in
    5 n bricks along both axes, all integer arithmetic (exact in Cycles' float32)."""
    return mod(add(add(mul(col, 7.0), mul(row, 3.0)), mod(mul(col, row), 5.0)), float(n))


def index_tree(p):
    """The palette index of a normalised pattern as an expression of x, y, z."""
    u, v = _coord(p["u"], p["origin"]), _coord(p["v"], p["origin"])
    n = float(p["n"])
    if p["type"] == "stripes":
        return mod(floor(div(u, p["size"][0])), n)
    w, h = p["size"]
    m = p["mortar_m"]
    row = floor(div(v, h))
    if p["type"] == "bricks" and p["bond"] != 0.0:
        u = add(u, mul(mod(row, 2.0), p["bond"] * w))
    col = floor(div(u, w))
    fu, fv = sub(u, mul(col, w)), sub(v, mul(row, h))
    joint = _op("MAXIMUM", _op("LESS_THAN", fu, m), _op("LESS_THAN", fv, m))
    k = _colour_index(col, row, n)
    return add(k, mul(joint, sub(n, k)))      # n (the mortar) in a joint, else k


def albedo_at(p, points):
    """Linear RGB albedo (N x 3) of a normalised pattern at world points (N x 3)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    k = evaluate(index_tree(p), {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]})
    k = np.broadcast_to(np.asarray(k), (len(pts),)).astype(np.int64)
    return np.asarray(p["palette"])[k]


def mean_albedo(p):
    """The area mean over one period of the pattern (what truth.ply carries per face)."""
    n = p["n"]
    pal = np.asarray(p["palette"])
    if p["type"] == "stripes":
        return [float(x) for x in pal.mean(axis=0)]
    col, row = np.meshgrid(np.arange(5 * n, dtype=np.float64), np.arange(5 * n, dtype=np.float64))
    k = evaluate(_colour_index("c", "r", n), {"c": col, "r": row}).astype(np.int64)
    w, h = p["size"]
    m = p["mortar_m"]
    face = (w - m) * (h - m) / (w * h)
    body = pal[k.ravel()].mean(axis=0)
    return [float(x) for x in face * body + (1.0 - face) * pal[n]]
