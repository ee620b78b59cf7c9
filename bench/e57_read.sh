#!/bin/sh
# e57_read.sh: the E57 reading figures of docs/BENCHMARKS.md (section E57 reading). Writes
# synthetic uncompressed-double E57 files of 10^6, 10^7 and 5 x 10^7 points (tools/e57write
# --synthetic: cartesianX/Y/Z as doubles, 24 bytes a point) into WORK and reads each one
# streaming and as a whole cloud. Usage: bench/e57_read.sh BUILD_DIR WORK
set -eu
build=$1
work=$2
mkdir -p "$work"
for n in 1000000 10000000 50000000; do
    f="$work/synthetic_$n.e57"
    [ -f "$f" ] || "$build/e57write" --synthetic "$n" "$f"
    ls -l "$f" | awk '{printf "%s: %.1f MB\n", $NF, $5 / 1e6}'
    cat "$f" > /dev/null # in the page cache: the figures are the reader's, not the disk's
    "$build/rhoscan-e57-bench" "$f"
    "$build/rhoscan-e57-bench" "$f" --cloud
done
