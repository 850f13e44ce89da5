#!/usr/bin/env bash
# Installs what is missing, builds Tessera, and runs the whole test suite: the release build's tests, then the
# unit tests (core, protocol, byte stream, coordinator, client, worker) again under AddressSanitizer +
# UndefinedBehaviorSanitizer (clang), the coordinator's, the worker's, the client's and the byte stream's unit tests
# under ThreadSanitizer (clang), then each libFuzzer target for a minute.
# Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh

JOBS=$(nproc)
echo "== release build"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DTESSERA_WERROR=ON >/dev/null
cmake --build build -j "$JOBS"
echo "== release tests"
ctest --test-dir build --output-on-failure -j "$JOBS"

echo "== sanitizer build (clang, ASan + UBSan: the libraries' unit tests, the randomised ones at 1/20 of their cases, and the fuzz targets)"
# clang for libFuzzer; a build-san configured by an earlier GCC-based script is started afresh.
if [ -f build-san/CMakeCache.txt ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang' build-san/CMakeCache.txt; then
  rm -rf build-san
fi
CC=clang CXX=clang++ cmake -S . -B build-san -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTESSERA_WERROR=ON \
  -DTESSERA_SANITIZE=ON -DTESSERA_FUZZ=ON -DTESSERA_ONLY_UNIT_TESTS=ON -DTESSERA_TEST_SCALE_DIVISOR=20 >/dev/null
cmake --build build-san -j "$JOBS"
echo "== sanitizer tests"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-san --output-on-failure -j "$JOBS"

echo "== thread sanitizer build (clang, TSan: the coordinator's, the worker's, the client's and the byte stream's unit tests)"
CC=clang CXX=clang++ cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTESSERA_WERROR=ON \
  -DTESSERA_TSAN=ON -DTESSERA_ONLY_UNIT_TESTS=ON -DTESSERA_TEST_SCALE_DIVISOR=20 >/dev/null
cmake --build build-tsan -j "$JOBS" --target server_tests worker_tests client_tests net_tests
echo "== thread sanitizer tests"
TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 ctest --test-dir build-tsan --output-on-failure -j "$JOBS" -L 'server|worker|client|net'

echo "== fuzzing (scene loader, OBJ reader, EXR reader, HTTP handler: 60 s each, all four at once)"
FUZZ_PARALLEL=4 bash tests/fuzz/run.sh build-san 60
