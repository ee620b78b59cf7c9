#!/usr/bin/env python3
# robustness_table: runs the real programs on bad inputs and prints the markdown table of
# docs/ROBUSTNESS.md (input, exit code, message). Usage: tools/robustness_table.py BUILD_DIR
import os
import shutil
import struct
import subprocess
import sys
import tempfile

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


def run(what, args, env=None, shell=False):
    cases.append((what, args, env, shell))


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

print("| input | exit | message (last line of stderr) |")
print("| --- | --- | --- |")
tried = zero = 0
for what, args, env, shell in cases:
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run(args, shell=shell, env=e, capture_output=True, text=True, errors="replace", timeout=600)
    lines = [l for l in p.stderr.strip().split("\n") if l.strip()]
    msg = lines[-1] if lines else "(nothing)"
    # Errors come before the run's summary; show the line that says what went wrong.
    for l in lines:
        if "ERROR" in l or "error" in l or "expected" in l or "cannot" in l:
            msg = l
            break
    msg = msg.replace(tmp, "TMP").replace(root, "SRC").replace("|", "\\|")
    if len(msg) > 300:
        msg = msg[:297] + "..."
    print("| %s | %d | `%s` |" % (what, p.returncode, msg))
    tried += 1
    zero += p.returncode == 0
print()
print("%d bad inputs tried; %d ended with exit 0." % (tried, zero))
shutil.rmtree(tmp)
