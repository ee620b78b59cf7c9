#!/bin/sh
# paper_ratio: CPU seconds of the method stages, `paper` against `interreflection`, by function
# (perf samples: other jobs on a shared machine do not inflate them). docs/BENCHMARKS.md.
#   bench/paper_ratio.sh BUILD_DIR WORK_DIR [irradiance overrides...]
# WORK_DIR: a folder rhoscan-bench prepared (facets_N, observe already run); it is rerun in place.
set -eu
bin=$1; work=$2; shift 2
[ $# -gt 0 ] || set -- --set irradiance.samples=16 --set irradiance.sky_samples=32 --set irradiance.sun_samples=8
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Threads waiting at OpenMP barriers sleep instead of spinning: on a loaded machine spinning
# threads burn CPU while the other thread waits for a core, which would count as work.
export OMP_WAIT_POLICY=passive
# perf record of one stage program with DWARF call graphs (the build has no frame pointers).
run() {
    name=$1; shift
    perf record -q -e cpu-clock -F 1000 --call-graph dwarf,16384 -o "$tmp/$name.data" "$@" >/dev/null 2>&1
    perf report -i "$tmp/$name.data" --children --sort symbol --stdio -g none 2>/dev/null > "$tmp/$name.txt"
}
# CPU seconds of the whole program.
total() { awk '/^# Event count/ { printf "%.3f", $NF / 1e9 }' "$tmp/$1.txt"; }
# CPU seconds of a function with what it calls (sum over the symbols matching the pattern).
cpu() {
    awk -v pat="$2" '/^# Event count/ { total = $NF }
        $0 ~ pat && $1 ~ /%$/ { sub("%", "", $1); s += $1 }
        END { printf "%.3f", s / 100 * total / 1e9 }' "$tmp/$1.txt"
}

run irr "$bin/rhoscan-irradiance" --quiet "$@" "$work/config.ini"
run refl_ir "$bin/rhoscan-reflectance" --quiet --set reflectance.method=interreflection "$work/config.ini"
run refl_paper "$bin/rhoscan-reflectance" --quiet --set reflectance.method=paper "$work/config.ini"

gather=$(cpu irr '\\] gather_list\\._omp_fn')
ir_solve=$(cpu refl_ir '\\] (rs_transport_read|solve \\(inlined\\)) ')
kernel=$(cpu refl_paper '\\] rs_paper_kernel\\._omp_fn')
p_solve=$(cpu refl_paper '\\] (compute_G\\._omp_fn\\.0|estimate \\(inlined\\))')
echo "irradiance stage:        $(total irr) CPU-s (sky map $(cpu irr '\\] rs_skyenv_build_opts'), gather $gather, dynamic loading $(cpu irr '\\] dl_main'))"
echo "interreflection solve:   $ir_solve CPU-s (transport read + solve; reflectance stage $(total refl_ir))"
echo "paper kernel:            $kernel CPU-s"
echo "paper solve:             $p_solve CPU-s (G sweeps + estimate; reflectance stage $(total refl_paper))"
awk -v a="$kernel" -v b="$p_solve" -v c="$gather" -v d="$ir_solve" \
    'BEGIN { printf "method stages: paper %.3f, interreflection %.3f CPU-s: %.1f x\n", a + b, c + d, (a + b) / (c + d) }'
