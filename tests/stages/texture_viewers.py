#!/usr/bin/python3
"""texture_viewers (issue 22, part 4): the exports open in the viewers users have, from Debian 12:
  - Blender 3.4 headless imports albedo.glb (Shading Flat and Smooth: its default setting fails
    on numpy's removed np.bool) and albedo.obj, and finds on the imported material an image
    texture node whose image loaded (pixels, the PNG's size);
  - Open3D 0.16 reads albedo_vertex.ply with vertex colours equal to its uchar red green blue;
  - CloudCompare 2.11 (command line, under xvfb-run) reads albedo_vertex.ply with its colours:
    its vertices exported as ASCII carry R G B equal to the file's.
Without blender, python3-open3d, cloudcompare or xvfb the test skips (77), and fails under CI=true.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

BLENDER_SCRIPT = r'''
import bpy, json, sys
path, kind, shading = sys.argv[sys.argv.index('--') + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
if kind == 'glb':
    bpy.ops.import_scene.gltf(filepath=path, import_shading=shading)
else:
    bpy.ops.wm.obj_import(filepath=path)
found = []
for ob in bpy.data.objects:
    if ob.type != 'MESH':
        continue
    for slot in ob.material_slots:
        m = slot.material
        if not m or not m.use_nodes:
            continue
        for n in m.node_tree.nodes:
            if n.type == 'TEX_IMAGE' and n.image is not None:
                found.append({'object': ob.name, 'material': m.name, 'image': n.image.name,
                              'size': list(n.image.size), 'faces': len(ob.data.polygons)})
print('RESULT ' + json.dumps(found))
'''


def need(tool):
    print('%s is not installed (tools/setup-debian.sh --tests installs it)' % tool)
    sys.exit(1 if os.environ.get('CI') == 'true' else 77)


def fail(msg):
    print('FAIL: ' + msg)
    sys.exit(1)


def blender_import(blender, path, kind, shading='SMOOTH'):
    r = subprocess.run([blender, '-b', '--factory-startup', '--python-expr', BLENDER_SCRIPT, '--', path, kind, shading],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith('RESULT ')]
    if r.returncode != 0 or not lines:
        fail('blender import of %s (%s) failed:\n%s' % (path, shading, r.stdout[-3000:]))
    found = json.loads(lines[-1][len('RESULT '):])
    if not found or not all(f['size'][0] > 0 and f['size'][1] > 0 and f['faces'] > 0 for f in found):
        fail('blender: no image texture with pixels on the material of %s: %s' % (path, found))
    print('blender %s %s: %s' % (kind, shading, found))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--config', required=True)
    a = ap.parse_args()
    blender = shutil.which('blender')
    if not blender:
        need('blender')
    try:
        import numpy as np
        import open3d as o3d
    except ImportError:
        need('python3-open3d')
    work = os.path.join(a.bin, 'texture_viewers')
    shutil.rmtree(work, ignore_errors=True)
    r = subprocess.run([os.path.join(a.bin, 'rhoscan'), 'run', a.config, '--set', 'pipeline.workdir=' + work, '--quiet'],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        fail('rhoscan run exited %d:\n%s' % (r.returncode, r.stdout[-3000:]))
    for shading in ('FLAT', 'SMOOTH'):
        blender_import(blender, os.path.join(work, 'albedo.glb'), 'glb', shading)
    blender_import(blender, os.path.join(work, 'albedo.obj'), 'obj')
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'playback'))
    from plyread import read_ply
    m = o3d.io.read_triangle_mesh(os.path.join(work, 'albedo_vertex.ply'))
    if not m.has_vertex_colors() or len(m.triangles) == 0:
        fail('open3d reads albedo_vertex.ply without vertex colours or triangles')
    v = read_ply(os.path.join(work, 'albedo_vertex.ply'))['vertex']
    want = np.stack([v['red'], v['green'], v['blue']], axis=1) / 255.0
    got = np.asarray(m.vertex_colors)
    if got.shape != want.shape or np.abs(got - want).max() > 1e-6:
        fail('open3d: vertex colours are not red green blue / 255')
    print('open3d: %d vertices, %d triangles, colours as written' % (len(got), len(m.triangles)))
    cloudcompare_colours(work, v)
    print('PASS')


def cloudcompare_colours(work, v):
    """CloudCompare loads the vertex PLY as a mesh; its vertices, extracted and saved as ASCII,
    must carry the file's colours (in the file's vertex order)."""
    import numpy as np
    cc, xvfb = shutil.which('CloudCompare'), shutil.which('xvfb-run')
    if not cc or not xvfb:
        need('cloudcompare' if not cc else 'xvfb')
    out = os.path.join(work, 'cloudcompare_vertices.asc')
    r = subprocess.run([xvfb, '-a', cc, '-SILENT', '-AUTO_SAVE', 'OFF', '-O', os.path.join(work, 'albedo_vertex.ply'),
                        '-EXTRACT_VERTICES', '-C_EXPORT_FMT', 'ASC', '-ADD_HEADER', '-SAVE_CLOUDS', 'FILE', out],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    if r.returncode != 0 or not os.path.exists(out):
        fail('CloudCompare could not read albedo_vertex.ply:\n' + r.stdout[-3000:])
    with open(out) as f:
        header = f.readline().split()
    if header[-3:] != ['R', 'G', 'B']:
        fail('CloudCompare read albedo_vertex.ply without colours (columns %s)' % header)
    got = np.loadtxt(out, comments='//')[:, -3:]
    want = np.stack([v['red'], v['green'], v['blue']], axis=1)
    if got.shape != want.shape or np.abs(got - want).max() > 0:
        fail('CloudCompare: colours differ from the file\'s red green blue')
    print('cloudcompare: %d vertices with the file\'s colours' % len(got))


if __name__ == '__main__':
    main()
