# Simulated Ladybug-style rig: camera layouts, OpenCV's pinhole lens model (k1 k2 p1 p2 k3) and its
# inverse, the remap from an undistorted render to a distorted frame, and the rig file
# (docs/DESIGN.md, section Rig file).
# SPDX-License-Identifier: BSD-3-Clause
"""numpy only, no Blender: test_refscene.py checks it in CI.

Camera frame: OpenCV's (x right, y down, z forward); pixel centres at integer coordinates.
A camera is a dict: name, size [width, height], K [fx, fy, cx, cy] (px), dist [k1, k2, p1, p2, k3],
R (camera -> rig rotation, 9 numbers row-major), t (camera centre in the rig frame, m).
"""
import math

import numpy as np

# The preset: five cameras around the horizon every 72 degrees and one looking up, portrait
# sensors as on a Ladybug 5 (smaller), barrel distortion of a wide lens. With these values the
# five side cameras overlap by about 24 degrees and reach 56 degrees above and below the horizon;
# the top camera covers the zenith down to 34 degrees elevation.
LADYBUG5 = {"image_size": [512, 640], "focal_px": 260.0, "dist": [-0.12, 0.02, 0.0005, -0.0003, 0.0],
            "radius_m": 0.04}
# Principal points of real heads sit a few pixels off centre; the preset does the same so that
# code that assumes the centre is caught.
_PRESET_PP_OFFSET = [(3.0, -2.0), (-2.5, 1.5), (1.0, 3.5), (-4.0, -1.0), (2.0, 2.5), (-1.5, -3.0)]


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


# The camera looking along rig +X, level: columns are its x (right), y (down), z (forward).
_R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def look_rotation(az_deg, el_deg, roll_deg):
    """Camera -> rig rotation (row-major) of a camera whose optical axis points at azimuth az
    (counter-clockwise from rig +X) and elevation el, turned by roll about its axis (positive
    turns the image's x axis toward its y axis); roll 0 keeps image x horizontal (for el = 90:
    image x = rig -Y, image y = rig +X)."""
    r = _rz(az_deg) @ _ry(-el_deg) @ _R0 @ _rz(roll_deg)
    return [0.0 if abs(x) < 1e-15 else float(x) + 0.0 for x in r.ravel()]


def is_rotation(r, tol=1e-6):
    m = np.asarray(r, dtype=float).reshape(3, 3)
    return bool(np.allclose(m.T @ m, np.eye(3), atol=tol) and abs(np.linalg.det(m) - 1) < tol)


def ladybug5(size, focal, dist, radius):
    cams = []
    w, h = size
    for k in range(6):
        az, el = (72.0 * k, 0.0) if k < 5 else (0.0, 90.0)
        t = [radius * math.cos(math.radians(az)), radius * math.sin(math.radians(az)), 0.0] if k < 5 \
            else [0.0, 0.0, radius]
        dx, dy = _PRESET_PP_OFFSET[k]
        cams.append({"name": "cam%d" % k, "size": list(size),
                     "K": [float(focal), float(focal), (w - 1) / 2.0 + dx, (h - 1) / 2.0 + dy],
                     "dist": [float(x) for x in dist], "R": look_rotation(az, el, 0.0),
                     "t": [0.0 if abs(x) < 1e-15 else x for x in t]})
    return cams


def distort(a, b, k):
    """OpenCV's pinhole model: ideal normalised coordinates (a, b) = (x/z, y/z) -> distorted."""
    k1, k2, p1, p2, k3 = k
    r2 = a * a + b * b
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
    return (a * radial + 2 * p1 * a * b + p2 * (r2 + 2 * a * a),
            b * radial + p1 * (r2 + 2 * b * b) + 2 * p2 * a * b)


def undistort(xd, yd, k, iterations=40):
    """Inverse of distort by Newton's method per point (arrays). Returns (a, b, ok) with ok where
    the iteration converged to 1e-10 (normalised units)."""
    k1, k2, p1, p2, k3 = k
    a, b = np.array(xd, dtype=float), np.array(yd, dtype=float)
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            r2 = a * a + b * b
            radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
            dradial = k1 + 2 * k2 * r2 + 3 * k3 * r2 * r2          # d radial / d r2
            fx, fy = distort(a, b, k)
            ex, ey = fx - xd, fy - yd
            j00 = radial + 2 * a * a * dradial + 2 * p1 * b + 6 * p2 * a
            j01 = 2 * a * b * dradial + 2 * p1 * a + 2 * p2 * b
            j11 = radial + 2 * b * b * dradial + 6 * p1 * b + 2 * p2 * a
            det = j00 * j11 - j01 * j01
            a = a - (j11 * ex - j01 * ey) / det
            b = b - (-j01 * ex + j00 * ey) / det
        fx, fy = distort(a, b, k)
        ok = np.isfinite(a) & np.isfinite(b) & (np.abs(fx - xd) + np.abs(fy - yd) < 1e-10)
    return a, b, ok


def usable_field(k):
    """The largest tan of the angle off the axis up to which the radial model is one-to-one,
    computed as calib/rig.c does (slope of r (1 + k1 r^2 + k2 r^4 + k3 r^6) above 0.05, a 2 %
    margin, at most 80 degrees), so that the frames hold nothing the stitcher would not use."""
    limit = math.tan(math.radians(80.0))
    steps = 20000
    for s in range(1, steps + 1):
        r = limit * s / steps
        r2 = r * r
        if 1 + 3 * k[0] * r2 + 5 * k[1] * r2 * r2 + 7 * k[4] * r2 * r2 * r2 <= 0.05:
            return 0.98 * limit * (s - 1) / steps
    return limit


def frame_rays(cam):
    """Per pixel of the distorted frame (rows top first): the ideal coordinates (a, b) and
    whether the pixel lies inside the lens's usable field."""
    w, h = cam["size"]
    fx, fy, cx, cy = cam["K"]
    y, x = np.mgrid[0:h, 0:w].astype(float)
    a, b, ok = undistort((x - cx) / fx, (y - cy) / fy, cam["dist"])
    ok &= np.hypot(a, b) < usable_field(cam["dist"])
    return a, b, ok


def ideal_view(cam, a, b, ok, oversample=1.0):
    """The undistorted pinhole render that covers the frame: focal f (px, square pixels), size
    (width, height), optical axis at the image centre. Two pixels of margin for the bilinear
    footprint."""
    if not ok.any():
        raise ValueError("no pixel of camera %s lies inside its lens's usable field" % cam["name"])
    f = max(cam["K"][0], cam["K"][1]) * oversample
    half_w = f * float(np.abs(a[ok]).max()) + 2.0
    half_h = f * float(np.abs(b[ok]).max()) + 2.0
    return f, (2 * int(math.ceil(half_w)), 2 * int(math.ceil(half_h)))


def remap(ideal, f, a, b, ok):
    """Distorted frame from the undistorted render ideal (H x W x C, rows top first, optical axis
    at the centre, focal f): bilinear samples at x = f a + (W - 1) / 2, y = f b + (H - 1) / 2.
    Pixels outside the usable field are 0."""
    hi, wi = ideal.shape[:2]
    x = f * a + (wi - 1) / 2.0
    y = f * b + (hi - 1) / 2.0
    x = np.where(ok, x, 0.0)
    y = np.where(ok, y, 0.0)
    x0 = np.clip(np.floor(x).astype(np.int64), 0, wi - 2)
    y0 = np.clip(np.floor(y).astype(np.int64), 0, hi - 2)
    tx = np.clip(x - x0, 0.0, 1.0)[..., None]
    ty = np.clip(y - y0, 0.0, 1.0)[..., None]
    out = ((1 - ty) * ((1 - tx) * ideal[y0, x0] + tx * ideal[y0, x0 + 1])
           + ty * ((1 - tx) * ideal[y0 + 1, x0] + tx * ideal[y0 + 1, x0 + 1]))
    out[~ok] = 0.0
    return out


def _num(x):
    x = float(x) + 0.0          # no "-0.0"
    return repr(x)


def _matrix(name, rows, cols, data):
    return ["     %s: !!opencv-matrix" % name, "        rows: %d" % rows, "        cols: %d" % cols,
            "        dt: d", "        data: [ %s ]" % ", ".join(_num(v) for v in data)]


def rig_yaml(cams):
    """The rig file in the layout of docs/DESIGN.md, section Rig file (OpenCV FileStorage YAML)."""
    lines = ["%YAML:1.0", "---", "camera_count: %d" % len(cams), "cameras:"]
    for c in cams:
        fx, fy, cx, cy = c["K"]
        lines += ["   - name: %s" % c["name"], "     image_width: %d" % c["size"][0],
                  "     image_height: %d" % c["size"][1], "     model: pinhole"]
        lines += _matrix("camera_matrix", 3, 3, [fx, 0, cx, 0, fy, cy, 0, 0, 1])
        lines += _matrix("distortion_coefficients", 1, 5, c["dist"])
        lines += _matrix("R_rig_cam", 3, 3, c["R"])
        lines += _matrix("t_rig_cam", 3, 1, c["t"])
    return "\n".join(lines) + "\n"


def camera_world(cam, rig_pos, rig_yaw_deg):
    """(R_world_cam, centre_world): the OpenCV camera frame in the world for a rig at rig_pos
    turned by rig_yaw_deg about +Z (rig frame = the stitched panorama's local frame)."""
    r_world_rig = _rz(rig_yaw_deg)
    r = r_world_rig @ np.asarray(cam["R"], dtype=float).reshape(3, 3)
    centre = np.asarray(rig_pos, dtype=float) + r_world_rig @ np.asarray(cam["t"], dtype=float)
    return r, centre
