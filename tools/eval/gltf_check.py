#!/usr/bin/python3
"""gltf_check: reads a GLB (glTF 2.0 binary) without rhoscan's code and checks it against the
glTF 2.0 specification's rules that a writer can break: the 12-byte header (magic, version 2,
total length), the JSON chunk then the BIN chunk (4-byte aligned, padded), asset.version, every
index in range (scene, nodes, meshes, accessors, bufferViews, buffers, materials, textures,
images, samplers), bufferViews inside their buffer, accessors inside their bufferView and aligned
to their component size, POSITION's required min/max equal to the data's, indices below the
vertex count, mode 4 (triangles), image/png texture sources that decode, and a
metallic-roughness material with a baseColorTexture.

As a module: load(path) -> dict with the parsed JSON, the buffer, each primitive's positions
(glTF Y-up), UVs, triangles and decoded texture (linear floats). As a program: prints the
problems and exits 1 when there is any.
"""
import io
import json
import struct
import sys

import numpy as np

COMPONENTS = {5120: ('b', 1), 5121: ('B', 1), 5122: ('h', 2), 5123: ('H', 2), 5125: ('I', 4), 5126: ('f', 4)}
TYPES = {'SCALAR': 1, 'VEC2': 2, 'VEC3': 3, 'VEC4': 4, 'MAT2': 4, 'MAT3': 9, 'MAT4': 16}


class GltfError(Exception):
    pass


def _need(cond, msg):
    if not cond:
        raise GltfError(msg)


def _chunks(data):
    _need(len(data) >= 20, 'shorter than a GLB header and one chunk')
    magic, version, length = struct.unpack_from('<III', data, 0)
    _need(magic == 0x46546C67, 'magic is not glTF')
    _need(version == 2, 'container version %d, expected 2' % version)
    _need(length == len(data), 'header length %d, file has %d bytes' % (length, len(data)))
    off, chunks = 12, []
    while off < len(data):
        _need(off + 8 <= len(data), 'chunk header past the end at %d' % off)
        clen, ctype = struct.unpack_from('<II', data, off)
        _need(clen % 4 == 0, 'chunk at %d: length %d not a multiple of 4' % (off, clen))
        _need(off + 8 + clen <= len(data), 'chunk at %d runs past the end' % off)
        chunks.append((ctype, data[off + 8:off + 8 + clen]))
        off += 8 + clen
    _need(chunks and chunks[0][0] == 0x4E4F534A, 'first chunk is not JSON')
    _need(len(chunks) < 2 or chunks[1][0] == 0x004E4942, 'second chunk is not BIN')
    return json.loads(chunks[0][1].decode('utf-8')), (chunks[1][1] if len(chunks) > 1 else b'')


def _index(doc, key, i, what):
    arr = doc.get(key, [])
    _need(isinstance(i, int) and 0 <= i < len(arr), '%s: %s index %r out of range (%d)' % (what, key, i, len(arr)))
    return arr[i]


def _view_bytes(doc, binbuf, vi, what):
    v = _index(doc, 'bufferViews', vi, what)
    b = _index(doc, 'buffers', v.get('buffer'), 'bufferView %d' % vi)
    _need('uri' not in b, 'buffer with a uri: a GLB buffer 0 is the BIN chunk')
    _need(b['byteLength'] <= len(binbuf), 'buffer byteLength %d > BIN chunk %d' % (b['byteLength'], len(binbuf)))
    off, ln = v.get('byteOffset', 0), v['byteLength']
    _need(off + ln <= b['byteLength'], 'bufferView %d [%d, %d) outside its buffer (%d)' % (vi, off, off + ln,
                                                                                       b['byteLength']))
    return v, binbuf[off:off + ln]


def _accessor(doc, binbuf, ai, what):
    a = _index(doc, 'accessors', ai, what)
    fmt, size = COMPONENTS.get(a.get('componentType'), (None, 0))
    _need(fmt, 'accessor %d: componentType %r' % (ai, a.get('componentType')))
    n = TYPES.get(a.get('type'))
    _need(n, 'accessor %d: type %r' % (ai, a.get('type')))
    v, vb = _view_bytes(doc, binbuf, a['bufferView'], 'accessor %d' % ai)
    off, count = a.get('byteOffset', 0), a['count']
    stride = v.get('byteStride', size * n)
    _need(off % size == 0 and v.get('byteOffset', 0) % size == 0, 'accessor %d: misaligned' % ai)
    _need(count >= 1 and off + stride * (count - 1) + size * n <= len(vb),
          'accessor %d: %d elements from %d overrun its bufferView (%d bytes)' % (ai, count, off, len(vb)))
    dt = np.dtype('<' + fmt)
    arr = np.ndarray((count, n), dtype=dt, buffer=vb, offset=off, strides=(stride, size)).copy()
    return a, arr


def _decode_png(data):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open('mem.png', oiio.ImageSpec(), oiio.IOMemReader(data)) if hasattr(
        oiio, 'IOMemReader') else None
    if inp is None:
        import tempfile
        import os
        fd, tmp = tempfile.mkstemp(suffix='.png')
        os.write(fd, data)
        os.close(fd)
        img = oiio.ImageBuf(tmp)
        px = img.get_pixels(oiio.FLOAT)
        os.unlink(tmp)
    else:
        px = inp.read_image(oiio.FLOAT)
        inp.close()
    _need(px is not None and px.ndim == 3, 'a texture image does not decode as PNG')
    s = px[:, :, :3].astype(np.float64)
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)  # sRGB -> linear


def load(path):
    data = open(path, 'rb').read()
    doc, binbuf = _chunks(data)
    _need(doc.get('asset', {}).get('version') == '2.0', 'asset.version is not "2.0"')
    scene = _index(doc, 'scenes', doc.get('scene', 0), 'scene')
    out = {'json': doc, 'primitives': [], 'translation': [0.0, 0.0, 0.0]}
    for ni in scene.get('nodes', []):
        node = _index(doc, 'nodes', ni, 'scene')
        out['translation'] = node.get('translation', [0.0, 0.0, 0.0])
        mesh = _index(doc, 'meshes', node['mesh'], 'node %d' % ni)
        for pi, prim in enumerate(mesh['primitives']):
            what = 'primitive %d' % pi
            _need(prim.get('mode', 4) == 4, what + ': mode is not 4 (triangles)')
            pa, pos = _accessor(doc, binbuf, prim['attributes']['POSITION'], what)
            _need(pa['componentType'] == 5126 and pa['type'] == 'VEC3', what + ': POSITION not float VEC3')
            _need('min' in pa and 'max' in pa, what + ': POSITION without min/max (required)')
            _need(np.allclose(pa['min'], pos.min(axis=0), rtol=0, atol=1e-6) and
                  np.allclose(pa['max'], pos.max(axis=0), rtol=0, atol=1e-6), what + ': POSITION min/max wrong')
            ta, uv = _accessor(doc, binbuf, prim['attributes']['TEXCOORD_0'], what)
            _need(ta['componentType'] == 5126 and ta['type'] == 'VEC2', what + ': TEXCOORD_0 not float VEC2')
            _need(uv.min() >= 0 and uv.max() <= 1, what + ': UVs outside [0, 1]')
            ia, idx = _accessor(doc, binbuf, prim['indices'], what)
            _need(ia['componentType'] in (5121, 5123, 5125) and ia['type'] == 'SCALAR', what + ': indices type')
            _need(idx.size % 3 == 0 and idx.max() < len(pos), what + ': indices beyond the vertices')
            mat = _index(doc, 'materials', prim['material'], what)
            pbr = mat.get('pbrMetallicRoughness', {})
            _need(pbr.get('metallicFactor') == 0 and pbr.get('roughnessFactor') == 1,
                  what + ': material not metallic 0, roughness 1')
            tex = _index(doc, 'textures', pbr['baseColorTexture']['index'], what)
            if 'sampler' in tex:
                _index(doc, 'samplers', tex['sampler'], what)
            img = _index(doc, 'images', tex['source'], what)
            _need(img.get('mimeType') == 'image/png', what + ': image not image/png')
            _, png = _view_bytes(doc, binbuf, img['bufferView'], 'image')
            _need(png[:8] == b'\x89PNG\r\n\x1a\n', what + ': image bytes are not a PNG')
            out['primitives'].append({'pos': pos.astype(np.float64), 'uv': uv.astype(np.float64),
                                      'tris': idx.reshape(-1, 3).astype(np.int64), 'texture': _decode_png(png),
                                      'image_name': img.get('name', '')})
    return out


def sample(tex, uv):
    """Bilinear lookup of tex (H x W x 3) at UVs (N x 2), glTF's convention (v down), clamped."""
    h, w = tex.shape[:2]
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    return ((1 - fx) * (1 - fy) * tex[y0, x0] + fx * (1 - fy) * tex[y0, x1] + (1 - fx) * fy * tex[y1, x0] +
            fx * fy * tex[y1, x1])


def main():
    if len(sys.argv) != 2:
        print('usage: gltf_check.py FILE.glb', file=sys.stderr)
        return 2
    try:
        g = load(sys.argv[1])
    except (GltfError, KeyError, ValueError, TypeError) as e:
        print('%s: %s' % (sys.argv[1], e))
        return 1
    nt = sum(len(p['tris']) for p in g['primitives'])
    print('%s: valid glTF 2.0 binary, %d primitive(s), %d triangles' % (sys.argv[1], len(g['primitives']), nt))
    return 0


if __name__ == '__main__':
    sys.exit(main())
