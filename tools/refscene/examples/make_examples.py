# Writes the example scene descriptions in this folder (arcade.json, imported.json, rig.json): the
# arches' outlines are many points, easier computed than typed. Run: python3 make_examples.py
# SPDX-License-Identifier: BSD-3-Clause
import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def r(x):
    return round(x, 4) + 0.0


def arch_top(cx, half_width, spring, segments=12, reverse=False):
    """Points of a semicircular arch over cx, from its right springing point to its left one."""
    pts = [[r(cx + half_width * math.cos(math.pi * k / segments)),
            r(spring + half_width * math.sin(math.pi * k / segments))] for k in range(segments + 1)]
    return pts[::-1] if reverse else pts


def arcade_outline(length, height, n_arches, opening, spring):
    """A wall length x height (u along the wall, v up) with n arched openings down to the ground:
    one outline, walked counter-clockwise (the openings reach the edge, so they are not holes)."""
    pier = (length - n_arches * opening) / (n_arches + 1)
    pts = [[0.0, 0.0]]
    x = pier
    for _ in range(n_arches):
        pts.append([r(x), 0.0])
        # Up the opening's left jamb, over the arch from left to right, down the right jamb.
        pts += arch_top(x + opening / 2, opening / 2, spring, reverse=True)
        pts.append([r(x + opening), 0.0])
        x += opening + pier
    pts += [[r(length), 0.0], [r(length), r(height)], [0.0, r(height)]]
    return pts


def octagon(cx, cy, radius):
    return [[r(cx + radius * math.cos(math.pi / 8 + k * math.pi / 4)),
             r(cy + radius * math.sin(math.pi / 8 + k * math.pi / 4))] for k in range(8)]


def write(name, scene):
    text = json.dumps(scene, indent=1)
    with open(os.path.join(HERE, name), "w", encoding="ascii") as f:
        f.write(text + "\n")


def arcade():
    length, height = 12.0, 5.0
    windows = []
    pier = (length - 4 * 1.8) / 5
    for k in range(4):
        cx = pier + 0.9 + k * (1.8 + pier)
        windows.append([[r(cx - 0.3), 3.6], [r(cx + 0.3), 3.6], [r(cx + 0.3), 4.4], [r(cx - 0.3), 4.4]])
    niche = [[-0.8, 0.8], [0.8, 0.8]] + arch_top(0.0, 0.8, 2.4)
    parts = [
        {"name": "ground", "min": [-10, -10, -0.2], "max": [10, 10, 0], "albedo": [0.30, 0.28, 0.25]},
        {"name": "arcade", "plane": "xz", "origin": [-6, 2, 0], "depth": 0.6,
         "outline": arcade_outline(length, height, 4, 1.8, 2.2), "holes": windows,
         "albedo": [0.62, 0.55, 0.45]},
        {"name": "back_wall", "plane": "xz", "origin": [-6, 5, 0], "depth": -0.6,
         "outline": [[0, 0], [12, 0], [12, 5], [0, 5]],
         "holes": [[[r(6 + p[0]), p[1]] for p in niche]], "albedo": [0.75, 0.72, 0.66]},
        {"name": "niche_back", "min": [-1, 5.6, 0.5], "max": [1, 5.9, 3.5], "albedo": [0.35, 0.45, 0.60]},
        {"name": "cornice", "plane": "yz", "origin": [-6.3, 0, 0], "depth": 12.6,
         "outline": [[1.1, 5.0], [2.0, 5.0], [2.0, 5.4], [0.9, 5.4], [0.9, 5.2], [1.1, 5.2]],
         "albedo": [0.80, 0.78, 0.72]},
    ]
    for k, y in enumerate([-3.0, -1.0, 1.0]):
        parts.append({"name": "column%d" % k, "plane": "xy", "origin": [0, 0, 0], "depth": 4.0,
                      "outline": octagon(7.0, y, 0.25), "albedo": [0.82, 0.82, 0.82]})
    parts.append({"name": "entablature", "min": [6.6, -3.5, 4], "max": [7.4, 1.5, 4.5], "albedo": [0.70, 0.30, 0.20]})
    return {"parts": parts,
            "env": {"file": "blender-data:courtyard.exr", "strength": 1.0, "rotation_z_deg": 30},
            "sun": {"direction_deg": [200, 40], "strength": 600, "angle_deg": 0.53},
            "camera": {"position": [0.5, -3, 1.6], "yaw_deg": 90},
            "scanner": {"position": [0, -3.2, 1.8], "grid": [480, 240], "elevation_deg": [-75, 80]},
            "samples": 256, "env_samples": 16, "pano_size": [512, 256], "seed": 3}


def imported():
    parts = [
        {"name": "ground", "min": [-10, -10, -0.2], "max": [10, 10, 0], "albedo": [0.30, 0.28, 0.25]},
        {"name": "house", "mesh": "house.obj", "translation": [0, 4, 0], "rotation_z_deg": 0,
         "albedo": [0.70, 0.62, 0.50]},
        {"name": "shed", "mesh": "house.obj", "translation": [-5, 1, 0], "rotation_z_deg": 35,
         "scale": [0.6, 0.6, 0.8], "albedo": [0.40, 0.55, 0.35]},
        {"name": "obelisk", "mesh": "obelisk.ply", "translation": [4, 0, 0], "scale": 1.5,
         "albedo": [0.80, 0.80, 0.78]},
    ]
    return {"parts": parts,
            "env": {"file": "blender-data:sunset.exr", "strength": 1.0, "rotation_z_deg": 0},
            "camera": {"position": [0, -3, 1.6], "yaw_deg": 80},
            "scanner": {"position": [0.3, -3.2, 1.8], "grid": [480, 240], "elevation_deg": [-75, 80]},
            "samples": 256, "env_samples": 16, "pano_size": [512, 256], "seed": 5}


def rig():
    scene = arcade()
    scene["camera"] = {"position": [0.5, -1.0, 1.6], "yaw_deg": 90}
    scene["scanner"]["position"] = [0.2, -1.2, 1.8]
    scene["rig"] = {"position": [0.5, -1.0, 1.6], "yaw_deg": 90, "samples": 64, "ladybug5": {}}
    scene["seed"] = 4
    return scene


if __name__ == "__main__":
    write("arcade.json", arcade())
    write("imported.json", imported())
    write("rig.json", rig())
