"""Renders an albedo.glb as Blender 3.4 imports it (glTF importer, Shading Smooth), with Cycles
under a uniform white sky, for the README's picture:
    blender -b --factory-startup --python tools/render_glb_picture.py -- ALBEDO.glb "CX CY CZ" "TX TY TZ" OUT.png
CX CY CZ: where the camera stands, TX TY TZ: where it looks (rhoscan's frame, which Blender's Z-up
frame is after the import)."""
import sys
import bpy
import mathutils

glb, cam_pos, target, out = sys.argv[sys.argv.index('--') + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb, import_shading='SMOOTH')
obs = [o for o in bpy.data.objects if o.type == 'MESH']
pts = [o.matrix_world @ mathutils.Vector(c) for o in obs for c in o.bound_box]
lo = mathutils.Vector([min(p[i] for p in pts) for i in range(3)])
hi = mathutils.Vector([max(p[i] for p in pts) for i in range(3)])
centre = (lo + hi) / 2
scene = bpy.context.scene
cam = bpy.data.objects.new('cam', bpy.data.cameras.new('cam'))
scene.collection.objects.link(cam)
cam.location = mathutils.Vector([float(v) for v in cam_pos.split()])
centre = mathutils.Vector([float(v) for v in target.split()])
cam.rotation_euler = (centre - cam.location).to_track_quat('-Z', 'Y').to_euler()
cam.data.lens = 24
scene.camera = cam
world = bpy.data.worlds.new('sky')
world.use_nodes = True
world.node_tree.nodes['Background'].inputs[0].default_value = (0.8, 0.85, 0.9, 1)
scene.world = world
scene.render.engine = 'CYCLES'
scene.cycles.samples = 24
scene.cycles.use_denoising = False
scene.cycles.device = 'CPU'
scene.render.resolution_x, scene.render.resolution_y = 800, 450
scene.view_settings.view_transform = 'Standard'
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
