# Tests of the reference-scene generator's Blender-free logic: polygon triangulation and extrusion,
# mesh import, scene validation messages, the lens model and the rig file. Runs in CI (ctest refscene_logic).
# SPDX-License-Identifier: BSD-3-Clause
"""Run: /usr/bin/python3 tools/refscene/test_refscene.py   (needs numpy, not Blender)."""
import json
import math
import os
import re
import struct
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import geom        # noqa: E402
import rigsim      # noqa: E402
import scenedesc   # noqa: E402

EXAMPLES = os.path.join(HERE, "examples")


def arch_wall(n_arches=3, segments=10):
    """A wall 10 x 4 with arched openings down to the ground (in the outline) and windows (holes)."""
    pts = [(0.0, 0.0)]
    holes = []
    for k in range(n_arches):
        x0 = 1.0 + 3.0 * k
        pts.append((x0, 0.0))
        pts += [(x0 + 0.75 - 0.75 * math.cos(math.pi * i / segments), 2.0 + 0.75 * math.sin(math.pi * i / segments))
                for i in range(segments + 1)]
        pts.append((x0 + 1.5, 0.0))
        holes.append([(x0 + 0.5, 3.2), (x0 + 1.0, 3.2), (x0 + 1.0, 3.7), (x0 + 0.5, 3.7)])
    pts += [(10.0, 0.0), (10.0, 4.0), (0.0, 4.0)]
    return pts, holes


class Triangulation(unittest.TestCase):
    def check_cover(self, outline, holes):
        tris, pts = geom.triangulate_polygon(outline, holes)
        n = len(outline) + sum(len(h) for h in holes)
        # Ear clipping of a polygon with n vertices and h holes gives n + 2 h - 2 triangles.
        self.assertEqual(len(tris), n + 2 * len(holes) - 2)
        areas = [geom._cross(pts[i], pts[j], pts[k]) * 0.5 for (i, j, k) in tris]
        self.assertGreaterEqual(min(areas), -1e-12, "a triangle is wound clockwise")
        want = abs(geom.signed_area(outline)) - sum(abs(geom.signed_area(h)) for h in holes)
        self.assertAlmostEqual(sum(areas), want, places=9)
        # No two triangles overlap: the summed area equals the polygon's, and every triangle's
        # centroid lies inside the outline and outside every hole.
        for (i, j, k) in tris:
            c = ((pts[i][0] + pts[j][0] + pts[k][0]) / 3, (pts[i][1] + pts[j][1] + pts[k][1]) / 3)
            if geom._cross(pts[i], pts[j], pts[k]) > 1e-12:
                self.assertTrue(geom._point_in_loop(c, outline))
                self.assertFalse(any(geom._point_in_loop(c, h) for h in holes))
        return tris

    def test_square_with_holes_either_winding(self):
        outline = [(0, 0), (4, 0), (4, 3), (0, 3)]
        holes = [[(1, 1), (1, 2), (1.5, 2), (1.5, 1)], [(2.5, 1), (3.2, 1), (3.2, 2.2), (2.5, 2.2)]]
        self.check_cover(outline, holes)
        self.check_cover(outline[::-1], [h[::-1] for h in holes])

    def test_arches_and_windows(self):
        self.check_cover(*arch_wall())

    def test_collinear_points_and_holes_in_line(self):
        outline = [(0, 0), (1, 0), (2, 0), (3, 0), (3, 1), (3, 2), (0, 2), (0, 1)]
        holes = [[(0.5, 0.5), (1.0, 0.5), (1.0, 1.5), (0.5, 1.5)], [(2.0, 0.5), (2.5, 0.5), (2.5, 1.5), (2.0, 1.5)]]
        self.check_cover(outline, holes)

    def test_window_grid_and_random_stars(self):
        # Holes in rows and columns share their largest x: the bridges must still not cross.
        grid = [[(1 + 3 * i, 1 + 3 * j), (2 + 3 * i, 1 + 3 * j), (2 + 3 * i, 2 + 3 * j), (1 + 3 * i, 2 + 3 * j)]
                for i in range(3) for j in range(3)]
        self.check_cover([(0, 0), (10, 0), (10, 10), (0, 10)], grid)

        def circle(cx, cy, r, n):
            return [(cx + r * math.cos(2 * math.pi * k / n), cy + r * math.sin(2 * math.pi * k / n)) for k in range(n)]
        rng = np.random.default_rng(7)
        for _ in range(150):
            n = int(rng.integers(3, 41))
            radius = 1 + 2 * rng.random(n)     # star-shaped about the origin: simple, often very concave
            star = [(radius[k] * math.cos(2 * math.pi * k / n), radius[k] * math.sin(2 * math.pi * k / n))
                    for k in range(n)]
            self.check_cover(star, [])
            self.check_cover(star, [circle(0.4, 0, 0.3, 7), circle(-0.4, 0.1, 0.3, 5)])

    def test_bad_polygons(self):
        bowtie = [(0, 0), (2, 2), (2, 0), (0, 3)]
        with self.assertRaisesRegex(geom.GeomError, "touch or cross"):
            geom.triangulate_polygon(bowtie)
        square = [(0, 0), (2, 0), (2, 2), (0, 2)]
        with self.assertRaisesRegex(geom.GeomError, "outside the outline"):
            geom.triangulate_polygon(square, [[(3, 3), (4, 3), (4, 4)]])
        with self.assertRaisesRegex(geom.GeomError, "touch or cross"):
            geom.triangulate_polygon(square, [[(0, 0.5), (1, 0.5), (1, 1)]])
        with self.assertRaisesRegex(geom.GeomError, "no area"):
            geom.triangulate_polygon([(0, 0), (1, 1), (2, 2)])


class Extrusion(unittest.TestCase):
    def check_solid(self, outline, holes, origin, u, v, depth):
        verts, tris, area = geom.extrude(outline, holes, origin, u, v, depth)
        closed, consistent, vol = geom.mesh_check(verts, tris)
        self.assertTrue(closed and consistent, "not watertight")
        self.assertAlmostEqual(vol, area * abs(depth), places=9)     # positive: faces point outward
        return verts, tris

    def test_named_planes_and_both_directions(self):
        outline, holes = arch_wall()
        for plane in geom.PLANES:
            for depth in (0.4, -0.4):
                self.check_solid(outline, holes, (1, 2, 3), *geom.PLANES[plane], depth)

    def test_tilted_plane(self):
        u = (math.cos(0.3), math.sin(0.3), 0.0)
        v = (-math.sin(0.3) * 0.6, math.cos(0.3) * 0.6, 0.8)
        verts, _ = self.check_solid([(0, 0), (2, 0), (1, 1.5)], [], (0, 0, 0), u, v, 0.25)
        n = geom._cross3(geom._unit(u), geom._unit(v))
        far = max(sum(p[k] * n[k] for k in range(3)) for p in verts)
        self.assertAlmostEqual(far, 0.25, places=12)

    def test_wall_normals_point_away_from_the_solid(self):
        verts, tris = self.check_solid([(0, 0), (1, 0), (1, 1), (0, 1)], [], (0, 0, 0), (1, 0, 0), (0, 1, 0), 1.0)
        for (i, j, k) in tris:
            a, b, c = verts[i], verts[j], verts[k]
            nrm = geom._cross3(geom._sub(b, a), geom._sub(c, a))
            centre = [(a[m] + b[m] + c[m]) / 3 - 0.5 for m in range(3)]
            self.assertGreater(sum(nrm[m] * centre[m] for m in range(3)), 0)


class MeshFiles(unittest.TestCase):
    def test_examples_are_closed(self):
        for name in ("house.obj", "obelisk.ply"):
            path = os.path.join(EXAMPLES, name)
            verts, polys = (geom.read_obj if name.endswith("obj") else geom.read_ply)(path)
            tris, dropped = geom.mesh_triangles(verts, polys)
            closed, consistent, v = geom.mesh_check(verts, tris)
            self.assertTrue(closed and consistent)
            self.assertEqual(dropped, 0)
            if name == "house.obj":
                self.assertAlmostEqual(v, 39.0, places=9)   # 4 x 3 x 2.5 plus the roof prism 0.5 x 3 x 1.5 x 4
            else:
                # Frustum 5 m high from 0.8 to 0.5 m squares, plus a pyramid 0.6 m high on 0.5 m.
                frustum = 5 / 3 * (0.64 + 0.25 + math.sqrt(0.64 * 0.25))
                self.assertAlmostEqual(v, frustum + 0.25 * 0.6 / 3, places=5)

    def test_binary_ply_reads_like_ascii(self):
        verts, polys = geom.read_ply(os.path.join(EXAMPLES, "obelisk.ply"))
        with tempfile.TemporaryDirectory() as d:
            for order, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
                path = os.path.join(d, "b.ply")
                head = ("ply\nformat %s 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
                        "property double z\nproperty uchar red\nelement face %d\n"
                        "property list uchar int vertex_indices\nend_header\n" % (fmt, len(verts), len(polys)))
                body = b"".join(struct.pack(order + "dddB", *v, 7) for v in verts)
                body += b"".join(struct.pack(order + "B%di" % len(p), len(p), *p) for p in polys)
                with open(path, "wb") as f:
                    f.write(head.encode() + body)
                self.assertEqual(geom.read_ply(path), (verts, polys))


def write_scene(d, scene, name="scene.json"):
    path = os.path.join(d, name)
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def base_scene():
    return {"parts": [{"name": "ground", "min": [-5, -5, -0.1], "max": [5, 5, 0], "albedo": [0.3, 0.3, 0.3]}],
            "env": {"file": "sky.exr"}, "camera": {"position": [0, 0, 1.6]},
            "scanner": {"position": [0, 0, 1.8], "grid": [36, 18], "elevation_deg": [-80, 80]}}


class Validation(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.d = self.tmp.name
        open(os.path.join(self.d, "sky.exr"), "wb").close()

    def tearDown(self):
        self.tmp.cleanup()

    def expect(self, scene, *parts):
        path = write_scene(self.d, scene)
        with self.assertRaises(scenedesc.SceneError) as cm:
            scenedesc.load_scene(path)
        msg = str(cm.exception)
        self.assertTrue(msg.startswith(path + ": "), msg)
        for p in parts:
            self.assertIn(p, msg)

    def test_examples_load(self):
        os.environ["RS_BLENDER_WORLDS"] = self.d
        for sky in ("courtyard.exr", "sunset.exr"):
            open(os.path.join(self.d, sky), "wb").close()
        try:
            for name in ("arcade.json", "imported.json", "rig.json"):
                sc = scenedesc.load_scene(os.path.join(EXAMPLES, name))
                for kind, solid in zip(sc["kinds"], sc["solids"]):
                    if solid is not None:
                        closed, consistent, vol = geom.mesh_check(*solid)
                        self.assertTrue(closed and consistent and vol > 0, name)
            self.assertEqual(len(sc["rig"]["cameras"]), 6)
        finally:
            del os.environ["RS_BLENDER_WORLDS"]

    def test_part_errors(self):
        sc = base_scene()
        sc["parts"].append({"name": "x", "albedo": [0.5, 0.5, 0.5]})
        self.expect(sc, "parts[1]", "exactly one of")
        sc["parts"][1] = {"outline": [[0, 0], [1, 1], [1, 0], [0, 1.5]], "depth": 1, "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1]", "touch or cross")
        sc["parts"][1] = {"outline": [[0, 0], [1, 0], [1, 1]], "depth": 0, "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].depth = 0", "thickness")
        sc["parts"][1] = {"outline": [[0, 0], [1, 0], [1, 1]], "depth": 1, "plane": "xq", "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].plane = \"xq\"", "expected one of")
        sc["parts"][1] = {"outline": [[0, 0], [1, 0], [1, 1]], "depth": 1, "plane": {"u": [1, 0, 0], "v": [1, 1, 0]},
                          "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].plane", "perpendicular")
        sc["parts"][1] = {"outline": [[0, 0], [1, 0]], "depth": 1, "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].outline = [[0, 0], [1, 0]]", "at least 3")
        sc["parts"][1] = {"mesh": "none.obj", "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].mesh = \"none.obj\"", "no such file")
        sc["parts"][1] = {"mesh": "sky.exr", "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].mesh = \"sky.exr\"", ".ply or .obj")
        with open(os.path.join(self.d, "bad.obj"), "w") as f:
            f.write("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
        sc["parts"][1] = {"mesh": "bad.obj", "albedo": [0.5, 0.5, 0.5]}
        self.expect(sc, "parts[1].mesh = \"bad.obj\"", "expected at least 3 indices of the 2 vertices")
        sc["parts"][1] = {"min": [0, 0, 0], "max": [1, 1, 1], "albedo": [0.5, 1.5, 0.5]}
        self.expect(sc, "parts[1].albedo", "0..1")

    def test_rig_errors(self):
        sc = base_scene()
        sc["rig"] = {"position": [0, 0, 1.6]}
        self.expect(sc, "rig", "exactly one of \"cameras\"")
        cam = {"image_size": [64, 48], "K": [50, 50, 31.5, 23.5], "look_deg": [0, 0, 0]}
        sc["rig"] = {"position": [0, 0, 1.6], "cameras": [dict(cam, K=[0, 50, 31.5, 23.5])]}
        self.expect(sc, "rig.cameras[0].K", "fx, fy > 0")
        sc["rig"]["cameras"] = [dict(cam, R_rig_cam=[1, 0, 0, 0, 1, 0, 0, 0, 1])]
        self.expect(sc, "rig.cameras[0]", "exactly one of R_rig_cam")
        c = dict(cam)
        del c["look_deg"]
        c["R_rig_cam"] = [1, 0, 0, 0, 1, 0, 0, 0, -1]
        sc["rig"]["cameras"] = [c]
        self.expect(sc, "rig.cameras[0].R_rig_cam", "det +1")
        sc["rig"]["cameras"] = [dict(cam, name="a"), dict(cam, name="a")]
        self.expect(sc, "rig.cameras", "distinct names")
        sc["rig"]["cameras"] = [dict(cam, dist=[-500.0, 0, 0, 0, 0])]
        self.expect(sc, "rig camera 0", "folds back")
        sc["rig"] = {"position": [0, 0, 1.6], "ladybug5": {"image_size": [1, 100]}}
        self.expect(sc, "rig.ladybug5.image_size")


class Lens(unittest.TestCase):
    DIST = [-0.12, 0.02, 0.0005, -0.0003, 0.001]

    def test_undistort_inverts_distort(self):
        field = rigsim.usable_field(self.DIST)
        a, b = np.meshgrid(np.linspace(-1.3, 1.3, 81), np.linspace(-1.3, 1.3, 81))
        inside = np.hypot(a, b) < field
        xd, yd = rigsim.distort(a, b, self.DIST)
        ua, ub, ok = rigsim.undistort(xd, yd, self.DIST)
        self.assertTrue(ok[inside].all())
        self.assertLess(np.abs(ua - a)[inside].max(), 1e-9)
        self.assertLess(np.abs(ub - b)[inside].max(), 1e-9)

    def test_usable_field_stops_where_the_model_folds(self):
        k = [-0.3, 0.0, 0.0, 0.0, 0.0]          # r (1 - 0.3 r^2) peaks at r = 1/sqrt(0.9)
        f = rigsim.usable_field(k)
        self.assertLess(f, 1 / math.sqrt(0.9))
        self.assertGreater(f, 0.9 * math.sqrt((1 - 0.05) / 0.9))

    def test_remap_reads_the_ideal_render_where_the_ray_points(self):
        # An ideal image whose value is a linear function of the ray (a, b): bilinear sampling
        # reproduces it exactly, so every frame pixel must hold its own ray's value.
        cam = {"name": "c", "size": [40, 30], "K": [30.0, 31.0, 20.5, 14.0], "dist": self.DIST}
        a, b, ok = rigsim.frame_rays(cam)
        f, (wi, hi) = rigsim.ideal_view(cam, a, b, ok)
        y, x = np.mgrid[0:hi, 0:wi].astype(float)
        ra, rb = (x - (wi - 1) / 2) / f, (y - (hi - 1) / 2) / f
        ideal = np.stack([3 * ra + 1, -2 * rb + 1, ra + rb], axis=-1)
        frame = rigsim.remap(ideal, f, a, b, ok)
        # The pixel's ray, independently: distort(a, b) must land on the pixel.
        xd, yd = rigsim.distort(a, b, cam["dist"])
        gy, gx = np.mgrid[0:30, 0:40]
        self.assertLess(np.abs(xd * 30.0 + 20.5 - gx).max(), 1e-7)
        self.assertLess(np.abs(yd * 31.0 + 14.0 - gy).max(), 1e-7)
        self.assertTrue(ok.all())
        self.assertLess(np.abs(frame[..., 0] - (3 * a + 1)).max(), 1e-9)
        self.assertLess(np.abs(frame[..., 1] - (-2 * b + 1)).max(), 1e-9)


class Rig(unittest.TestCase):
    def test_look_rotation(self):
        # The camera looking up, roll 0, is the up camera of tests/stages/test_calib.c.
        r = np.array(rigsim.look_rotation(0, 90, 0)).reshape(3, 3)
        np.testing.assert_allclose(r[:, 0], [0, -1, 0], atol=1e-12)
        np.testing.assert_allclose(r[:, 1], [1, 0, 0], atol=1e-12)
        np.testing.assert_allclose(r[:, 2], [0, 0, 1], atol=1e-12)
        for az in (0, 72, 144, 216, 288):
            r = np.array(rigsim.look_rotation(az, 0, 0)).reshape(3, 3)
            c, s = math.cos(math.radians(az)), math.sin(math.radians(az))
            np.testing.assert_allclose(r[:, 2], [c, s, 0], atol=1e-12)     # forward
            np.testing.assert_allclose(r[:, 0], [s, -c, 0], atol=1e-12)    # right
            np.testing.assert_allclose(r[:, 1], [0, 0, -1], atol=1e-12)    # down
        r = np.array(rigsim.look_rotation(30, 20, 15)).reshape(3, 3)
        self.assertTrue(rigsim.is_rotation(r.ravel()))
        el = math.radians(20)
        np.testing.assert_allclose(r[:, 2], [math.cos(el) * math.cos(math.radians(30)),
                                             math.cos(el) * math.sin(math.radians(30)), math.sin(el)], atol=1e-12)

    def test_preset_covers_the_sphere_above_the_lowest_rows(self):
        cams = rigsim.ladybug5([128, 160], 65.0, rigsim.LADYBUG5["dist"], 0.04)
        # Directions from the zenith down to 50 degrees below the horizon are each seen by a camera.
        rng = np.random.default_rng(1)
        d = rng.normal(size=(4000, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        d = d[d[:, 2] > math.sin(math.radians(-50))]
        seen = np.zeros(len(d), bool)
        for c in cams:
            w, h = c["size"]
            fx, fy, cx, cy = c["K"]
            dc = d @ np.array(c["R"]).reshape(3, 3)       # rig -> camera: R^T d
            front = dc[:, 2] > 1e-6
            a, b = dc[:, 0] / np.where(front, dc[:, 2], 1), dc[:, 1] / np.where(front, dc[:, 2], 1)
            xd, yd = rigsim.distort(a, b, c["dist"])
            px, py = fx * xd + cx, fy * yd + cy
            seen |= front & (np.hypot(a, b) < rigsim.usable_field(c["dist"])) & \
                (px >= 0) & (px <= w - 1) & (py >= 0) & (py <= h - 1)
        self.assertTrue(seen.all(), "%d directions unseen" % (~seen).sum())

    def test_rig_yaml_layout(self):
        cams = rigsim.ladybug5([512, 640], 260.0, rigsim.LADYBUG5["dist"], 0.04)
        text = rigsim.rig_yaml(cams)
        lines = text.splitlines()
        self.assertEqual(lines[:4], ["%YAML:1.0", "---", "camera_count: 6", "cameras:"])
        self.assertEqual(text.count("   - name: cam"), 6)
        self.assertIsNone(re.search(r"-0\.0(,| \])", text), "negative zero")
        mats = re.findall(r"     (\w+): !!opencv-matrix\n        rows: (\d)\n        cols: (\d)\n        dt: d\n"
                          r"        data: \[ ([^\]]*) \]", text)
        self.assertEqual(len(mats), 24)
        for k, (name, rows, cols, data) in enumerate(mats):
            self.assertEqual(name, ["camera_matrix", "distortion_coefficients", "R_rig_cam", "t_rig_cam"][k % 4])
            vals = [float(x) for x in data.split(", ")]
            self.assertEqual(len(vals), int(rows) * int(cols))
            self.assertTrue(all("." in x or "e" in x for x in data.split(", ")), "OpenCV reads dt d as reals")
            if name == "R_rig_cam":
                self.assertEqual(vals, cams[k // 4]["R"])
                self.assertTrue(rigsim.is_rotation(vals))


if __name__ == "__main__":
    unittest.main(verbosity=1)
