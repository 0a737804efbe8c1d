#!/usr/bin/env bash
# The whole test suite, from a fresh Debian 12 machine: installs what is
# missing, builds from scratch, runs every test. Exit status 0 = all passed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/local/build.sh
# Loader tests, and the farm's scheduling, store and restart logic, again under
# AddressSanitizer and UndefinedBehaviorSanitizer.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DLOCUS_SANITIZE=ON >/dev/null
cmake --build build-asan -j "$(nproc)" --target locus_tests
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  build-asan/bin/locus_tests --gtest_filter='Nff*:SceneJson*:SceneProto*:Polyhedron*:Validate*:LoaderFuzz*:Animation*:Geometry*:Optics*:Scheduler*:JobStore*:BandFiles*:CoordinatorRestart*'
cd build
ctest --output-on-failure -j "$(nproc)"
