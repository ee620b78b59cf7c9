#!/bin/sh
# mesh_scale: ingest + mesh of 10^7 organized (PTX) points and of 10^6 unorganized points, each
# stage under /usr/bin/time -v (CPU s, wall s, peak RSS) on a simulated step_park scan.
# usage: bench/mesh_scale.sh BUILD_DIR WORK_DIR [SCENE.json]   (docs/BENCHMARKS.md, scan to mesh)
# SCENE.json defaults to step_park's in RHOSCAN_SHARED_DIR (default: ../shared beside the source).
set -eu
build=$(cd "$1" && pwd)
work=$2
here=$(cd "$(dirname "$0")" && pwd)
scene=${3:-${RHOSCAN_SHARED_DIR:-$here/../../shared}/reference/step_park/scene.json}
mkdir -p "$work"
cd "$work"
[ -f scan_5000x2000.ptx ] && [ -f cloud_1000000.ply ] ||
    nice -n 10 /usr/bin/python3 "$here/mesh_scale.py" "$scene" . --ptx 5000 2000 --ply 1000000
pos=$(/usr/bin/python3 -c "import json, sys; print(*json.load(open(sys.argv[1]))['scanner']['position'])" "$scene")
cat > organized.ini <<END
[pipeline]
workdir = organized
[ingest]
scan = scan_5000x2000.ptx
[mesh]
facets = 100000
END
cat > unorganized.ini <<END
[pipeline]
workdir = unorganized
[ingest]
scan = cloud_1000000.ply
scanner_position = $pos
[mesh]
facets = 20000
END
for case in organized unorganized; do
    for stage in ingest mesh; do
        nice -n 10 /usr/bin/time -v -o "$case.$stage.time" "$build/rhoscan-$stage" --quiet "$case.ini"
        awk -v c="$case" -v s="$stage" -F': ' '
            /User time/ {u = $2} /System time/ {y = $2} /Elapsed/ {w = $2} /Maximum resident/ {r = $2}
            END {printf "%-12s %-7s CPU %7.1f s  wall %s  peak RSS %.0f MB\n", c, s, u + y, w, r / 1024}' \
            "$case.$stage.time"
    done
done
