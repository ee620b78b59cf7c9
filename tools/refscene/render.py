# Reference-scene generator: builds a scene of Lambertian parts (boxes, extruded polygons, imported meshes)
# under an HDR sky from a JSON description and writes the panorama, its passes, the truth, a PTX scan, rig frames.
# SPDX-License-Identifier: BSD-3-Clause
"""Run inside Blender 3.4 (needs numpy, from Debian's python3-numpy):

    blender -b --factory-startup --python tools/refscene/render.py -- SCENE.json OUTDIR \
        [--samples N] [--seed S] [--threads T] [--no-render]

Writes into OUTDIR: pano.exr, env.exr, pano_diffcol.exr, pano_diffdir.exr, pano_diffind.exr,
truth.ply, truth.json, scan.ptx, and with a rig rig.yaml and cam_K.exr (see tools/refscene/README.md
for the schema and conventions).
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import geom        # noqa: E402  (beside this script; Blender does not put it on the path)
import pattern     # noqa: E402
import rigsim      # noqa: E402
import scenedesc   # noqa: E402

PROG = "refscene"
PANO_CONVENTION = ("u=(c+.5)/W, v=(r+.5)/H, azimuth=pi*(1-2u)=atan2(y,x), "
                   "polar=pi*v from +Z, local frame")
HALF_MAX = 65504.0
# Cycles maps its panorama frame (x forward, y left, z up) onto the Blender camera frame
# (looking along -Z, up +Y) with this matrix (intern/cycles/blender/camera.cpp,
# blender_camera_matrix for CAMERA_PANORAMA); local -> world of the panorama is
# camera.matrix_world @ PANO_TO_CAMERA.
PANO_TO_CAMERA = Matrix(((0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0)))


SceneError = scenedesc.SceneError


def blender_worlds():
    """Where this Blender keeps its bundled skies (the blender-data: prefix of env.file)."""
    return [os.path.join(bpy.utils.system_resource('DATAFILES'), "studiolights", "world")]


# ---------------------------------------------------------------- geometry

def build_bmesh(sc):
    """One triangulated mesh of all parts; face material_index = part index. Boxes come first,
    in part order, with the vertex order and triangle split of Blender's cube primitive + bmesh
    triangulate (how the shared reference truth.ply files were made, so box-only scenes stay
    byte-identical); then the triangles of extrusions and meshes, in part order, as
    scenedesc made them (outward, counter-clockwise)."""
    bm = bmesh.new()
    for i, p in enumerate(sc["parts"]):
        if sc["kinds"][i] != "box":
            continue
        lo, hi = Vector(p["min"]), Vector(p["max"])
        res = bmesh.ops.create_cube(bm, size=2.0)
        for v in res["verts"]:
            v.co = Vector(lo[k] + (v.co[k] + 1.0) * 0.5 * (hi[k] - lo[k]) for k in range(3))
        for f in {f for v in res["verts"] for f in v.link_faces}:
            f.material_index = i
    bm.faces.ensure_lookup_table()
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    for i, solid in enumerate(sc["solids"]):
        if solid is None:
            continue
        verts, tris = solid
        bv = [bm.verts.new(co) for co in verts]
        skipped = 0
        for t in tris:
            try:
                f = bm.faces.new((bv[t[0]], bv[t[1]], bv[t[2]]))
            except ValueError:        # the same three vertices twice: one face is enough
                skipped += 1
                continue
            f.material_index = i
        closed, consistent, vol = geom.mesh_check(verts, tris)
        name = sc["parts"][i].get("name", "part%d" % i)
        log("part %d (%s, %s): %d triangles%s, %s" % (
            i, name, sc["kinds"][i], len(tris) - skipped,
            "" if not skipped and not sc["dropped_faces"][i]
            else " (%d degenerate or repeated faces left out)" % (skipped + sc["dropped_faces"][i]),
            "closed, volume %.4g m3" % vol if closed else
            "open" + ("" if consistent else ", inconsistently wound")))
        if closed and vol < 0:
            log("part %d (%s): the mesh encloses a negative volume: its faces point inward" % (i, name))
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


def pattern_colour(nt, pat):
    """Cycles math nodes computing pattern.index_tree(pat) at the shading point (world position:
    the model object has the identity transform) and picking that palette entry; returns the
    colour socket. Mix nodes with factor exactly 0 or 1 give the palette's values exactly."""
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    xyz = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(geo.outputs["Position"], xyz.inputs["Vector"])
    made = {}

    def socket(node):
        if isinstance(node, (int, float)):
            return float(node)
        if isinstance(node, str):
            return xyz.outputs[node.upper()]
        if id(node) in made:
            return made[id(node)]
        name, a, b = node
        m = nt.nodes.new("ShaderNodeMath")
        m.operation = name
        m.use_clamp = False
        for k, arg in enumerate((a, b) if name != "COMPARE" else (a, b, 0.5)):
            v = socket(arg)
            if isinstance(v, float):
                m.inputs[k].default_value = v
            else:
                nt.links.new(v, m.inputs[k])
        made[id(node)] = m.outputs["Value"]
        return made[id(node)]

    index = socket(pattern.index_tree(pat))
    colour = None
    for k, rgb in enumerate(pat["palette"]):
        if colour is None:
            rgbn = nt.nodes.new("ShaderNodeRGB")
            rgbn.outputs["Color"].default_value = (*rgb, 1.0)
            colour = rgbn.outputs["Color"]
            continue
        pick = nt.nodes.new("ShaderNodeMath")
        pick.operation = "COMPARE"
        nt.links.new(index, pick.inputs[0])
        pick.inputs[1].default_value = float(k)
        pick.inputs[2].default_value = 0.5
        mix = nt.nodes.new("ShaderNodeMixRGB")
        mix.blend_type = 'MIX'
        mix.use_clamp = False
        nt.links.new(pick.outputs["Value"], mix.inputs["Fac"])
        nt.links.new(colour, mix.inputs["Color1"])
        mix.inputs["Color2"].default_value = (*rgb, 1.0)
        colour = mix.outputs["Color"]
    return colour


def make_model(bm, parts, patterns):
    mesh = bpy.data.meshes.new("model")
    bm.to_mesh(mesh)
    for i, p in enumerate(parts):
        mat = bpy.data.materials.new(p.get("name", "part%d" % i))
        mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        # A pure Diffuse BSDF (roughness 0 = Lambert): the DiffCol pass is then the albedo.
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        if patterns[i] is None:
            bsdf.inputs["Color"].default_value = (*p["albedo"], 1.0)
        else:
            nt.links.new(pattern_colour(nt, patterns[i]), bsdf.inputs["Color"])
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


# ---------------------------------------------------------------- rig

def rig_truth(rig, samples):
    yaw = math.radians(rig["yaw_deg"])
    cams = []
    for k, c in enumerate(rig["cameras"]):
        cams.append({"name": c["name"], "frame": "cam_%d.exr" % k, "image_size": c["size"], "K": c["K"],
                     "dist": c["dist"], "R_rig_cam": c["R"], "t_rig_cam": c["t"]})
    return {"file": "rig.yaml", "position": rig["position"], "yaw_deg": rig["yaw_deg"],
            "rotation_local_to_world": [[math.cos(yaw), -math.sin(yaw), 0.0],
                                        [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]],
            "samples": samples, "preset": rig["preset"], "cameras": cams}


def render_rig(rig, samples, outdir, half):
    """One frame per rig camera, cam_K.exr: Cycles renders an undistorted pinhole view wide
    enough for the frame (square pixels, optical axis at the centre), then every frame pixel is
    undistorted (Newton, rigsim.undistort) and the render sampled there bilinearly. Pixels
    outside the lens's usable field (where calib/rig.c stops too) are black with alpha 0."""
    scene = bpy.context.scene
    scene.cycles.samples = samples
    # Only the camera changes between these renders: keep Cycles' scene (BVH, sky importance
    # map) instead of rebuilding it each time, which costs more than a small frame's samples.
    scene.render.use_persistent_data = True
    tmpdir = os.path.join(outdir, ".rig-tmp%d" % os.getpid())
    for k, c in enumerate(rig["cameras"]):
        t0 = time.time()
        a, b, ok = rigsim.frame_rays(c)
        try:
            f, (wi, hi) = rigsim.ideal_view(c, a, b, ok, rig["oversample"])
        except ValueError as e:
            raise SceneError("rig camera %d: %s" % (k, e))
        camd = bpy.data.cameras.new("rig_" + c["name"])
        camd.type = 'PERSP'
        camd.sensor_fit = 'HORIZONTAL'      # the focal applies to the width, whatever the aspect
        camd.sensor_width = 36.0
        camd.lens = f * 36.0 / wi
        camd.shift_x = camd.shift_y = 0.0
        camd.clip_start = 1e-3
        camd.clip_end = 1e6
        ob = bpy.data.objects.new("rig_" + c["name"], camd)
        r_cv, centre = rigsim.camera_world(c, rig["position"], rig["yaw_deg"])
        # Blender's camera looks along its -Z with +Y up: OpenCV's frame with y and z negated.
        r_bl = r_cv @ np.diag([1.0, -1.0, -1.0])
        ob.matrix_world = Matrix([[r_bl[i][0], r_bl[i][1], r_bl[i][2], centre[i]] for i in range(3)]
                                 + [[0.0, 0.0, 0.0, 1.0]])
        scene.collection.objects.link(ob)
        scene.camera = ob
        scene.render.resolution_x, scene.render.resolution_y = wi, hi
        render_files(tmpdir, {"ideal": "Image"}, False)
        ideal = read_exr(os.path.join(tmpdir, "ideal.exr"))
        frame = np.zeros(ok.shape + (4,), dtype=np.float32)
        frame[..., :3] = rigsim.remap(ideal[..., :3], f, a, b, ok)
        frame[..., 3] = ok
        write_exr(frame, os.path.join(outdir, "cam_%d.exr" % k), half)
        log("rig camera %d (%s): %d x %d from a %d x %d render (focal %.1f px), %d samples, %.1f%% of the "
            "pixels inside the usable field, %.1f s" % (k, c["name"], c["size"][0], c["size"][1], wi, hi, f,
                                                        samples, 100.0 * ok.mean(), time.time() - t0))
    remove_tree(tmpdir)


def read_exr(path):
    """H x W x 4 float32, rows top first."""
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1]


def write_exr(rgba, path, half):
    """Writes H x W x 4 (rows top first) as a ZIP EXR, half float unless that would clip."""
    h, w = rgba.shape[:2]
    if half and not np.all(np.abs(rgba) < HALF_MAX):
        log("%s: values beyond the half-float range: written as 32-bit float" % os.path.basename(path))
        half = False
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=True, float_buffer=True)
    try:
        img.colorspace_settings.name = 'Linear'
        img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
        st = bpy.context.scene.render.image_settings
        st.file_format = 'OPEN_EXR'
        st.color_depth = '16' if half else '32'
        st.exr_codec = 'ZIP'
        st.color_mode = 'RGBA'
        tmp = path + ".tmp%d.exr" % os.getpid()
        img.save_render(tmp, scene=bpy.context.scene)
        os.replace(tmp, path)
    finally:
        bpy.data.images.remove(img)


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
    sc = scenedesc.load_scene(scene_path, blender_worlds())
    samples = opts["samples"] or sc["samples"]
    seed = sc["seed"] if opts["seed"] is None else opts["seed"]
    os.makedirs(outdir, exist_ok=True)
    t_start = time.time()
    clear_scene()
    bm = build_bmesh(sc)
    model = make_model(bm, sc["parts"], sc["patterns"])
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
    rig = sc["rig"]
    if rig is not None:
        rig_samples = opts["samples"] or rig["samples"]
        truth["rig"] = rig_truth(rig, rig_samples)
        write_text(os.path.join(outdir, "rig.yaml"), rigsim.rig_yaml(rig["cameras"]))
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
        if rig is not None:
            model.hide_render = False
            render_rig(rig, rig_samples, outdir, sc["exr_half"])
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
