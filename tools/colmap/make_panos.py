#!/usr/bin/python3
# make_panos: textured equirectangular panoramas of sample_data/courtyard's boxes from several known
# poses, the input of run_colmap.sh's test model (the Cycles panoramas' plain albedo has too few SIFT features).
"""Renders the boxes of a scene.json (rhoscan's reference-scene format) with a procedural
value-noise texture on every face and a cloudy sky at infinity, by ray casting in numpy, as linear
EXR panoramas in the convention of docs/DESIGN.md, section Frames (u = (c + 0.5) / W,
azimuth = pi (1 - 2u) = atan2(y, x), polar angle = pi v from +Z, local frame; world direction =
R local direction).

Writes OUTDIR/<name>.exr for each pose and OUTDIR/poses.txt:
    NAME  X Y Z  R00 R01 ... R22      (centre in the world frame, m; rotation local -> world, row-major)

Usage: make_panos.py SCENE.json OUTDIR [--width 2048]
Deterministic: the same arguments give byte-identical panoramas.
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import OpenImageIO as oiio

# The poses: inside the courtyard, at different heights and headings, one slightly tilted so that
# the rotation is not a pure yaw. Four positions: three serve as control points, one is held out.
POSES = [
    ("pano0", (1.0, -2.0, 1.6), 90.0, 0.0),
    ("pano1", (-2.0, 0.5, 1.5), 0.0, 0.0),
    ("pano2", (2.0, 2.0, 1.8), 200.0, 3.0),
    ("pano3", (-1.0, -3.5, 1.7), 315.0, 0.0),
]
SUN = np.array([0.4, -0.5, 0.77]) / np.linalg.norm([0.4, -0.5, 0.77])


def rotation(yaw_deg, roll_deg):
    """Local -> world: Rz(yaw) Rx(roll)."""
    a, b = math.radians(yaw_deg), math.radians(roll_deg)
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    return rz @ rx


def hash3(i, j, k):
    """A value in [0, 1) per integer lattice point (integer hash: no float-sin artefacts)."""
    h = (i.astype(np.int64) * 73856093) ^ (j.astype(np.int64) * 19349663) ^ (k.astype(np.int64) * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return (h & 0xFFFF).astype(np.float64) / 65536.0


def value_noise(p, cell):
    """Trilinear value noise of the points p (n x 3) on a lattice of the given cell size."""
    q = p / cell
    f = np.floor(q)
    t = q - f
    t = t * t * (3 - 2 * t)
    i, j, k = f[:, 0], f[:, 1], f[:, 2]
    out = np.zeros(len(p))
    for di in (0, 1):
        for dj in (0, 1):
            for dk in (0, 1):
                w = (t[:, 0] if di else 1 - t[:, 0]) * (t[:, 1] if dj else 1 - t[:, 1]) * (t[:, 2] if dk else 1 - t[:, 2])
                out += w * hash3(i + di, j + dj, k + dk)
    return out


def texture(p):
    """Blobs at several scales (0.6 m down to 4 cm), contrast-stretched: SIFT finds them at 2 to 10 m."""
    n = 0.45 * value_noise(p, 0.6) + 0.3 * value_noise(p, 0.2) + 0.25 * value_noise(p, 0.07)
    return np.clip(0.5 + 2.2 * (n - 0.5), 0.08, 1.0)


def sky(d):
    """Blue gradient with clouds (noise on the direction, i.e. at infinity); ground-level haze below."""
    up = np.clip(d[:, 2], -1, 1)
    base = np.stack([0.35 + 0.25 * (1 - up), 0.5 + 0.2 * (1 - up), 0.9 + 0.0 * up], axis=1)
    c = value_noise(d * 6.0, 1.0) * 0.6 + value_noise(d * 15.0, 1.0) * 0.4
    cloud = np.clip((c - 0.45) * 3, 0, 1)[:, None]
    col = base * (1 - cloud) + cloud * 1.2
    return col * 2.0


def render(parts, centre, rot, width):
    h = width // 2
    c = (np.arange(width) + 0.5) / width
    r = (np.arange(h) + 0.5) / h
    u, v = np.meshgrid(c, r)
    phi, theta = math.pi * (1 - 2 * u.ravel()), math.pi * v.ravel()
    d_local = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
    d = d_local @ rot.T
    o = np.asarray(centre, dtype=np.float64)
    best_t = np.full(len(d), np.inf)
    best_part = np.full(len(d), -1)
    best_axis = np.zeros(len(d), dtype=np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        for pi_, part in enumerate(parts):
            lo, hi = np.array(part["min"], float), np.array(part["max"], float)
            t1, t2 = (lo - o) * inv, (hi - o) * inv
            tmin3, tmax3 = np.minimum(t1, t2), np.maximum(t1, t2)
            tnear, tfar = np.nanmax(tmin3, axis=1), np.nanmin(tmax3, axis=1)
            hit = (tnear <= tfar) & (tnear > 1e-6) & (tnear < best_t)
            best_t[hit] = tnear[hit]
            best_part[hit] = pi_
            best_axis[hit] = np.nanargmax(tmin3[hit], axis=1)
    img = sky(d)
    m = best_part >= 0
    p = o + d[m] * best_t[m][:, None]
    normal = np.zeros((m.sum(), 3))
    normal[np.arange(m.sum()), best_axis[m]] = -np.sign(d[m][np.arange(m.sum()), best_axis[m]])
    albedo = np.array([parts[k]["albedo"] for k in range(len(parts))])[best_part[m]]
    shade = 0.35 + 1.6 * np.clip(normal @ SUN, 0, None)
    img[m] = albedo * texture(p)[:, None] * shade[:, None]
    return img.reshape(h, width, 3).astype(np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("outdir")
    ap.add_argument("--width", type=int, default=2048)
    a = ap.parse_args()
    with open(a.scene) as f:
        parts = json.load(f)["parts"]
    os.makedirs(a.outdir, exist_ok=True)
    lines = ["# make_panos.py: NAME X Y Z (m, world) R00..R22 (local -> world, row-major)"]
    for name, centre, yaw, roll in POSES:
        rot = rotation(yaw, roll)
        img = render(parts, centre, rot, a.width)
        out = oiio.ImageOutput.create(os.path.join(a.outdir, name + ".exr"))
        spec = oiio.ImageSpec(a.width, a.width // 2, 3, oiio.FLOAT)
        spec.attribute("compression", "zip")
        out.open(os.path.join(a.outdir, name + ".exr"), spec)
        out.write_image(img)
        out.close()
        lines.append("%s %.17g %.17g %.17g %s" % (name, *centre, " ".join("%.17g" % x for x in rot.ravel())))
    with open(os.path.join(a.outdir, "poses.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
