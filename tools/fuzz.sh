#!/usr/bin/env bash
# fuzz.sh: builds the libFuzzer harnesses (tests/fuzz, clang, ASan + UBSan) in build-fuzz and
# runs each one for its share of a time budget. Usage: tools/fuzz.sh [TOTAL_SECONDS] (default 300)
set -euo pipefail
cd "$(dirname "$0")/.."
total=${1:-300}
readers="ply ptx config image pairs response colmap pcd xyz rig las e57"
nreaders=$(echo $readers | wc -w)
per=$(( total / nreaders )); [ "$per" -ge 1 ] || per=1

cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
      -DRHOSCAN_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build-fuzz -j2 --target $(for r in $readers; do printf 'fuzz_%s ' "$r"; done) >/dev/null

shared=${RHOSCAN_SHARED_DIR:-$PWD/../shared}
stats=build-fuzz/fuzz-stats.txt
: > "$stats"
status=0
for r in $readers; do
    # The committed seeds (and the reproducers of fixed crashes) stay read-only; new inputs go
    # to a working corpus in the build folder, together with run-time seeds that are not ours
    # to commit (the foreign PTX files of ../shared, the sample's EXR images).
    work=build-fuzz/corpus/$r
    mkdir -p "$work" build-fuzz/artifacts
    case $r in
        ptx)   [ -d "$shared/formats/ptx" ] && cp -f "$shared"/formats/ptx/*.ptx "$work"/ ;;
        las)   # fuzz_las reads from the second byte on (the first picks the class filter)
               if [ -d "$shared/formats/las" ]; then
                   for f in "$shared"/formats/las/*.la[sz]; do
                       { printf '\0'; cat "$f"; } > "$work/$(basename "$f")"
                   done
               fi ;;
        e57)   [ -d "$shared/formats/e57" ] && cp -f "$shared"/formats/e57/*.e57 "$work"/ ;;
        image) cp -f sample_data/two_planes/pano_diffcol.exr "$work"/ 2>/dev/null || true ;;
    esac
    echo "fuzz_$r: ${per} s" >&2
    log=build-fuzz/fuzz_$r.log
    # -rss_limit_mb: images up to 2^27 pixels are accepted by design, so allow their size.
    if ! build-fuzz/fuzz_$r -max_total_time="$per" -timeout=20 -rss_limit_mb=4096 \
            -print_final_stats=1 -artifact_prefix="build-fuzz/artifacts/$r-" \
            "$work" "tests/fuzz/corpus/$r" >"$log" 2>&1; then
        status=1
        echo "fuzz_$r FAILED: see $log; reproducer in build-fuzz/artifacts/" >&2
        grep -E "ERROR|SUMMARY|Test unit written" "$log" >&2 || tail -20 "$log" >&2
    fi
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    echo "$r ${runs:-0}" >> "$stats"
    echo "fuzz_$r: ${runs:-0} inputs" >&2
done
exit $status
