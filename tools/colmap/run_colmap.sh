#!/bin/sh
# run_colmap: panoramas -> pinhole views -> a COLMAP text model, headless on the CPU (Debian's
# colmap 3.8); the calib stage's [colmap] section then poses the panoramas from it (docs/COLMAP.md).
#
# Usage: tools/colmap/run_colmap.sh OUTDIR PANO.exr...        (colmap: apt-get install colmap)
#   env: VIEWS (8) SIZE (512) FOV (90) PITCH (-10) MAX_FEATURES (1500) THREADS (2)
# Writes OUTDIR/views/images/*.png and OUTDIR/views/views.txt (each view's rotation into its panorama: the
# [colmap] views file), OUTDIR/database.db, OUTDIR/sparse/0 (binary) and OUTDIR/model/{cameras,
# images,points3D}.txt (the [colmap] model folder). The intrinsics are the cut's own (PINHOLE,
# fixed), so the mapper only solves poses and points.
set -eu
if [ $# -lt 2 ]; then
    sed -n '2,11p' "$0" >&2
    exit 1
fi
here=$(cd "$(dirname "$0")" && pwd)
out=$1
shift
VIEWS=${VIEWS:-8} SIZE=${SIZE:-512} FOV=${FOV:-90} PITCH=${PITCH:-"-10"}
MAX_FEATURES=${MAX_FEATURES:-1500} THREADS=${THREADS:-2}
# COLMAP is a Qt program: without a display it needs the offscreen platform, and SIFT on the
# GPU needs OpenGL, hence use_gpu 0 for extraction and matching (LIBRARY-NOTES.md).
export QT_QPA_PLATFORM=offscreen
mkdir -p "$out"
rm -rf "$out/views" "$out/database.db" "$out/sparse" "$out/model"
/usr/bin/python3 "$here/cut_views.py" "$out/views" "$@" --views "$VIEWS" --size "$SIZE" --fov "$FOV" \
    --pitch="$PITCH"
params=$(cat "$out/views/camera.txt")
colmap feature_extractor --database_path "$out/database.db" --image_path "$out/views/images" \
    --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 --ImageReader.camera_params "$params" \
    --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$THREADS" \
    --SiftExtraction.max_num_features "$MAX_FEATURES"
colmap exhaustive_matcher --database_path "$out/database.db" --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads "$THREADS"
mkdir -p "$out/sparse"
colmap mapper --database_path "$out/database.db" --image_path "$out/views/images" --output_path "$out/sparse" \
    --Mapper.num_threads "$THREADS" --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 \
    --Mapper.ba_refine_extra_params 0
# The mapper may split the views into several models; the first (sparse/0) is the largest.
mkdir -p "$out/model"
colmap model_converter --input_path "$out/sparse/0" --output_path "$out/model" --output_type TXT
echo "run_colmap.sh: model in $out/model, views file $out/views/views.txt"
