#!/bin/sh
# report_cost: what the run report (report.html, issue 23) adds to a sample run. Per config, REPS
# forced runs with [report] write = true and REPS with false, alternating; prints the median wall
# and CPU (user + sys) seconds of each, and the median of the report's own CPU seconds (it logs
# them). docs/BENCHMARKS.md, section The run report.
#   bench/report_cost.sh BUILD_DIR [REPS [CONFIG...]]
set -eu
bin=$1; reps=${2:-5}; shift; [ $# -gt 0 ] && shift
[ $# -gt 0 ] || set -- configs/two_planes.ini configs/tower.ini configs/courtyard.ini
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Threads waiting at OpenMP barriers sleep instead of spinning (a loaded machine would count
# spinning as work).
export OMP_WAIT_POLICY=passive
median() { sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }
printf '%-26s %10s %10s %10s %10s %12s %8s\n' config wall_on wall_off cpu_on cpu_off report_cpu share
for cfg in "$@"; do
    name=$(basename "$cfg" .ini)
    : > "$tmp/on"; : > "$tmp/off"; : > "$tmp/rep"
    for i in $(seq "$reps"); do
        for w in true false; do
            /usr/bin/time -f '%e %U %S' -o "$tmp/t" "$bin/rhoscan" run "$cfg" --force --set pipeline.workdir="$tmp/work_$name" \
                --set report.write=$w 2> "$tmp/log"
            if [ $w = true ]; then
                awk '{print $1, $2 + $3}' "$tmp/t" >> "$tmp/on"
                sed -n 's/.*report\.html (.* s, CPU \([0-9.]*\) s)/\1/p' "$tmp/log" >> "$tmp/rep"
            else
                awk '{print $1, $2 + $3}' "$tmp/t" >> "$tmp/off"
            fi
        done
    done
    won=$(cut -d' ' -f1 "$tmp/on" | median); woff=$(cut -d' ' -f1 "$tmp/off" | median)
    con=$(cut -d' ' -f2 "$tmp/on" | median); coff=$(cut -d' ' -f2 "$tmp/off" | median)
    rep=$(median < "$tmp/rep")
    printf '%-26s %10.3f %10.3f %10.3f %10.3f %12.3f %7.1f%%\n' "$name" "$won" "$woff" "$con" "$coff" "$rep" \
        "$(echo "$rep $coff" | awk '{print 100 * $1 / $2}')"
done
