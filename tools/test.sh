#!/usr/bin/env bash
# The test command of the README and of CI: installs what the tests need (Debian 12, root),
# builds, and runs every suite. Suites: unit, stages, playback (ctest labels).
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup-debian.sh --tests
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo
cmake --build build -j2
ctest --test-dir build --output-on-failure -j2
