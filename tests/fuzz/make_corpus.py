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
# ---- pairs files: column row X Y Z, comments, commas, CR LF
put("pairs", "pairs.txt", "# column row X Y Z\n10 20 1 2 3\n30.5 40 -1 2.5 3\n100 5 4 4 4  # a comment\n"
    "7 8 9 10 11\n")
put("pairs", "commas.txt", "1,2,3,4,5\r\n6,7,8,9,10\r\n11 12 13 14 15\r\n16\t17\t18\t19\t20\r\n")

# ---- response curves: one column, three columns with commas
put("response", "gamma.txt", "# gamma 2.2\n" + "".join("%.9g\n" % ((max(i, 0.25) / 255) ** 2.2) for i in range(256)))
put("response", "rgb.txt", "".join("%g, %g, %g\n" % ((i + 1) / 256, (i + 1) / 200, (i + 1) / 300) for i in range(256)))

# ---- COLMAP text: cameras, images, points3D, views, control points, NUL-separated
cameras = "# Camera list\n1 PINHOLE 512 512 256 256 256 256\n2 SIMPLE_RADIAL 640 480 300 320 240 0.01\n"
images = ("# Image list\n1 1 0 0 0 0 0 0 1 a.png\n10 20 1 30 40 -1\n"
          "2 0.7071067811865476 0 0.7071067811865476 0 1 0 0 2 b.png\n50 60 2 70 80 3\n")
points = "# 3D points\n1 0 0 5 255 0 0 0.5 1 0\n2 1 0 5 0 255 0 0.25 1 1 2 0\n3 0 1 5 0 0 255 0.1 2 1\n"
views = "a.png pano0 1 0 0 0 1 0 0 0 1\nb.png pano0 0 0 1 0 1 0 -1 0 0 0 0 0.1\n"
control = "image a.png 0 0 0\nimage b.png 1 0 0\npoint 3 0 1 5\npanorama pano0 0.5 0 0\n"
put("colmap", "model", "\0".join([cameras, images, points, views, control]))

# ---- PCD: ascii with intensity and packed rgb, binary, a NaN (no return) point
pcd_head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity rgb\nSIZE 4 4 4 4 4\nTYPE F F F F U\n"
            "COUNT 1 1 1 1 1\nWIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n")
pcd_pts = [(0, 0, 0, 0.5, 0xff0000), (1, 0, 0.1, 0.25, 0x00ff00), (0, 1, 0.2, 1, 0x0000ff), (float("nan"), 0, 0, 0, 0)]
put("pcd", "ascii.pcd", pcd_head % (4, 4, "ascii") + "".join("%g %g %g %g %d\n" % p for p in pcd_pts))
put("pcd", "binary.pcd", (pcd_head % (4, 4, "binary")).encode() +
    b"".join(struct.pack("<ffffI", *p) for p in pcd_pts))
put("pcd", "double.pcd", "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
    "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n500000.25 4000000.5 12\n500001 4000001 13\n")

# ---- XYZ text: the first byte picks the column map (fuzz_xyz.c): x y z / + intensity / + r g b
put("xyz", "plain.xyz", b"\x00" + b"# x y z\n0 0 0\n1 0 0.5\n0,1,0.25\n1;1;1\n")
put("xyz", "intensity.xyz", b"\x01" + b"X Y Z I\n0 0 0 0.5\n1 0 0 0.25\n// comment\n0 1 0 1\n")
put("xyz", "colour.xyz", b"\x02" + b"3\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n")


# ---- rig values (fuzz_rig.c): a tag byte per value, 200 = 8 raw bytes of a double follow
def rig_value(v):
    return bytes([200]) + struct.pack("<d", v)


def rig_camera(model, w, h, k, dist, r, t):
    b = bytes([model, 1]) + rig_value(w) + bytes([1]) + rig_value(h) + bytes([1])
    b += b"".join(rig_value(x) for x in k) + bytes([len(dist)]) + b"".join(rig_value(x) for x in dist)
    b += bytes([1]) + b"".join(rig_value(x) for x in r) + bytes([1]) + b"".join(rig_value(x) for x in t)
    return b


ident = (1, 0, 0, 0, 1, 0, 0, 0, 1)
put("rig", "pinhole", bytes([0, 3]) + rig_camera(0, 640, 512, (300, 0, 319.5, 0, 300, 255.5, 0, 0, 1),
                                                 (-0.08, 0.01, 0.0005, -0.0003, 0), ident, (0.04, 0, 0.05)))
put("rig", "two", bytes([1, 4]) + rig_camera(0, 64, 32, (40, 0, 31.5, 0, 40, 15.5, 0, 0, 1), (0, 0, 0, 0, 0),
                                             (0, 0, 1, -1, 0, 0, 0, -1, 0), (0, 0, 0)) +
    rig_camera(1, 640, 640, (200, 0, 319.5, 0, 200, 319.5, 0, 0, 1), (0.02, -0.004, 0.0005, 0), ident, (0, 0, 0.05)))

# ---- LAS (fuzz_las.c: the first byte picks the class filter): 1.2 format 3 with 2 padding bytes,
# 1.4 format 8 with extra bytes and the 64-bit count, 1.3 format 1
def las(minor, fmt, reclen, pts, pad=0, nvlr=0, vlrs=b""):
    hsize = {0: 227, 1: 227, 2: 227, 3: 235, 4: 375}[minor]
    h = bytearray(hsize)
    h[0:4] = b"LASF"
    h[24], h[25] = 1, minor
    struct.pack_into("<HIIBHI", h, 94, hsize, hsize + len(vlrs) + pad, nvlr, fmt, reclen,
                     0 if fmt >= 6 else len(pts))
    struct.pack_into("<3d3d", h, 131, 0.01, 0.01, 0.01, 1000.0, 2000.0, 0.0)
    struct.pack_into("<6d", h, 179, 1001, 1000, 2001, 2000, 1, 0)
    if minor >= 4:
        struct.pack_into("<Q", h, 247, len(pts))
    body = b""
    for i, (x, y, z, cls) in enumerate(pts):
        rec = bytearray(reclen)
        struct.pack_into("<iiiH", rec, 0, x, y, z, 100 * i)
        if fmt >= 6:
            rec[16] = cls
        else:
            rec[15] = cls
        if fmt in (2, 3, 5, 7, 8, 10):
            at = {2: 20, 3: 28, 5: 28, 7: 30, 8: 30, 10: 30}[fmt]
            struct.pack_into("<HHH", rec, at, 60000, 300 * i, 255)
        body += bytes(rec)
    return bytes(h) + vlrs + bytes(pad) + body


las_pts = [(0, 0, 0, 2), (100, 0, 50, 6), (0, 100, 100, 5), (100, 100, 20, 2)]
vlr = struct.pack("<H16sHH32s", 0, b"LASF_Projection", 2112, 4, b"seed") + b"abcd"
put("las", "v12_f3_pad.las", b"\x00" + las(2, 3, 34, las_pts, pad=2))
put("las", "v14_f8_extra.las", b"\x01" + las(4, 8, 38 + 5, las_pts, nvlr=1, vlrs=vlr))
put("las", "v13_f1.las", b"\x00" + las(3, 1, 28, las_pts))
print("seeds written under", root, file=sys.stderr)
