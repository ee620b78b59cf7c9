# Checks the project's own reference scenes (tools/refscene/scenes/*.json, issue 28 part 5) without
# Blender: every scene parses with scenedesc.py, every part is a closed solid, the camera and the
# scanner stand outside every part at the height above the ground that scenes/README.md states, and
# the README's table lists exactly the JSON files. Runs in CI (ctest refscene_scenes).
# SPDX-License-Identifier: BSD-3-Clause
"""Run: /usr/bin/python3 tools/refscene/test_scenes.py   (needs numpy, not Blender)."""
import glob
import json
import math
import os
import re
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import geom        # noqa: E402
import pattern     # noqa: E402
import scenedesc   # noqa: E402

SCENES = os.path.join(HERE, "scenes")
# Realistic ground-level stations (issue 28): instrument heights 1.5 to 2 m above the ground.
HEIGHT_RANGE = (1.5, 2.0)
ALBEDO_RANGE = (0.15, 0.85)


def box_solid(lo, hi):
    """The 12 outward triangles of an axis-aligned box (vertex k: bit 0 = x, bit 1 = y, bit 2 = z)."""
    verts = [[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = []
    for a, b, c, d in quads:
        tris += [(a, b, c), (a, c, d)]
    return verts, tris


def solid_of(part, solid):
    return box_solid(part["min"], part["max"]) if solid is None else solid


def _ray_hits(o, d, a, b, c):
    """Distance along d (unit) to triangle abc, or None (Moeller-Trumbore, both sides)."""
    e1 = [b[i] - a[i] for i in range(3)]
    e2 = [c[i] - a[i] for i in range(3)]
    p = [d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]]
    det = sum(e1[i] * p[i] for i in range(3))
    if abs(det) < 1e-12:
        return None
    s = [o[i] - a[i] for i in range(3)]
    u = sum(s[i] * p[i] for i in range(3)) / det
    if u < 0 or u > 1:
        return None
    q = [s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]]
    v = sum(d[i] * q[i] for i in range(3)) / det
    if v < 0 or u + v > 1:
        return None
    t = sum(e2[i] * q[i] for i in range(3)) / det
    return t if t > 1e-9 else None


def inside(point, solid):
    """Point in a closed solid: odd number of crossings along a slightly tilted ray."""
    verts, tris = solid
    d = [0.3713, 0.5521, 0.7465]
    n = sum(1 for t in tris if _ray_hits(point, d, verts[t[0]], verts[t[1]], verts[t[2]]) is not None)
    return n % 2 == 1


def height_above_model(point, solids):
    """Distance straight down to the first surface of the model, or None when nothing is below."""
    best = None
    for verts, tris in solids:
        for t in tris:
            h = _ray_hits(point, [0.0, 0.0, -1.0], verts[t[0]], verts[t[1]], verts[t[2]])
            if h is not None and (best is None or h < best):
                best = h
    return best


def readme_table():
    """{scene: {column: cell}} from the first table of scenes/README.md whose first column is `scene`."""
    rows, header = {}, None
    with open(os.path.join(SCENES, "README.md"), encoding="utf-8") as f:
        for line in f:
            if not line.startswith("|"):
                if rows:
                    break
                continue
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if cells[0] == "scene":
                header = cells
            elif header and not set(cells[0]) <= set("- :"):
                rows[cells[0].strip("`")] = dict(zip(header, cells))
    return rows


def numbers(cell):
    return [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?", cell)]


class OwnScenes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # Sky files need not exist in CI: point both prefixes at a folder of empty stand-ins.
        cls.tmp = tempfile.TemporaryDirectory()
        cls.paths = sorted(glob.glob(os.path.join(SCENES, "*.json")))
        for p in cls.paths:
            with open(p, encoding="utf-8") as f:
                text = f.read()
            for name in re.findall(r'"(?:blender-data|shared):([^"]+)"', text):
                full = os.path.join(cls.tmp.name, name)
                os.makedirs(os.path.dirname(full), exist_ok=True)
                open(full, "wb").close()
        cls.saved = {k: os.environ.get(k) for k in ("RS_BLENDER_WORLDS", "RHOSCAN_SHARED")}
        os.environ["RS_BLENDER_WORLDS"] = cls.tmp.name
        os.environ["RHOSCAN_SHARED"] = cls.tmp.name
        cls.scenes = {os.path.basename(p)[:-5]: scenedesc.load_scene(p) for p in cls.paths}
        cls.table = readme_table()

    @classmethod
    def tearDownClass(cls):
        for k, v in cls.saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        cls.tmp.cleanup()

    def test_the_five_kinds_are_there(self):
        for name in ("street_canyon", "walkway_court", "portico", "balcony_awning", "piers"):
            self.assertIn(name, self.scenes)

    def test_readme_lists_exactly_the_scenes(self):
        self.assertEqual(sorted(self.table), sorted(self.scenes))

    def test_parts_are_closed_solids_with_plausible_albedo(self):
        for name, sc in self.scenes.items():
            for i, (part, solid) in enumerate(zip(sc["parts"], sc["solids"])):
                closed, consistent, vol = geom.mesh_check(*solid_of(part, solid))
                self.assertTrue(closed and consistent and vol > 0, "%s part %d" % (name, i))
                for a in part["albedo"]:
                    self.assertTrue(ALBEDO_RANGE[0] <= a <= ALBEDO_RANGE[1], "%s part %d albedo %s" % (name, i, a))

    def test_stations_outside_every_part_at_the_stated_height(self):
        for name, sc in self.scenes.items():
            solids = [solid_of(p, s) for p, s in zip(sc["parts"], sc["solids"])]
            row = self.table[name]
            for key, col in (("cam_pos", "camera"), ("scan_pos", "scanner")):
                pos = sc[key]
                for k, solid in enumerate(solids):
                    self.assertFalse(inside(pos, solid), "%s: %s inside part %d" % (name, col, k))
                h = height_above_model(pos, solids)
                self.assertIsNotNone(h, "%s: nothing below the %s" % (name, col))
                self.assertTrue(HEIGHT_RANGE[0] <= h <= HEIGHT_RANGE[1], "%s: %s %.3f m up" % (name, col, h))
                stated = numbers(row[col])
                self.assertEqual(len(stated), 4, "%s: README %s cell: x, y, z and the height" % (name, col))
                self.assertEqual(stated[:3], [float(x) for x in pos], "%s: README %s position" % (name, col))
                self.assertAlmostEqual(stated[3], h, places=6, msg="%s: README %s height" % (name, col))

    def test_the_geometry_helpers_see_inside_and_below(self):
        box = box_solid([0, 0, 0], [2, 3, 4])
        self.assertTrue(inside([1, 1, 1], box))
        self.assertFalse(inside([1, 1, 5], box))
        self.assertFalse(inside([-0.1, 1, 1], box))
        self.assertAlmostEqual(height_above_model([1, 2, 5.5], [box]), 1.5)
        self.assertIsNone(height_above_model([3, 2, 5.5], [box]))

    def test_realistic_render_settings(self):
        for name, sc in self.scenes.items():
            self.assertEqual(sc["pano_size"], [1024, 512], name)
            self.assertEqual(sc["samples"], 256, name)
            self.assertEqual(sc["rig"], None, name)

    def test_the_canyon_sun_is_low_and_hidden_from_the_camera(self):
        sc = self.scenes["street_canyon"]
        az, el = sc["sun_dir_deg"]
        self.assertTrue(6.0 <= el <= 10.0)
        d = [math.cos(math.radians(el)) * math.cos(math.radians(az)),
             math.cos(math.radians(el)) * math.sin(math.radians(az)), math.sin(math.radians(el))]
        solids = [solid_of(p, s) for p, s in zip(sc["parts"], sc["solids"])]
        for pos in (sc["cam_pos"], sc["scan_pos"]):
            blocked = any(_ray_hits(pos, d, v[t[0]], v[t[1]], v[t[2]]) is not None for v, tris in solids for t in tris)
            self.assertTrue(blocked, "the sun must be hidden from %s" % (pos,))

    def test_the_tile_yard_patterns_give_the_stated_albedos(self):
        """tile_yard.json's walls (issue 22): points worked out by hand from the JSON's pattern
        parameters, in bricks, in tiles, in joints, on stripes, at negative pattern coordinates."""
        sc = self.scenes["tile_yard"]
        by_name = {p["name"]: (p, pat) for p, pat in zip(sc["parts"], sc["patterns"])}
        stated = {
            # bricks 0.3 x 0.1, joints 0.02, half bond, from (-7.5, 6, 0) along x and z
            "north_wall": [([-7.35, 6, 0.05], [0.62, 0.32, 0.20]),    # row 0, brick 0: albedos[0]
                           ([-7.49, 6, 0.05], [0.78, 0.76, 0.70]),    # the head joint: mortar
                           ([-7.30, 6, 0.15], [0.72, 0.48, 0.34]),    # row 1 shifted 0.15: brick 1, (7+3+1) mod 3
                           ([-7.30, 6, 0.11], [0.78, 0.76, 0.70])],   # the bed joint above row 0
            # tiles 0.4, joints 0.03, from (-7, -4, 0) along y and z
            "west_wall": [([-7, -3.8, 0.2], [0.18, 0.28, 0.55]), ([-7, -3.4, 0.2], [0.70, 0.70, 0.64]),
                          ([-7, -3.4, 0.6], [0.35, 0.55, 0.40]), ([-7, -3.59, 0.2], [0.50, 0.50, 0.48])],
            # bricks along -y from (7, 6, 0): y = 6.1 is u = -0.1, brick -1, (-7) mod 2 = 1
            "east_wall": [([7, 6.1, 0.03], [0.30, 0.26, 0.22]), ([7, 5.9, 0.03], [0.55, 0.50, 0.42])],
            # stripes 0.25 wide from x = -7
            "south_wall": [([-6.9, -4, 1], [0.20, 0.20, 0.22]), ([-6.7, -4, 1], [0.66, 0.60, 0.50]),
                           ([-6.4, -4, 1], [0.20, 0.20, 0.22])],
        }
        for name, points in stated.items():
            part, pat = by_name[name]
            self.assertIsNotNone(pat, name)
            got = pattern.albedo_at(pat, [pt for pt, _ in points])
            for (pt, want), g in zip(points, got):
                self.assertEqual([round(x, 6) for x in g], want, "%s at %s" % (name, pt))
            for rgb in pat["palette"]:
                for a in rgb:
                    self.assertTrue(0.15 <= a <= 0.8, "%s: albedo %s outside 0.15 to 0.8" % (name, rgb))
            self.assertEqual(part["albedo"], pattern.mean_albedo(pat), name)
        # stripes: the mean is the two albedos' mean; the wall's pattern spans 0.15 to 0.8
        self.assertEqual([round(x, 6) for x in by_name["south_wall"][0]["albedo"]], [0.43, 0.4, 0.36])
        # every wall carries a pattern, the pergola and canopy are plain
        for name in ("ground", "north_wall", "west_wall", "east_wall", "south_wall"):
            self.assertIsNotNone(by_name[name][1], name)
        self.assertEqual(sum(1 for n in by_name if n.startswith("slat_")), 16)
        self.assertIsNone(by_name["canopy"][1])

    def test_the_pattern_mean_is_the_area_mean(self):
        """mean_albedo against a fine sampling of one period (5 n bricks each way)."""
        pat = pattern.check({"type": "bricks", "plane": "xz", "size": [0.3, 0.1], "mortar_m": 0.02,
                             "albedos": [[0.2, 0.2, 0.2], [0.6, 0.5, 0.4], [0.3, 0.7, 0.2]],
                             "mortar": [0.8, 0.8, 0.8]}, "p", geom.PLANES)
        n = 200
        u = (np.arange(15 * n) + 0.5) * (15 * 0.3) / (15 * n)
        v = (np.arange(15 * n // 3) + 0.5) * (15 * 0.1) / (15 * n // 3)
        uu, vv = np.meshgrid(u, v)
        pts = np.stack([uu.ravel(), np.zeros(uu.size), vv.ravel()], axis=1)
        np.testing.assert_allclose(pattern.albedo_at(pat, pts).mean(axis=0), pattern.mean_albedo(pat), atol=2e-3)

    def test_bad_patterns_are_named(self):
        base = {"type": "tiles", "plane": "xz", "size": [0.4, 0.4], "mortar_m": 0.02,
                "albedos": [[0.2, 0.2, 0.2], [0.6, 0.5, 0.4]], "mortar": [0.8, 0.8, 0.8]}
        for key, value, words in (("type", "checks", "type"), ("size", [0.4], "size"), ("mortar_m", 0.5, "mortar_m"),
                                  ("albedos", [[0.2, 0.2, 0.2]], "albedos"), ("mortar", [2, 0, 0], "mortar"),
                                  ("plane", "qq", "plane")):
            bad = dict(base)
            bad[key] = value
            with self.assertRaises(pattern.PatternError) as cm:
                pattern.check(bad, "parts[3].pattern", geom.PLANES)
            self.assertIn("parts[3].pattern." + words, str(cm.exception))
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "s.json")
            open(os.path.join(tmp, "sky.exr"), "wb").close()
            with open(path, "w") as f:
                f.write('{"parts":[{"min":[0,0,0],"max":[1,1,1],"albedo":[0.5,0.5,0.5],"pattern":%s}],'
                        '"env":{"file":"sky.exr"},"camera":{"position":[0,-5,1]},'
                        '"scanner":{"position":[0,-5,1],"grid":[10,10],"elevation_deg":[-10,10]}}'
                        % json.dumps(base))
            with self.assertRaises(scenedesc.SceneError) as cm:
                scenedesc.load_scene(path)
            self.assertIn("both albedo and pattern", str(cm.exception))


if __name__ == "__main__":
    unittest.main(verbosity=1)
