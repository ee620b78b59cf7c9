#!/usr/bin/env bash
# The test command of the README and of CI: installs what the tests need (Debian 12, root),
# builds, and runs every suite. Suites: unit, stages, stress, playback (ctest labels); then
# unit and stages again under AddressSanitizer + UndefinedBehaviorSanitizer (build-asan), and
# each reader's libFuzzer harness for its share of RHOSCAN_FUZZ_SECONDS (default 300).
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup-debian.sh --tests
# The layering first: a forbidden include fails in a second, before any build.
python3 tools/check_layers.py
python3 tools/check_functions.py
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo
cmake --build build -j2
ctest --test-dir build --output-on-failure -j2
# MPI (cmake -DRHOSCAN_MPI=ON): the samples under mpirun -np 1, 2, 3 against one process, and
# the stage programs that mpi_rank0_fails starts on their own.
cmake -S . -B build-mpi -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRHOSCAN_MPI=ON
cmake --build build-mpi -j2 --target rhoscan rhoscan-render rhoscan-texture test_par
ctest --test-dir build-mpi -L mpi --output-on-failure
# Sanitizers: any report aborts the test that triggered it (-fno-sanitize-recover).
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRHOSCAN_SANITIZE=ON
cmake --build build-asan -j2
# LeakSanitizer: a leak inside PCL's Poisson is suppressed by name (tests/lsan.supp), no other.
LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0" \
  ctest --test-dir build-asan -L 'unit|stages' --output-on-failure -j2
tools/fuzz.sh "${RHOSCAN_FUZZ_SECONDS:-300}"
