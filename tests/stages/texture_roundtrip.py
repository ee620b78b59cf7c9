#!/usr/bin/python3
"""texture_roundtrip (issue 22, parts 3 and 4): runs the pipeline on sample_data/two_planes (a
floor and a wall, each of one uniform albedo), then reads the exports back without rhoscan's
code:
  - albedo.glb passes tools/eval/gltf_check.py's checks of the glTF 2.0 rules;
  - its triangles are albedo.ply's faces (same order, Y-up turned back to Z-up, with
    rhoscan_origin as the node's translation) and the texture at each face's centroid equals
    the facet's solved albedo and the part's true albedo (median over faces within 3 %, 90th
    percentile within 8 %);
  - albedo.obj: triangles only, Y up, every face with a UV, its mtllib and map_Kd files there;
  - albedo_vertex.ply: uchar sRGB red green blue equal to the sRGB encoding of its linear floats;
  - albedo_texture.exr (R G B) and albedo_texture_flags.exr (flags, sigma): a power-of-two square,
    nothing non-finite; albedo_texture.png its sRGB encoding.
"""
import argparse
import os
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(SRC, 'tools', 'eval'))
sys.path.insert(0, os.path.join(SRC, 'tests', 'playback'))
import gltf_check  # noqa: E402
from plyread import read_ply  # noqa: E402

FLOOR, WALL = np.array([0.1, 0.2, 0.7]), np.array([0.7, 0.1, 0.1])  # sample_data/two_planes/README.md


def fail(msg):
    print('FAIL: ' + msg)
    sys.exit(1)


def srgb8(x):
    x = np.clip(x, 0, 1)
    return np.floor(np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255 + 0.5)


def check_glb(work, alb):
    g = gltf_check.load(os.path.join(work, 'albedo.glb'))
    if len(g['primitives']) != 1:
        fail('expected one page (one primitive), got %d' % len(g['primitives']))
    p = g['primitives'][0]
    pos = p['pos'] + np.array(g['translation'])
    zup = np.stack([pos[:, 0], -pos[:, 2], pos[:, 1]], axis=1)  # glTF Y-up -> rhoscan Z-up
    v = alb['vertex']
    verts = np.stack([v['x'], v['y'], v['z']], axis=1).astype(np.float64)
    faces = alb['face']['vertex_indices'].astype(np.int64)
    if len(p['tris']) != len(faces):
        fail('albedo.glb has %d triangles, albedo.ply %d faces' % (len(p['tris']), len(faces)))
    cen_glb = zup[p['tris']].mean(axis=1)
    cen_ply = verts[faces].mean(axis=1)
    off = np.abs(cen_glb - cen_ply).max()
    if off > 1e-4:
        fail('albedo.glb triangles are not albedo.ply faces (centroids %.3g m apart)' % off)
    tex = gltf_check.sample(p['texture'], p['uv'][p['tris']].mean(axis=1))
    rho = np.stack([alb['face']['albedo_' + c] for c in 'rgb'], axis=1)
    est = alb['face']['estimable'] > 0
    truth = np.where((np.abs(cen_ply[:, 2]) < 0.3)[:, None], FLOOR, WALL)  # the floor is z = 0
    areas = []
    for name, ref in (('facet albedo', rho), ('true albedo', truth)):
        rel = np.abs(tex[est] - ref[est]).sum(axis=1) / ref[est].sum(axis=1)
        med, p90 = np.median(rel), np.percentile(rel, 90)
        print('texture at facet centroids against the %s: median %.2f %%, 90th percentile %.2f %% (%d facets)' %
              (name, 100 * med, 100 * p90, est.sum()))
        if med > 0.03 or p90 > 0.08:
            fail('texture at the centroids differs from the %s' % name)
        areas.append(med)
    return g


def check_obj(work, nfaces, zrange):
    lines = open(os.path.join(work, 'albedo.obj')).read().splitlines()
    vs = np.array([[float(t) for t in ln.split()[1:4]] for ln in lines if ln.startswith('v ')])
    vts = [ln for ln in lines if ln.startswith('vt ')]
    fs = [ln.split()[1:] for ln in lines if ln.startswith('f ')]
    if len(fs) != nfaces or any(len(f) != 3 or '/' not in f[0] for f in fs):
        fail('albedo.obj: expected %d triangles with UVs' % nfaces)
    if len(vts) != len(vs):
        fail('albedo.obj: %d vertices, %d UVs' % (len(vs), len(vts)))
    if abs(vs[:, 1].min() - zrange[0]) > 1e-3 or abs(vs[:, 1].max() - zrange[1]) > 1e-3:
        fail('albedo.obj is not Y-up: its y range is not the model\'s height range')
    mtl = [ln.split()[1] for ln in lines if ln.startswith('mtllib')]
    if mtl != ['albedo.mtl'] or not os.path.isfile(os.path.join(work, 'albedo.mtl')):
        fail('albedo.obj: mtllib albedo.mtl missing')
    maps = [ln.split()[1] for ln in open(os.path.join(work, 'albedo.mtl')) if ln.startswith('map_Kd')]
    if not maps or not all(os.path.isfile(os.path.join(work, m)) for m in maps):
        fail('albedo.mtl: map_Kd names no texture that exists')
    print('albedo.obj: %d triangles, Y up, texture %s' % (len(fs), ', '.join(maps)))


def check_vertex_ply(work):
    vp = read_ply(os.path.join(work, 'albedo_vertex.ply'))['vertex']
    for c, n in (('r', 'red'), ('g', 'green'), ('b', 'blue')):
        if vp[n].dtype != np.uint8:
            fail('albedo_vertex.ply: %s is not uchar' % n)
        if np.abs(srgb8(vp['albedo_' + c].astype(np.float64)) - vp[n]).max() > 1:
            fail('albedo_vertex.ply: %s is not the sRGB encoding of albedo_%s' % (n, c))
    print('albedo_vertex.ply: %d vertices with uchar sRGB and float linear albedo' % len(vp['red']))


def check_exr(work):
    import OpenImageIO as oiio
    rgb, fl = oiio.ImageBuf(os.path.join(work, 'albedo_texture.exr')), oiio.ImageBuf(
        os.path.join(work, 'albedo_texture_flags.exr'))
    spec = rgb.spec()
    if list(spec.channelnames) != ['R', 'G', 'B'] or list(fl.spec().channelnames) != ['flags', 'sigma']:
        fail('albedo_texture.exr channels %s, albedo_texture_flags.exr %s' % (list(spec.channelnames),
                                                                             list(fl.spec().channelnames)))
    if spec.width != spec.height or spec.width & (spec.width - 1):
        fail('albedo_texture.exr is %d x %d: expected a power-of-two square' % (spec.width, spec.height))
    px, fx = rgb.get_pixels(oiio.FLOAT), fl.get_pixels(oiio.FLOAT)
    if not np.isfinite(px).all() or not np.isfinite(fx).all():
        fail('the texture EXRs hold values that are not finite')
    png = oiio.ImageBuf(os.path.join(work, 'albedo_texture.png')).get_pixels(oiio.FLOAT)[:, :, :3]
    if np.abs(png - srgb8(px) / 255).max() > 1.01 / 255:
        fail('albedo_texture.png is not the sRGB encoding of albedo_texture.exr')
    flags = fx[:, :, 0].astype(int)
    surface = (flags & 8) == 0
    print('albedo_texture.exr: %d x %d, %.1f %% of the texels on the surface, %.1f %% of those unseen' %
          (spec.width, spec.height, 100 * surface.mean(), 100 * ((flags & 1) != 0)[surface].mean()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    a = ap.parse_args()
    work = os.path.join(a.bin, 'texture_roundtrip')
    shutil.rmtree(work, ignore_errors=True)
    cmd = [os.path.join(a.bin, 'rhoscan'), 'run', os.path.join(SRC, 'configs', 'two_planes.ini'),
           '--set', 'pipeline.workdir=' + work, '--force', '--quiet']
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        fail('rhoscan run exited %d:\n%s' % (r.returncode, r.stdout[-3000:]))
    alb = read_ply(os.path.join(work, 'albedo.ply'))
    check_glb(work, alb)
    z = alb['vertex']['z']
    check_obj(work, len(alb['face']['vertex_indices']), (float(z.min()), float(z.max())))
    check_vertex_ply(work)
    check_exr(work)
    print('PASS')


if __name__ == '__main__':
    main()
