#!/bin/sh
# Installs the Debian 12 packages rhoscan builds and tests with (run as root).
# Usage: tools/setup-debian.sh [--tests | --bench]   (--tests adds what the test suites need,
# --bench what bench/ compares against: OctoMap and OpenVDB for rhoscan-freespace-bench --libs)
set -eu
pkgs="build-essential cmake pkg-config libembree-dev libtbb-dev libopenexr-dev libstb-dev zlib1g-dev libinih-dev libcjson-dev libexpat1-dev libopencv-dev libpcl-dev libjs-three"
# libexpat1-dev: the XML section of E57 files (common/e57_xml.c).
# libpcl-dev: point-cloud cleaning, normals and surface reconstruction (common/pcl_bridge.cpp).
# libjs-three: three.js r111, copied beside report.html for the 3D view of albedo.glb (pipeline/report_model.c).
# libopencv-dev: rig files, TIFF frames and HDR merging in the calib stage (calib/cv_adapter.cpp).
if [ "${1:-}" = "--tests" ]; then
    # cmocka: unit tests; python3 with numpy/scipy/OpenImageIO: the reference evaluator;
    # clang + libclang-rt-14-dev + libomp-dev (OpenMP for clang): fuzzing and sanitizer builds;
    # blender-data: real DWA-compressed skies; chromium, chromium-driver, python3-selenium: the
    # report's page test (tests/report/report_page.py); blender and python3-open3d: the viewers
    # the texture stage's exports must open in (tests/stages/texture_viewers.py; about 45 s to
    # install, 85 MB of packages, 266 MB on disk); cloudcompare with xvfb and xauth: the same
    # test reads albedo_vertex.ply's colours through CloudCompare's command line;
    # libopenmpi-dev and openmpi-bin: the MPI build and its test (tests/mpi, ctest -L mpi).
    pkgs="$pkgs libcmocka-dev python3 python3-numpy python3-scipy python3-openimageio clang libclang-rt-14-dev libomp-dev blender-data chromium chromium-driver python3-selenium blender python3-open3d cloudcompare xvfb xauth libopenmpi-dev openmpi-bin"
fi
if [ "${1:-}" = "--bench" ]; then
    pkgs="$pkgs liboctomap-dev libopenvdb-dev"
fi
missing=""
for p in $pkgs; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends $missing
fi
