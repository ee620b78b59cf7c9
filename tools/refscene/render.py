# Reference-scene generator: builds a scene of Lambertian boxes under an HDR sky from a JSON
# description and writes the panorama, its Cycles passes, the truth mesh, poses and a simulated PTX scan.
# SPDX-License-Identifier: MIT
"""Run inside Blender 3.4 (needs numpy, from Debian's python3-numpy):

    blender -b --factory-startup --python tools/refscene/render.py -- SCENE.json OUTDIR \
        [--samples N] [--seed S] [--threads T] [--no-render]

Writes into OUTDIR: pano.exr, env.exr, pano_diffcol.exr, pano_diffdir.exr, pano_diffind.exr,
truth.ply, truth.json, scan.ptx (see tools/refscene/README.md for the schema and conventions).
Exit code 0 on success, 1 on a bad scene description or arguments, 2 when a file cannot be
written, 3 on an internal error.
"""
import json
import math
import os
import sys
import time

import bmesh
import bpy
import numpy as np
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

PROG = "refscene"
PANO_CONVENTION = ("u=(c+.5)/W, v=(r+.5)/H, azimuth=pi*(1-2u)=atan2(y,x), "
                   "polar=pi*v from +Z, local frame")
HALF_MAX = 65504.0
# Cycles maps its panorama frame (x forward, y left, z up) onto the Blender camera frame
# (looking along -Z, up +Y) with this matrix (intern/cycles/blender/camera.cpp,
# blender_camera_matrix for CAMERA_PANORAMA); local -> world of the panorama is
# camera.matrix_world @ PANO_TO_CAMERA.
PANO_TO_CAMERA = Matrix(((0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0)))


class SceneError(Exception):
    """A bad scene description or command line (exit code 1)."""


# ---------------------------------------------------------------- scene description

def _vec(obj, key, n, where, path):
    v = obj.get(key)
    if (not isinstance(v, list) or len(v) != n
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                       for x in v)):
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
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if ok and integer:
        ok = float(v).is_integer()
    if ok and lo is not None:
        ok = v >= lo
    if not ok:
        raise SceneError("%s: %s.%s = %s: expected %s%s" % (
            path, where, key, json.dumps(v), "an integer" if integer else "a number",
            "" if lo is None else " >= %g" % lo))
    return int(v) if integer else float(v)


def resolve_path(spec, json_path):
    """blender-data:NAME, shared:PATH or a path relative to the JSON file."""
    if spec.startswith("blender-data:"):
        name = spec[len("blender-data:"):]
        roots = [os.environ.get("RS_BLENDER_WORLDS", ""),
                 os.path.join(bpy.utils.system_resource('DATAFILES'), "studiolights", "world"),
                 "/usr/share/blender/datafiles/studiolights/world"]
        for root in roots:
            if root and os.path.isfile(os.path.join(root, name)):
                return os.path.join(root, name)
        return os.path.join(roots[-1], name)
    if spec.startswith("shared:"):
        # The shared folder sits beside the repository unless RHOSCAN_SHARED says otherwise.
        repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        root = os.environ.get("RHOSCAN_SHARED", os.path.join(os.path.dirname(repo), "shared"))
        return os.path.join(root, spec[len("shared:"):])
    return os.path.join(os.path.dirname(os.path.abspath(json_path)), spec)


def load_scene(path):
    """Reads and checks the scene description; returns a dict with defaults filled in."""
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
        raise SceneError("%s: parts: expected a non-empty list of boxes" % path)
    for i, p in enumerate(parts):
        where = "parts[%d]" % i
        if not isinstance(p, dict):
            raise SceneError("%s: %s: expected an object with min, max, albedo" % (path, where))
        lo, hi = _vec(p, "min", 3, where, path), _vec(p, "max", 3, where, path)
        if not all(a < b for a, b in zip(lo, hi)):
            raise SceneError("%s: %s: min %s, max %s: expected min < max on every axis"
                             % (path, where, lo, hi))
        alb = _vec(p, "albedo", 3, where, path)
        if not all(0.0 <= a <= 1.0 for a in alb):
            raise SceneError("%s: %s.albedo = %s: expected values in 0..1" % (path, where, alb))
    env = sc["env"]
    if not isinstance(env, dict) or not isinstance(env.get("file"), str):
        raise SceneError("%s: env: expected an object with a \"file\" string" % path)
    env_file = resolve_path(env["file"], path)
    if not os.path.isfile(env_file):
        raise SceneError("%s: env.file = \"%s\": no such file (%s)" % (path, env["file"], env_file))
    cam, scn = sc["camera"], sc["scanner"]
    if not isinstance(cam, dict) or not isinstance(scn, dict):
        raise SceneError("%s: camera and scanner: expected objects" % path)
    out = {
        "parts": parts,
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
        "env_samples": _num(sc, "env_samples", "scene", path, 16, lo=1, integer=True),
        "pano_size": _ints(sc, "pano_size", 2, "scene", path) if "pano_size" in sc else [1024, 512],
        "seed": _num(sc, "seed", "scene", path, 0, lo=0, integer=True),
        "exr_half": sc.get("exr_half", True),
        "sun": sc.get("sun"),
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
    return out


# ---------------------------------------------------------------- geometry

def build_bmesh(parts):
    """One triangulated mesh of all boxes, in part order; face material_index = part index.
    Vertex order and triangle split follow Blender's cube primitive + bmesh triangulate,
    which is how the shared reference truth.ply files were made."""
    bm = bmesh.new()
    for i, p in enumerate(parts):
        lo, hi = Vector(p["min"]), Vector(p["max"])
        res = bmesh.ops.create_cube(bm, size=2.0)
        for v in res["verts"]:
            v.co = Vector(lo[k] + (v.co[k] + 1.0) * 0.5 * (hi[k] - lo[k]) for k in range(3))
        for f in {f for v in res["verts"] for f in v.link_faces}:
            f.material_index = i
    bm.faces.ensure_lookup_table()
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.verts.ensure_lookup_table()
    bm.faces.ensure_lookup_table()
    bm.verts.index_update()
    bm.faces.index_update()
    return bm


def write_truth_ply(bm, parts, path):
    lines = ["ply", "format ascii 1.0",
             "comment reference scene, per-face Lambertian albedo",
             "element vertex %d" % len(bm.verts),
             "property float x", "property float y", "property float z",
             "element face %d" % len(bm.faces),
             "property list uchar int vertex_indices",
             "property float red", "property float green", "property float blue",
             "property int part", "end_header"]
    lines += ["%f %f %f" % tuple(v.co) for v in bm.verts]
    for f in bm.faces:
        a = parts[f.material_index]["albedo"]
        lines.append("3 %d %d %d %f %f %f %d" % (
            f.verts[0].index, f.verts[1].index, f.verts[2].index, a[0], a[1], a[2], f.material_index))
    write_text(path, "\n".join(lines) + "\n")


def write_text(path, text):
    """Atomic write: a temporary file beside the target, then rename."""
    tmp = path + ".tmp%d" % os.getpid()
    with open(tmp, "w", encoding="ascii", newline="\n") as f:
        f.write(text)
    os.replace(tmp, path)


# ---------------------------------------------------------------- Blender scene

def clear_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)


def make_model(bm, parts):
    mesh = bpy.data.meshes.new("model")
    bm.to_mesh(mesh)
    for i, p in enumerate(parts):
        mat = bpy.data.materials.new(p.get("name", "part%d" % i))
        mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        # A pure Diffuse BSDF (roughness 0 = Lambert): the DiffCol pass is then the albedo.
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*p["albedo"], 1.0)
        bsdf.inputs["Roughness"].default_value = 0.0
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
        mesh.materials.append(mat)
    ob = bpy.data.objects.new("model", mesh)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def make_camera(pos, yaw_deg):
    cam = bpy.data.cameras.new("cam")
    cam.type = 'PANO'
    # Blender 3.4 keeps the panorama type in the Cycles settings; later versions on the camera.
    if hasattr(cam, "panorama_type"):
        cam.panorama_type = 'EQUIRECTANGULAR'
    else:
        cam.cycles.panorama_type = 'EQUIRECTANGULAR'
    cam.clip_start = 1e-3
    cam.clip_end = 1e6
    ob = bpy.data.objects.new("cam", cam)
    ob.location = pos
    # Euler XYZ (90, 0, yaw - 90) degrees turns the camera's -Z onto world azimuth yaw.
    ob.rotation_euler = (math.pi / 2, 0.0, math.radians(yaw_deg) - math.pi / 2)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob
    return ob


def make_world(path, strength, rot_deg):
    world = bpy.data.worlds.new("env")
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = 'POINT'
    # Lookup direction = Rz(rot) * world direction, so world azimuth = HDR azimuth - rot.
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(rot_deg))
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(path, check_existing=False)
    tex.image.colorspace_settings.name = 'Linear'
    tex.interpolation = 'Linear'
    tex.projection = 'EQUIRECTANGULAR'
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    bpy.context.scene.world = world


def make_sun(sc):
    light = bpy.data.lights.new("sun", 'SUN')
    light.energy = sc["sun_strength"]          # W/m2 on a surface facing the sun
    light.angle = math.radians(sc["sun_angle_deg"])
    light.color = sc["sun_color"]
    ob = bpy.data.objects.new("sun", light)
    az, el = sc["sun_dir_deg"]
    # A sun lamp shines along its local -Z: point local +Z at the sun.
    ob.rotation_euler = (0.0, math.radians(90.0 - el), math.radians(az))
    bpy.context.scene.collection.objects.link(ob)
    return ob


def setup_cycles(sc, samples, seed, threads):
    scene = bpy.context.scene
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y = sc["pano_size"]
    r.resolution_percentage = 100
    r.film_transparent = False
    r.threads_mode = 'FIXED'
    r.threads = threads
    r.use_persistent_data = False
    c = scene.cycles
    c.device = 'CPU'
    c.progressive = 'PATH'
    c.samples = samples
    c.seed = seed
    c.use_animated_seed = False
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.max_bounces = 32
    c.diffuse_bounces = 32
    c.glossy_bounces = 0
    c.transmission_bounces = 0
    c.volume_bounces = 0
    c.transparent_max_bounces = 8
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.blur_glossy = 0.0
    vs = scene.view_settings
    vs.view_transform = 'Standard'
    vs.look = 'None'
    vs.exposure = 0.0
    vs.gamma = 1.0
    for attr in dir(r):
        if attr.startswith("use_stamp"):
            try:
                setattr(r, attr, False)   # no dates or timings in the image files
            except (AttributeError, TypeError):
                pass
    vl = scene.view_layers[0]
    vl.use_pass_diffuse_color = True
    vl.use_pass_diffuse_direct = True
    vl.use_pass_diffuse_indirect = True


def render_files(outdir, slots, half):
    """Renders the current scene once; the compositor writes each slot (file stem -> Render
    Layers output) as an RGBA EXR with ZIP compression, half or float. Returns the list of
    written files. Half cannot hold values beyond 65504: such an image is written as float."""
    scene = bpy.context.scene
    scene.use_nodes = True
    nt = scene.node_tree
    nt.nodes.clear()
    rl = nt.nodes.new("CompositorNodeRLayers")
    tmpdir = os.path.join(outdir, ".render-tmp%d" % os.getpid())
    outs = {}
    for depth in (("16", "32") if half else ("32",)):
        node = nt.nodes.new("CompositorNodeOutputFile")
        node.base_path = os.path.join(tmpdir, depth)
        node.format.file_format = 'OPEN_EXR'
        node.format.color_depth = depth
        node.format.exr_codec = 'ZIP'
        node.format.color_mode = 'RGBA'
        node.file_slots.clear()
        for stem, socket in slots.items():
            node.file_slots.new(stem)
            nt.links.new(rl.outputs[socket], node.inputs[stem])
        outs[depth] = node.base_path
    comp = nt.nodes.new("CompositorNodeComposite")
    nt.links.new(rl.outputs["Image"], comp.inputs["Image"])
    scene.frame_set(1)
    bpy.ops.render.render(write_still=False)
    written = []
    for stem in slots:
        name = "%s%04d.exr" % (stem, scene.frame_current)
        chosen = outs["32"]
        if half:
            if not half_overflows(os.path.join(outs["16"], name)):
                chosen = outs["16"]
            else:
                log("%s: values beyond the half-float range (%g): written as 32-bit float"
                    % (stem, HALF_MAX))
        dst = os.path.join(outdir, stem + ".exr")
        os.replace(os.path.join(chosen, name), dst)
        written.append(dst)
    remove_tree(tmpdir)
    return written


def half_overflows(path):
    """True when a half-float EXR holds values at the half range's end (Blender clamps to
    +-65504 when writing half) or non-finite ones."""
    img = bpy.data.images.load(path, check_existing=False)
    try:
        px = np.empty(len(img.pixels), dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return not np.all(np.abs(px) < HALF_MAX)


def remove_tree(path):
    for root, dirs, files in os.walk(path, topdown=False):
        for f in files:
            os.remove(os.path.join(root, f))
        for d in dirs:
            os.rmdir(os.path.join(root, d))
    if os.path.isdir(path):
        os.rmdir(path)


# ---------------------------------------------------------------- scan

def simulate_scan(bm, parts, sc, seed):
    """Casts the scanner's angular grid against the mesh. Column c looks at azimuth
    360 c / cols degrees (counter-clockwise from +X), row r at elevation
    linspace(low, high, rows)[r]. Returns (cols, rows, 4) float64: scanner-local x y z and
    intensity, all zero (intensity 0.5) where nothing was hit."""
    cols, rows = sc["scan_grid"]
    az = np.radians(np.arange(cols) * (360.0 / cols))
    el = np.radians(np.linspace(sc["scan_el_deg"][0], sc["scan_el_deg"][1], rows))
    ca, sa = np.cos(az)[:, None], np.sin(az)[:, None]
    ce, se = np.cos(el)[None, :], np.sin(el)[None, :]
    dirs = np.stack(np.broadcast_arrays(ca * ce, sa * ce, np.ones_like(ca) * se), -1).reshape(-1, 3)
    tree = BVHTree.FromBMesh(bm)
    origin = Vector(sc["scan_pos"])
    dist = np.full(len(dirs), np.nan)
    part = np.zeros(len(dirs), dtype=np.int64)
    faces = bm.faces
    ray_cast = tree.ray_cast
    for i, d in enumerate(dirs.tolist()):
        loc, nrm, idx, t = ray_cast(origin, Vector(d))
        if idx is not None:
            dist[i] = t
            part[i] = faces[idx].material_index
    # One draw per grid cell, hit or not, so the noise of a cell depends only on the seed.
    noise = np.random.default_rng(seed).normal(0.0, sc["scan_noise_m"], len(dirs))
    hit = np.isfinite(dist)
    out = np.zeros((len(dirs), 4))
    out[:, 3] = 0.5
    rng_m = dist[hit] + noise[hit]
    out[hit, :3] = dirs[hit] * rng_m[:, None]
    mean_albedo = np.array([sum(p["albedo"]) / 3.0 for p in parts])
    out[hit, 3] = mean_albedo[part[hit]]
    return out.reshape(cols, rows, 4), int(hit.sum())


def write_ptx(path, pts, scan_pos):
    cols, rows = pts.shape[:2]
    p = tuple(scan_pos)
    head = ["%d" % cols, "%d" % rows, "%f %f %f" % p, "1 0 0", "0 1 0", "0 0 1",
            "1 0 0 0", "0 1 0 0", "0 0 1 0", "%f %f %f 1" % p]
    flat = pts.reshape(-1, 4)
    hit = ~np.all(flat[:, :3] == 0.0, axis=1)
    lines = np.full(len(flat), "0 0 0 0.5", dtype=object)
    lines[hit] = ["%.4f %.4f %.4f %.4f" % tuple(q) for q in flat[hit].tolist()]
    write_text(path, "\n".join(head) + "\n" + "\n".join(lines.tolist()) + "\n")


# ---------------------------------------------------------------- main

def log(msg):
    print("%s: %s" % (PROG, msg), file=sys.stderr, flush=True)


def parse_args(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    opts = {"samples": None, "seed": None, "threads": 2, "render": True}
    pos = []
    i = 0
    while i < len(args):
        a = args[i]
        if a in ("--samples", "--seed", "--threads"):
            if i + 1 >= len(args) or not args[i + 1].isdigit() or (a != "--seed" and int(args[i + 1]) < 1):
                raise SceneError("%s: expected a positive integer after it" % a)
            opts[a[2:]] = int(args[i + 1])
            i += 2
            continue
        if a == "--no-render":
            opts["render"] = False
        elif a.startswith("--"):
            raise SceneError("unknown option %s (expected --samples, --seed, --threads, --no-render)" % a)
        else:
            pos.append(a)
        i += 1
    if len(pos) != 2:
        raise SceneError("usage: blender -b --factory-startup --python render.py -- SCENE.json OUTDIR "
                         "[--samples N] [--seed S] [--threads T] [--no-render]")
    return pos[0], pos[1], opts


def run(argv):
    scene_path, outdir, opts = parse_args(argv)
    sc = load_scene(scene_path)
    samples = opts["samples"] or sc["samples"]
    seed = sc["seed"] if opts["seed"] is None else opts["seed"]
    os.makedirs(outdir, exist_ok=True)
    t_start = time.time()
    clear_scene()
    bm = build_bmesh(sc["parts"])
    model = make_model(bm, sc["parts"])
    cam = make_camera(sc["cam_pos"], sc["cam_yaw_deg"])
    make_world(sc["env_path"], sc["env_strength"], sc["env_rot_deg"])
    if sc["sun"] is not None:
        make_sun(sc)
    bpy.context.view_layer.update()

    write_truth_ply(bm, sc["parts"], os.path.join(outdir, "truth.ply"))
    scan_pos = Vector(sc["scan_pos"])      # float32, as Blender stores positions
    t0 = time.time()
    pts, nhit = simulate_scan(bm, sc["parts"], sc, seed)
    write_ptx(os.path.join(outdir, "scan.ptx"), pts, scan_pos)
    log("scan %d x %d, %d returns, %.1f s" % (sc["scan_grid"][0], sc["scan_grid"][1], nhit, time.time() - t0))

    # The intended pose in double precision; Blender's float32 camera matrix must agree.
    yaw = math.radians(sc["cam_yaw_deg"])
    rot = [[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]]
    blender_rot = cam.matrix_world.to_3x3() @ PANO_TO_CAMERA
    err = max(abs(blender_rot[i][j] - rot[i][j]) for i in range(3) for j in range(3))
    if err > 1e-6:
        raise RuntimeError("camera rotation differs from Rz(yaw) by %g" % err)
    truth = {
        "pano_convention": PANO_CONVENTION,
        "camera_position": list(cam.location),
        "camera_rotation_local_to_world": rot,
        "scanner_position": list(scan_pos),
        "parts": sc["parts"],
        "env": sc["env"],
        "sun": sc["sun"],
        "samples": samples,
    }
    write_text(os.path.join(outdir, "truth.json"), json.dumps(truth, indent=1) + "\n")

    if opts["render"]:
        setup_cycles(sc, samples, seed, opts["threads"])
        t0 = time.time()
        render_files(outdir, {"pano": "Image", "pano_diffcol": "DiffCol",
                              "pano_diffdir": "DiffDir", "pano_diffind": "DiffInd"}, sc["exr_half"])
        log("pano %d x %d, %d samples, %d threads, %.1f s"
            % (sc["pano_size"][0], sc["pano_size"][1], samples, opts["threads"], time.time() - t0))
        # The environment alone: hide the model (a sun lamp is never seen by camera rays).
        model.hide_render = True
        bpy.context.scene.cycles.samples = sc["env_samples"]
        t0 = time.time()
        render_files(outdir, {"env": "Image"}, sc["exr_half"])
        log("env %d samples, %.1f s" % (sc["env_samples"], time.time() - t0))
    bm.free()
    log("done in %.1f s" % (time.time() - t_start))


def main():
    try:
        run(sys.argv)
    except SceneError as e:
        log(str(e))
        sys.exit(1)
    except OSError as e:
        log("%s: %s" % (e.filename or "", e.strerror or e))
        sys.exit(2)
    except Exception:              # Blender would print the traceback and still exit 0
        import traceback
        traceback.print_exc()
        sys.exit(3)
    sys.exit(0)


if __name__ == "__main__":
    main()
