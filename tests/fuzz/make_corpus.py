#!/usr/bin/env python3
# make_corpus: writes the small seed files of tests/fuzz/corpus/<reader>/ (committed; rerun
# only to regenerate them). EXR seeds are added at run time by tools/fuzz.sh (the sample's
# pano_diffcol.exr); files named after a failure (hang-*, oom-*, crash-*) are fixed findings.
import os
import struct
import sys
import zlib

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def put(reader, name, data):
    os.makedirs(os.path.join(root, reader), exist_ok=True)
    with open(os.path.join(root, reader, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# ---- PLY: a square of two triangles with face properties, in the three encodings
verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
faces = [(0, 1, 2), (0, 2, 3)]


def ply_header(fmt):
    return ("ply\nformat %s 1.0\ncomment rhoscan seed\nelement vertex 4\n"
            "property float x\nproperty float y\nproperty double z\n"
            "element face 2\nproperty list uchar int vertex_indices\n"
            "property uchar estimable\nproperty float albedo_r\nend_header\n" % fmt)


ascii_body = "".join("%g %g %g\n" % v for v in verts) + \
    "".join("3 %d %d %d %d %g\n" % (f + (1, 0.5)) for f in faces)
put("ply", "ascii.ply", ply_header("ascii") + ascii_body)
for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
    body = b"".join(struct.pack(e + "ffd", *v) for v in verts)
    body += b"".join(struct.pack(e + "BiiiBf", 3, *f, 1, 0.5) for f in faces)
    put("ply", fmt + ".ply", ply_header(fmt).encode() + body)
put("ply", "points.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\n"
    "property double y\nproperty double z\nproperty uchar red\nproperty uchar green\n"
    "property uchar blue\nend_header\n0 0 0 255 0 0\n1 2 3 0 255 0\n")

# ---- PTX: one 2x3 scan with colour (one no-return point), one without colour, two scans
def ptx_scan(cols, rows, colour, scale=1.0, shift=(0, 0, 0)):
    s = "%d\n%d\n0 0 1.5\n1 0 0\n0 1 0\n0 0 1\n" % (cols, rows)
    s += "%g 0 0 0\n0 %g 0 0\n0 0 %g 0\n%g %g %g 1\n" % (scale, scale, scale, *shift)
    for c in range(cols):
        for r in range(rows):
            if c == 0 and r == 0:
                s += "0 0 0 0.5" + (" 0 0 0\n" if colour else "\n")
            else:
                s += "%g %g %g 0.%d" % (1 + c, 0.5 * r, 0.25 * (c + r), r + 1)
                s += (" %d %d %d\n" % (10 * c, 20 * r, 30) if colour else "\n")
    return s


put("ptx", "colour.ptx", ptx_scan(2, 3, True))
put("ptx", "no_colour.ptx", ptx_scan(3, 2, False))
put("ptx", "two_scans.ptx", ptx_scan(2, 2, False) + ptx_scan(2, 2, False, 2.0, (1, 2, 3)))

# ---- INI: the sample config, several captures, and a config with every value type
src = os.path.join(os.path.dirname(root), "..", "..", "configs", "two_planes.ini")
with open(src) as f:
    put("config", "two_planes.ini", f.read())
put("config", "captures.ini", "[pipeline]\nworkdir = out\nthreads = 1\n[ingest]\nscan = a.ptx b.ptx\n"
    "[capture]\npanorama = a.exr\nposition = 0 0 1\nrotation = 0 -1 0  1 0 0  0 0 1\n"
    "[capture.north]\npanorama = b.hdr\nposition = 1 2 3\n"
    "[irradiance]\nsamples = 64\n[reflectance]\nmethod = paper\n")
put("config", "mesh.ini", "; comment\n[mesh]\ninput_mesh = m.ply ; inline\nfacet_size = 0.25\n"
    "[render]\n")

# ---- Radiance .hdr: flat (width < 8) and run-length encoded scanlines (width 8)
hdr_head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1\n\n"
flat = b"".join(bytes((128 + i, 64, 32, 129 + i % 2)) for i in range(4 * 2))
put("image", "flat.hdr", hdr_head + b"-Y 2 +X 4\n" + flat)
rle = b""
for row in range(2):
    rle += bytes((2, 2, 0, 8))
    for comp in range(4):
        # one run of 4 equal values, then 4 literal values
        rle += bytes((128 + 4, 100 + comp)) + bytes((4, 10, 20, 30, 40 + row)) \
            if comp < 3 else bytes((128 + 8, 130))
put("image", "rle.hdr", hdr_head + b"-Y 2 +X 8\n" + rle)
put("image", "rgbe.hdr", b"#?RGBE\n\n-Y 1 +X 2\n" + bytes((128, 128, 128, 128, 1, 2, 3, 140)))

# ---- PNG: 8-bit RGB, 8-bit grey+alpha, 16-bit RGBA (tiny, deflate-compressed)
def png(w, h, colour_type, depth, rows):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + \
            struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
    raw = b"".join(b"\0" + r for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, colour_type, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


put("image", "rgb8.png", png(2, 2, 2, 8, [bytes((255, 0, 0, 0, 255, 0)), bytes((0, 0, 255, 128, 128, 128))]))
put("image", "grey_alpha8.png", png(3, 1, 4, 8, [bytes((0, 255, 128, 255, 255, 0))]))
put("image", "rgba16.png", png(1, 2, 6, 16, [struct.pack(">4H", 65535, 0, 1000, 65535),
                                            struct.pack(">4H", 0, 30000, 65535, 0)]))
print("seeds written under", root, file=sys.stderr)
