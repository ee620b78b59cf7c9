#!/usr/bin/env python3
# robustness_table: runs the real programs on bad inputs and prints the markdown table of
# docs/ROBUSTNESS.md (input, exit code, message). Usage: tools/robustness_table.py BUILD_DIR
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zlib

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
bin_dir = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "build"))
sample = os.path.join(root, "sample_data", "two_planes")
tmp = tempfile.mkdtemp(prefix="rhoscan-robust-")


def path(name):
    return os.path.join(tmp, name)


def write(name, data):
    with open(path(name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())
    return path(name)


base_cfg = open(os.path.join(root, "configs", "two_planes.ini")).read()
base_cfg = base_cfg.replace("../sample_data/two_planes", sample).replace("../out/two_planes", path("work"))


def cfg(name, text=None, replace=None):
    t = base_cfg if text is None else text
    for a, b in (replace or []):
        assert a in t, a
        t = t.replace(a, b)
    return write(name, t)


good = cfg("good.ini")
truth = os.path.join(sample, "truth.ply")
pano = os.path.join(sample, "pano.exr")
ply_ok = open(truth, "rb").read()
ptx_big = open(os.path.join(sample, "scan.ptx"), "rb").read()[:4000].decode().split("\n")
ptx_ok = open(os.path.join(root, "tests/fuzz/corpus/ptx/colour.ptx")).read().split("\n")  # 2 x 3 points

cases = []  # (what, argv or shell string, env)


def run(what, args, env=None, shell=False, pick=None, repaired=False):
    """pick: a substring that marks the line to show (default: the first error-like line);
    repaired: an input that is cleaned with a warning and meant to run (exit 0)."""
    cases.append((what, args, env, shell, pick, repaired))


rh = os.path.join(bin_dir, "rhoscan")
mesh_only = ["--only", "mesh"]
# ---- config
run("config file missing", [rh, "run", path("nope.ini")])
run("config: empty file", [rh, "run", write("empty.ini", "")])
run("config: unknown key (typo)", [rh, "run", cfg("typo.ini", replace=[("pixels_per_facet", "pixels_per_facett")])])
run("config: unknown section", [rh, "run", cfg("sect.ini", replace=[("[mesh]", "[meshh]")])])
run("config: bad number", [rh, "run", cfg("num.ini", replace=[("samples = 256", "samples = 25x6")])])
run("config: number out of range", [rh, "run", cfg("range.ini", replace=[("samples = 256", "samples = -3")])])
run("config: rotation not orthonormal", [rh, "run", cfg("rot.ini", replace=[("rotation = 1 0 0  0 1 0  0 0 1", "rotation = 1 0 0  0 2 0  0 0 1")])])
run("config: rotation with 8 numbers", [rh, "run", cfg("rot8.ini", replace=[("rotation = 1 0 0  0 1 0  0 0 1", "rotation = 1 0 0  0 1 0  0 0")])])
run("config: NaN position", [rh, "run", cfg("nanpos.ini", replace=[("position = 0 -9 4", "position = 0 nan 4")])])
run("config: missing [capture] position", [rh, "run", cfg("nopos.ini", replace=[("position = 0 -9 4", "")])])
run("config: missing section [capture]", [rh, "run", cfg("nocap.ini", replace=[("[capture]", "; no capture"), ("panorama = ", "; "), ("position = ", "; "), ("rotation = ", "; ")])])
run("config: line without '='", [rh, "run", cfg("noeq.ini", replace=[("[mesh]", "[mesh]\nfacet_size 0.3")])])
run("--set of an unknown key", [rh, "run", good, "--set", "mesh.facet_sise=0.3"])
run("--set without '='", [rh, "run", good, "--set", "mesh.facet_size"])
run("unknown option", [rh, "run", good, "--frobnicate"])
# ---- scans (PTX)
def ptx_case(what, data):
    p = write(what.replace(" ", "_").replace(":", "") + ".ptx", data)
    run("PTX: " + what, [rh, "run", good, "--only", "ingest", "--set", "ingest.scan=" + p])


ptx_case("empty file", "")
ptx_case("binary garbage", bytes(range(256)) * 4)
ptx_case("truncated (header only)", "\n".join(ptx_big[:10]) + "\n")
ptx_case("truncated in the points", "\n".join(ptx_big[:40]))
ptx_case("one point line short", "\n".join(ptx_ok[:15]) + "\n")
ptx_case("transform not 4 numbers a line", "\n".join(ptx_ok[:6] + ["1 0 0"] + ptx_ok[7:]))
ptx_case("NaN coordinate", "\n".join(ptx_ok[:10] + ["nan 0 0 0.5 0 0 0"] + ptx_ok[11:]))
ptx_case("negative column count", "\n".join(["-4"] + ptx_ok[1:]))
ptx_case("too many numbers on a point line", "\n".join(ptx_ok[:10] + ["1 2 3 0.5 1 2 3 4 5"] + ptx_ok[11:]))
run("scan path missing", [rh, "run", good, "--only", "ingest", "--set", "ingest.scan=" + path("none.ptx")])
# ---- meshes (PLY as [mesh] input_mesh)
def ply_case(what, data):
    p = write(what.replace(" ", "_").replace(":", "") + ".ply", data)
    run("PLY mesh: " + what, [rh, "run", good, "--only", "mesh", "--set", "mesh.input_mesh=" + p])


ply_case("empty file", "")
ply_case("wrong magic", b"plx" + ply_ok[3:])
ply_case("binary garbage", bytes(range(256)) * 4)
ply_case("truncated data", ply_ok[: len(ply_ok) // 2])
ply_case("vertex count larger than the data", ply_ok.replace(b"element vertex 16", b"element vertex 99"))
ply_case("face index out of range", ply_ok.replace(b"\n3 1 2 0 ", b"\n3 1 2 300 ", 1))
ply_case("face with 2 vertices", ply_ok.replace(b"\n3 1 2 0 ", b"\n2 1 2 ", 1))
ply_case("NaN coordinate", ply_ok.replace(b"-5.000000 -5.000000 -0.100000", b"nan -5.000000 -0.100000", 1))
ply_case("unknown property type", ply_ok.replace(b"property float x", b"property float128 x"))
run("mesh path missing", [rh, "run", good, "--only", "mesh", "--set", "mesh.input_mesh=" + path("none.ply")])
# ---- panoramas (observe on the true mesh)
mesh_cfg = cfg("mesh.ini", replace=[("[mesh]", "[mesh]\ninput_mesh = " + truth)])


def pano_case(what, data=None, p=None):
    if p is None:
        p = write(what.replace(" ", "_").replace(":", "").replace("/", "") + ".img", data)
    run("panorama: " + what, [rh, "run", mesh_cfg, "--set", "capture.panorama=" + p])


pano_case("missing path", p=path("none.exr"))
pano_case("empty file", b"")
pano_case("binary garbage", bytes(range(256)) * 4)
pano_case("truncated EXR", open(pano, "rb").read()[:3000])
pano_case("not 2:1 (Radiance .hdr, 4 x 4)", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\n" + bytes([128, 128, 128, 129]) * 16)
pano_case("PNG chunk running past the end", open(os.path.join(root, "tests/fuzz/corpus/image/oom-png-huge-chunk.png"), "rb").read())
run("camera inside the model (in the floor slab)", [rh, "run", mesh_cfg, "--set", "capture.position=0 0 -0.05"])
# ---- outputs
run("work folder is /dev/full (not a folder)", [rh, "run", good, "--set", "pipeline.workdir=/dev/full/out"])
run("stdout is /dev/full (--print-config)", "%s --print-config %s > /dev/full" % (os.path.join(bin_dir, "rhoscan-mesh"), good), shell=True)
run("full disk at the first write (RHOSCAN_FAULT=enospc:1)", [rh, "run", mesh_cfg, "--only", "mesh"], env={"RHOSCAN_FAULT": "enospc:1"})

# ---- the surfaces of issue 29: rig files, brackets and response files, pairs, COLMAP text, datetime
# and sun keys, grey card, captures and sky panoramas, input meshes, PCD and XYZ clouds, long paths,
# a read-only work folder
calib = os.path.join(bin_dir, "rhoscan-calib")


def png(w, h):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
    raw = b"".join(b"\0" + b"".join(bytes((x * 4 % 256, y * 8 % 256, 128)) for x in range(w)) for y in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


for f in ("cam0.png", "cam0_e0.png", "cam0_e1.png"):
    write(f, png(64, 32))


def rig(count="1", width="64", k="[ 40., 0., 31.5, 0., 40., 15.5, 0., 0., 1. ]", dist="[ 0., 0., 0., 0., 0. ]",
        t="[ 0., 0., 0. ]"):
    m = "     %s: !!opencv-matrix\n        rows: %d\n        cols: %d\n        dt: d\n        data: %s\n"
    return ("%%YAML:1.0\n---\ncamera_count: %s\ncameras:\n   - name: cam0\n     image_width: %s\n     image_height: 32\n"
            "     model: pinhole\n" % (count, width) + m % ("camera_matrix", 3, 3, k) +
            m % ("distortion_coefficients", 1, 5, dist) +
            m % ("R_rig_cam", 3, 3, "[ 0., 0., 1., -1., 0., 0., 0., -1., 0. ]") + m % ("t_rig_cam", 3, 1, t))


def calib_case(what, rig_text, extra="", frames="cam0.png", name=None):
    name = name or what.split(":")[0].replace(" ", "_")
    write(name + ".yaml", rig_text)
    cfgp = write(name + ".ini", "[pipeline]\nworkdir = %s\n[rig]\nfile = %s.yaml\nframes = %s\nwidth = 128\n%s\n"
                 % (path("calib_work"), name, frames, extra))
    run(what, [calib, cfgp])


calib_case("rig: NaN principal point (crashed with SIGSEGV)", rig(k="[ 40., 0., .nan, 0., 40., 15.5, 0., 0., 1. ]"),
           name="rig_nan_cx")
calib_case("rig: infinite cy", rig(k="[ 40., 0., 31.5, 0., 40., .inf, 0., 0., 1. ]"), name="rig_inf_cy")
calib_case("rig: NaN distortion", rig(dist="[ .nan, 0., 0., 0., 0. ]"), name="rig_nan_dist")
calib_case("rig: infinite translation", rig(t="[ 0., .inf, 0. ]"), name="rig_inf_t")
calib_case("rig: negative camera_count", rig(count="-1"), name="rig_neg_count")
calib_case("rig: image_width 4294967297 (OpenCV reads 1)", rig(width="4294967297"), name="rig_wide")
write("resp.txt", "".join("%g\n" % ((i + 1) / 256.0) for i in range(256)))
calib_case("response file without exposure times", rig(), "response_file = resp.txt\n", name="resp_alone")
calib_case("exposure time inf", rig(), "exposure_times_s = 0.01 inf\n", "cam0_e0.png cam0_e1.png", name="exp_inf")
write("resp_inf.txt", "0.001\ninf\n" + "".join("%g\n" % ((i + 1) / 256.0) for i in range(2, 256)))
calib_case("response value inf", rig(), "exposure_times_s = 0.01 0.02\nresponse_file = resp_inf.txt\n",
           "cam0_e0.png cam0_e1.png", name="resp_inf")
write("pairs_dup.txt", "".join("%d %d %d %d 3\n" % (10 + 17 * i, 10 + 7 * i, i, 2 * i + 1) for i in range(6)) +
      "10 10 0 1 3\n")
calib_case("pairs: the same correspondence twice", rig(),
           "[capture]\ncorrespondences = pairs_dup.txt\nposition = 0 0 0\n", name="pairs_dup")
colmap_dir = path("colmap_model")
os.makedirs(colmap_dir)
for f in ("cameras.txt", "images.txt", "points3D.txt"):
    shutil.copy(os.path.join(root, "sample_data/colmap_courtyard/model", f), colmap_dir)
cams = open(os.path.join(colmap_dir, "cameras.txt")).read().replace("1 PINHOLE 512 512 256.00000000000006",
                                                                     "1 PINHOLE 512 512 0")
open(os.path.join(colmap_dir, "cameras.txt"), "w").write(cams)
cc = os.path.join(root, "sample_data/colmap_courtyard")
run("COLMAP: focal length 0", [calib, write("colmap.ini", "[pipeline]\nworkdir = %s\n[colmap]\nmodel = %s\n"
                                            "views = %s/views.txt\ncontrol_points = %s/control_points.txt\n"
                                            "[capture]\ncolmap_panorama = pano3\n"
                                            % (path("colmap_work"), colmap_dir, cc, cc))])
site = ["--set", "sky.latitude_deg=40", "--set", "sky.longitude_deg=-3"]
for what, dt in (("30 February", "2021-02-30T12:00:00Z"), ("time zone +99:00", "2021-06-01T12:00:00+99:00"),
                 ("seconds NaN (hung the run)", "2021-06-01T12:00:nan")):
    run("datetime: " + what, [rh, "run", mesh_cfg, "--set", "sky.datetime=" + dt] + site)
run("grey card: x0 4294967396 (wrapped to 100)", [rh, "run", mesh_cfg, "--set",
                                                  "calib.grey_card_region=4294967396 0 4294967496 10"],
    pick="grey_card_region")
run("[capture.b] position with NaN", [rh, "run", mesh_cfg, "--set", "capture.b.position=0 nan 4", "--set",
                                      "capture.b.panorama=" + pano])
run("[sky] panorama missing", [rh, "run", mesh_cfg, "--set", "sky.panorama=" + path("nosky.exr"), "--set",
                               "sky.position=0 -9 4"])


def mesh_file(name, verts, faces):
    return write(name, "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
                 "property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n"
                 % (len(verts), len(faces)) + "".join("%r %r %r\n" % v for v in verts) +
                 "".join("3 %d %d %d\n" % f for f in faces))


col = [(0.0, 0.0, 0.0), (0.1, 0.2, 0.3), (0.3, 0.6, 0.9), (0.7, 1.4, 2.1)]
run("input mesh: all triangles collinear", [rh, "run", good, "--only", "mesh", "--set", "mesh.input_mesh=" +
                                            mesh_file("collinear.ply", col, [(0, 1, 2), (1, 2, 3), (0, 1, 3)])])
n = 2000000
coinc = write("coincident.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
              b"property float y\nproperty float z\nelement face %d\nproperty list uchar int vertex_indices\n"
              b"end_header\n" % n + struct.pack("<9f", -1, -1, 0.01, 1, -1, 0.01, 0, 1, 0.01) +
              struct.pack("<Biii", 3, 0, 1, 2) * n)
run("input mesh: 2 million coincident triangles (ran past 300 s)", [rh, "run", good, "--set",
                                                                     "mesh.input_mesh=" + coinc], pick="coincident",
    repaired=True)
scan = ["--only", "ingest", "--set", "ingest.scanner_position=0 -9 4", "--set"]
pcd_head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH %d\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n")
run("PCD: empty file (crashed PCL's reader)", [rh, "run", good] + scan + ["ingest.scan=" + write("empty.pcd", "")])
run("PCD: infinite coordinate", [rh, "run", good] + scan + [
    "ingest.scan=" + write("inf.pcd", pcd_head % (2, 2, "ascii") + "inf 0 0\n1 2 3\n")])
run("PCD: binary data that reads as a header line", [rh, "run", good] + scan + [
    "ingest.scan=" + write("kw.pcd", (pcd_head % (2, 2, "binary")).encode() + b"FIELDS x" + bytes(16))])
run("XYZ: intensity 1e300", [rh, "run", good] + scan + ["ingest.scan=" + write("bigi.xyz", "1 2 3 1e300\n"),
                                                       "--set", "ingest.columns=x y z intensity"])
run("XYZ: colour 300", [rh, "run", good] + scan + ["ingest.scan=" + write("rgb.xyz", "1 2 3 300 0 0\n"),
                                                  "--set", "ingest.columns=x y z r g b"])
run("XYZ: 200000 copies of one point (took 214 s)", [rh, "run", good] + scan + [
    "ingest.scan=" + write("same.xyz", "1 2 3\n" * 200000)])
run("XYZ: points on one line", [rh, "run", good] + scan + [
    "ingest.scan=" + write("line.xyz", "".join("%g %g %g\n" % (k * 0.01, k * 0.02, k * 0.03) for k in range(5000)))])
deep = os.path.join(tmp, *["d%02d_a_folder_name_of_forty_characters_xxxxxx" % i for i in range(14)])
os.makedirs(deep)
run("a path of %d characters to a bad mesh" % (len(deep) + 18), [rh, "run", good, "--only", "mesh", "--set",
    "mesh.input_mesh=" + os.path.join(deep, "the_bad_mesh.ply")], pick="the_bad_mesh")
open(os.path.join(deep, "the_bad_mesh.ply"), "w").write("ply\nformat ascii 1.0\nelement vertex 1\n")
# A read-only work folder: a first run as this user, then the rerun of reflectance as nobody (root
# ignores permissions) after the folder was made read-only.
ro = path("ro")
os.makedirs(ro)
ro_cfg = cfg("ro.ini", replace=[(path("work"), os.path.join(ro, "work"))])
as_nobody = "setpriv --reuid=65534 --regid=65534 --clear-groups " if os.geteuid() == 0 else ""
run("read-only work folder (rerun of reflectance)",
    "%s run %s >/dev/null 2>&1; chmod -R a+rX %s; chmod 555 %s/work %s/work/.rhoscan; %s%s run %s "
    "--set reflectance.method=direct; rc=$?; chmod 755 %s/work %s/work/.rhoscan; exit $rc"
    % (rh, ro_cfg, tmp, ro, ro, as_nobody, rh, ro_cfg, ro, ro), shell=True)

print("| input | exit | message (last line of stderr) |")
print("| --- | --- | --- |")
tried = zero = 0
repairs = 0
for what, args, env, shell, pick, repaired in cases:
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run(args, shell=shell, env=e, capture_output=True, text=True, errors="replace", timeout=600)
    lines = [l for l in p.stderr.strip().split("\n") if l.strip()]
    msg = lines[-1] if lines else "(nothing)"
    # Errors come before the run's summary; show the line that says what went wrong.
    for l in lines:
        if (pick in l) if pick else ("ERROR" in l or "error" in l or "expected" in l or "cannot" in l):
            msg = l
            break
    msg = msg.replace(tmp, "TMP").replace(root, "SRC").replace("|", "\\|")
    if len(msg) > 300:  # its start and its end: a file's name is at the end of a long path
        msg = msg[:140] + " [...] " + msg[-153:]
    print("| %s | %d | `%s` |" % (what, p.returncode, msg))
    tried += 1
    zero += p.returncode == 0 and not repaired
    repairs += repaired
print()
print("%d bad inputs tried; %d ended with exit 0 (besides %d repaired with a warning, meant to run)." %
      (tried, zero, repairs))
shutil.rmtree(tmp)
