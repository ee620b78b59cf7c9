# Reference-scene description: reads and checks the scene JSON (parts, sky, sun, camera, scanner, rig)
# and turns its parts into triangles; no Blender here, so that the checks run in CI (test_refscene.py).
# SPDX-License-Identifier: BSD-3-Clause
"""Every error is a SceneError whose message names the file, the key, the value and what was
expected. See tools/refscene/README.md for the keys."""
import json
import math
import os

import geom
import pattern
import rigsim


class SceneError(Exception):
    """A bad scene description or command line (exit code 1)."""


def _isnum(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _vec(obj, key, n, where, path):
    v = obj.get(key)
    if not isinstance(v, list) or len(v) != n or not all(_isnum(x) for x in v):
        raise SceneError("%s: %s.%s = %s: expected a list of %d finite numbers"
                         % (path, where, key, json.dumps(v), n))
    return [float(x) for x in v]


def _ints(obj, key, n, where, path):
    v = _vec(obj, key, n, where, path)
    if not all(x.is_integer() for x in v):
        raise SceneError("%s: %s.%s = %s: expected %d integers" % (path, where, key, json.dumps(obj[key]), n))
    return [int(x) for x in v]


def _num(obj, key, where, path, default=None, lo=None, integer=False):
    v = obj.get(key, default)
    ok = _isnum(v)
    if ok and integer:
        ok = float(v).is_integer()
    if ok and lo is not None:
        ok = v >= lo
    if not ok:
        raise SceneError("%s: %s.%s = %s: expected %s%s" % (
            path, where, key, json.dumps(v), "an integer" if integer else "a number",
            "" if lo is None else " >= %g" % lo))
    return int(v) if integer else float(v)


def _points(obj, key, where, path, value=None):
    v = obj.get(key) if value is None else value
    if (not isinstance(v, list) or len(v) < 3
            or not all(isinstance(p, list) and len(p) == 2 and all(_isnum(x) for x in p) for p in v)):
        raise SceneError("%s: %s.%s = %s: expected a list of at least 3 [u, v] points (metres)"
                         % (path, where, key, _short(v)))
    return [(float(p[0]), float(p[1])) for p in v]


def _short(v):
    s = json.dumps(v)
    return s if len(s) <= 80 else s[:77] + "..."


def resolve_path(spec, json_path, blender_worlds=()):
    """blender-data:NAME (Debian's blender-data skies), shared:PATH (the shared folder beside the
    repository, env RHOSCAN_SHARED) or a path relative to the JSON file."""
    if spec.startswith("blender-data:"):
        name = spec[len("blender-data:"):]
        roots = [os.environ.get("RS_BLENDER_WORLDS", "")] + list(blender_worlds) + \
                ["/usr/share/blender/datafiles/studiolights/world"]
        for root in roots:
            if root and os.path.isfile(os.path.join(root, name)):
                return os.path.join(root, name)
        return os.path.join(roots[-1], name)
    if spec.startswith("shared:"):
        repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        root = os.environ.get("RHOSCAN_SHARED", os.path.join(os.path.dirname(repo), "shared"))
        return os.path.join(root, spec[len("shared:"):])
    return os.path.join(os.path.dirname(os.path.abspath(json_path)), spec)


def _albedo(p, where, path):
    alb = _vec(p, "albedo", 3, where, path)
    if not all(0.0 <= a <= 1.0 for a in alb):
        raise SceneError("%s: %s.albedo = %s: expected values in 0..1" % (path, where, alb))
    return alb


PART_KINDS = (("min", "box"), ("outline", "extrusion"), ("mesh", "mesh"))


def check_part(p, i, path, blender_worlds=()):
    """Checks parts[i] and returns (kind, solid, dropped): kind box, extrusion or mesh; solid None
    for a box (Blender builds it, as for the shared reference scenes), else (verts, tris);
    dropped the number of degenerate faces left out of a mesh file."""
    where = "parts[%d]" % i
    if not isinstance(p, dict):
        raise SceneError("%s: %s: expected an object with albedo and one of min/max, outline, mesh" % (path, where))
    kinds = [k for key, k in PART_KINDS if key in p]
    if len(kinds) != 1:
        raise SceneError("%s: %s: has %s: expected exactly one of \"min\" (a box), \"outline\" (an "
                         "extruded polygon), \"mesh\" (a PLY or OBJ file)"
                         % (path, where, " and ".join(kinds) if kinds else "none of them"))
    if "pattern" in p:
        if "albedo" in p:
            raise SceneError("%s: %s: has both albedo and pattern: expected one (a textured part's albedo is "
                             "its pattern's mean, filled in)" % (path, where))
        try:
            pat = pattern.check(p["pattern"], where + ".pattern", geom.PLANES)
        except pattern.PatternError as e:
            raise SceneError("%s: %s" % (path, e))
        p["albedo"] = pattern.mean_albedo(pat)
    _albedo(p, where, path)
    if kinds[0] == "box":
        lo, hi = _vec(p, "min", 3, where, path), _vec(p, "max", 3, where, path)
        if not all(a < b for a, b in zip(lo, hi)):
            raise SceneError("%s: %s: min %s, max %s: expected min < max on every axis" % (path, where, lo, hi))
        return "box", None, 0
    if kinds[0] == "extrusion":
        return "extrusion", _extrusion(p, where, path), 0
    verts, tris, dropped = _mesh(p, where, path, blender_worlds)
    return "mesh", (verts, tris), dropped


def _extrusion(p, where, path):
    outline = _points(p, "outline", where, path)
    holes_v = p.get("holes", [])
    if not isinstance(holes_v, list):
        raise SceneError("%s: %s.holes = %s: expected a list of point lists" % (path, where, _short(holes_v)))
    holes = [_points(p, "holes[%d]" % k, where, path, h) for k, h in enumerate(holes_v)]
    plane = p.get("plane", "xz")
    origin = _vec(p, "origin", 3, where, path) if "origin" in p else [0.0, 0.0, 0.0]
    if isinstance(plane, str):
        if plane not in geom.PLANES:
            raise SceneError("%s: %s.plane = \"%s\": expected one of %s or {\"u\": [x,y,z], \"v\": [x,y,z]}"
                             % (path, where, plane, ", ".join(sorted(geom.PLANES))))
        u, v = geom.PLANES[plane]
    elif isinstance(plane, dict):
        u, v = _vec(plane, "u", 3, where + ".plane", path), _vec(plane, "v", 3, where + ".plane", path)
        nu, nv = math.sqrt(sum(x * x for x in u)), math.sqrt(sum(x * x for x in v))
        if nu == 0 or nv == 0 or abs(sum(a * b for a, b in zip(u, v))) > 1e-6 * nu * nv:
            raise SceneError("%s: %s.plane: u %s, v %s: expected two perpendicular, non-zero axes"
                             % (path, where, u, v))
    else:
        raise SceneError("%s: %s.plane = %s: expected a plane name or {\"u\": [x,y,z], \"v\": [x,y,z]}"
                         % (path, where, _short(plane)))
    depth = _num(p, "depth", where, path)
    if depth == 0:
        raise SceneError("%s: %s.depth = 0: expected a thickness in metres, != 0 (negative: along -normal)"
                         % (path, where))
    try:
        verts, tris, _ = geom.extrude(outline, holes, origin, u, v, depth)
    except geom.GeomError as e:
        raise SceneError("%s: %s: %s" % (path, where, e))
    return verts, tris


def _mesh(p, where, path, blender_worlds):
    spec = p["mesh"]
    if not isinstance(spec, str):
        raise SceneError("%s: %s.mesh = %s: expected a path to a PLY or OBJ file" % (path, where, _short(spec)))
    file = resolve_path(spec, path, blender_worlds)
    ext = os.path.splitext(file)[1].lower()
    if ext not in (".ply", ".obj"):
        raise SceneError("%s: %s.mesh = \"%s\": expected a .ply or .obj file" % (path, where, spec))
    if not os.path.isfile(file):
        raise SceneError("%s: %s.mesh = \"%s\": no such file (%s)" % (path, where, spec, file))
    t = _vec(p, "translation", 3, where, path) if "translation" in p else [0.0, 0.0, 0.0]
    rz = math.radians(_num(p, "rotation_z_deg", where, path, 0.0))
    sc = p.get("scale", 1.0)
    if _isnum(sc):
        sc = [float(sc)] * 3
    else:
        sc = _vec(p, "scale", 3, where, path)
    if not all(s != 0 for s in sc):
        raise SceneError("%s: %s.scale = %s: expected a number or 3 numbers, none 0" % (path, where, json.dumps(sc)))
    try:
        verts, polys = (geom.read_ply if ext == ".ply" else geom.read_obj)(file)
        tris, dropped = geom.mesh_triangles(verts, polys)
    except (geom.GeomError, ValueError, IndexError, UnicodeDecodeError, __import__("struct").error) as e:
        raise SceneError("%s: %s.mesh = \"%s\": %s: %s" % (path, where, spec, file, e))
    if not tris:
        raise SceneError("%s: %s.mesh = \"%s\": no triangles in %s" % (path, where, spec, file))
    c, s = math.cos(rz), math.sin(rz)
    out = []
    for (x, y, z) in verts:
        x, y, z = x * sc[0], y * sc[1], z * sc[2]
        out.append((t[0] + c * x - s * y, t[1] + s * x + c * y, t[2] + z))
    if sc[0] * sc[1] * sc[2] < 0:          # a mirror turns the winding inside out
        tris = [(a, c_, b) for (a, b, c_) in tris]
    return out, tris, dropped


def load_scene(path, blender_worlds=()):
    """Reads and checks the scene description; returns a dict with defaults filled in and the
    triangles of every extrusion and mesh part in "solids" (None for boxes)."""
    try:
        with open(path, encoding="utf-8") as f:
            sc = json.load(f)
    except OSError as e:
        raise SceneError("%s: cannot read: %s" % (path, e.strerror))
    except ValueError as e:
        raise SceneError("%s: not valid JSON: %s" % (path, e))
    if not isinstance(sc, dict):
        raise SceneError("%s: expected a JSON object at the top level" % path)
    for key in ("parts", "env", "camera", "scanner"):
        if key not in sc:
            raise SceneError("%s: missing key \"%s\"" % (path, key))
    parts = sc["parts"]
    if not isinstance(parts, list) or not parts:
        raise SceneError("%s: parts: expected a non-empty list of parts" % path)
    kinds, solids, dropped = [], [], []
    for i, p in enumerate(parts):
        k, s, d = check_part(p, i, path, blender_worlds)
        kinds.append(k)
        solids.append(s)
        dropped.append(d)
    patterns = [pattern.check(p["pattern"], "", geom.PLANES) if isinstance(p, dict) and "pattern" in p else None
                for p in parts]
    env = sc["env"]
    if not isinstance(env, dict) or not isinstance(env.get("file"), str):
        raise SceneError("%s: env: expected an object with a \"file\" string" % path)
    env_file = resolve_path(env["file"], path, blender_worlds)
    if not os.path.isfile(env_file):
        raise SceneError("%s: env.file = \"%s\": no such file (%s)" % (path, env["file"], env_file))
    cam, scn = sc["camera"], sc["scanner"]
    if not isinstance(cam, dict) or not isinstance(scn, dict):
        raise SceneError("%s: camera and scanner: expected objects" % path)
    out = {
        "parts": parts, "kinds": kinds, "solids": solids, "dropped_faces": dropped, "patterns": patterns,
        "env": env,
        "env_path": env_file,
        "env_strength": _num(env, "strength", "env", path, 1.0, lo=0.0),
        "env_rot_deg": _num(env, "rotation_z_deg", "env", path, 0.0),
        "cam_pos": _vec(cam, "position", 3, "camera", path),
        "cam_yaw_deg": _num(cam, "yaw_deg", "camera", path, 0.0),
        "scan_pos": _vec(scn, "position", 3, "scanner", path),
        "scan_grid": _ints(scn, "grid", 2, "scanner", path),
        "scan_el_deg": _vec(scn, "elevation_deg", 2, "scanner", path),
        "scan_noise_m": _num(scn, "range_noise_m", "scanner", path, 0.003, lo=0.0),
        "samples": _num(sc, "samples", "scene", path, 256, lo=1, integer=True),
        "env_samples": _num(sc, "env_samples", "scene", path, 256, lo=1, integer=True),
        "pano_size": _ints(sc, "pano_size", 2, "scene", path) if "pano_size" in sc else [1024, 512],
        "seed": _num(sc, "seed", "scene", path, 0, lo=0, integer=True),
        "exr_half": sc.get("exr_half", True),
        "sun": sc.get("sun"),
        "rig": None,
    }
    cols, rows = out["scan_grid"]
    if cols < 1 or rows < 2 or cols * rows > 50_000_000:
        raise SceneError("%s: scanner.grid = %s: expected [cols >= 1, rows >= 2], at most 5e7 points"
                         % (path, out["scan_grid"]))
    el0, el1 = out["scan_el_deg"]
    if not -90.0 <= el0 < el1 <= 90.0:
        raise SceneError("%s: scanner.elevation_deg = %s: expected -90 <= low < high <= 90"
                         % (path, out["scan_el_deg"]))
    w, h = out["pano_size"]
    if w != 2 * h or h < 2 or w > 65536:
        raise SceneError("%s: pano_size = %s: expected [2 H, H] with H >= 2" % (path, out["pano_size"]))
    if not isinstance(out["exr_half"], bool):
        raise SceneError("%s: exr_half = %s: expected true or false" % (path, json.dumps(out["exr_half"])))
    if out["sun"] is not None:
        sun = out["sun"]
        if not isinstance(sun, dict):
            raise SceneError("%s: sun: expected an object or null" % path)
        out["sun_dir_deg"] = _vec(sun, "direction_deg", 2, "sun", path)
        out["sun_strength"] = _num(sun, "strength", "sun", path, lo=0.0)
        out["sun_angle_deg"] = _num(sun, "angle_deg", "sun", path, 0.53, lo=0.0)
        out["sun_color"] = _vec(sun, "color", 3, "sun", path) if "color" in sun else [1.0, 1.0, 1.0]
    if sc.get("rig") is not None:
        out["rig"] = load_rig(sc["rig"], path, out["samples"])
    return out


def load_rig(rig, path, default_samples):
    """The rig object: pose, samples and cameras (listed, or the ladybug5 preset)."""
    if not isinstance(rig, dict):
        raise SceneError("%s: rig: expected an object or null" % path)
    out = {
        "position": _vec(rig, "position", 3, "rig", path),
        "yaw_deg": _num(rig, "yaw_deg", "rig", path, 0.0),
        "samples": _num(rig, "samples", "rig", path, default_samples, lo=1, integer=True),
        "oversample": _num(rig, "oversample", "rig", path, 1.0, lo=0.25),
    }
    if ("cameras" in rig) == ("ladybug5" in rig):
        raise SceneError("%s: rig: expected exactly one of \"cameras\" (a list) and \"ladybug5\" (the preset)" % path)
    if "ladybug5" in rig:
        lb = rig["ladybug5"]
        if not isinstance(lb, dict):
            raise SceneError("%s: rig.ladybug5 = %s: expected an object (may be empty: {})" % (path, _short(lb)))
        d = rigsim.LADYBUG5
        size = _ints(lb, "image_size", 2, "rig.ladybug5", path) if "image_size" in lb else d["image_size"]
        focal = _num(lb, "focal_px", "rig.ladybug5", path, d["focal_px"], lo=1e-3)
        dist = _vec(lb, "dist", 5, "rig.ladybug5", path) if "dist" in lb else d["dist"]
        radius = _num(lb, "radius_m", "rig.ladybug5", path, d["radius_m"], lo=0.0)
        if min(size) < 2:
            raise SceneError("%s: rig.ladybug5.image_size = %s: expected two sizes >= 2" % (path, size))
        out["cameras"] = rigsim.ladybug5(size, focal, dist, radius)
        out["preset"] = {"ladybug5": {"image_size": size, "focal_px": focal, "dist": dist, "radius_m": radius}}
    else:
        cams = rig["cameras"]
        if not isinstance(cams, list) or not cams:
            raise SceneError("%s: rig.cameras = %s: expected a non-empty list" % (path, _short(cams)))
        out["cameras"] = [_rig_camera(c, k, path) for k, c in enumerate(cams)]
        out["preset"] = None
    names = [c["name"] for c in out["cameras"]]
    if len(set(names)) != len(names):
        raise SceneError("%s: rig.cameras: names %s: expected distinct names" % (path, names))
    for k, c in enumerate(out["cameras"]):
        field = rigsim.usable_field(c["dist"])
        if field <= 0.05:
            raise SceneError("%s: rig camera %d (%s): dist = %s: the radial model folds back at once: expected a "
                             "lens that is one-to-one near its axis" % (path, k, c["name"], c["dist"]))
    return out


def _rig_camera(c, k, path):
    where = "rig.cameras[%d]" % k
    if not isinstance(c, dict):
        raise SceneError("%s: %s: expected an object" % (path, where))
    name = c.get("name", "cam%d" % k)
    if not isinstance(name, str) or not name or len(name) > 60 or any(ch in name for ch in " :#\"'\n"):
        raise SceneError("%s: %s.name = %s: expected a short name without spaces, quotes, ':' or '#'"
                         % (path, where, json.dumps(name)))
    size = _ints(c, "image_size", 2, where, path)
    if min(size) < 2 or max(size) > 16384:
        raise SceneError("%s: %s.image_size = %s: expected [width, height], 2 to 16384" % (path, where, size))
    fx, fy, cx, cy = _vec(c, "K", 4, where, path)
    if not (fx > 0 and fy > 0):
        raise SceneError("%s: %s.K = %s: expected [fx, fy, cx, cy] with fx, fy > 0 (pixels)"
                         % (path, where, c["K"]))
    dist = _vec(c, "dist", 5, where, path) if "dist" in c else [0.0] * 5
    t = _vec(c, "t_rig_cam", 3, where, path) if "t_rig_cam" in c else [0.0, 0.0, 0.0]
    if ("R_rig_cam" in c) == ("look_deg" in c):
        raise SceneError("%s: %s: expected exactly one of R_rig_cam (9 numbers, row-major, camera -> rig) and "
                         "look_deg ([azimuth, elevation, roll] of the optical axis in the rig frame)" % (path, where))
    if "R_rig_cam" in c:
        r = _vec(c, "R_rig_cam", 9, where, path)
        if not rigsim.is_rotation(r):
            raise SceneError("%s: %s.R_rig_cam = %s: expected a rotation (orthonormal to 1e-6, det +1)"
                             % (path, where, r))
    else:
        r = rigsim.look_rotation(*_vec(c, "look_deg", 3, where, path))
    return {"name": name, "size": size, "K": [fx, fy, cx, cy], "dist": dist, "R": r, "t": t}
