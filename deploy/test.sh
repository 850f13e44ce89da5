#!/usr/bin/env bash
# Installs what is missing, builds Tessera, and runs the whole test suite: the release build's tests, then the
# unit tests (core, protocol, byte stream, coordinator, client, worker) again under AddressSanitizer +
# UndefinedBehaviorSanitizer (clang), the coordinator's, the worker's, the client's and the byte stream's unit tests
# under ThreadSanitizer (clang), then each libFuzzer target for a minute. The sanitizer builds compile beside the
# tests of the build before them (below).
# Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh

JOBS=$(nproc)
# The release tests keep two cores about 60% busy (they wait on the processes, sockets and browser they drive), so
# the next build compiles beside them at low priority, its output in a log printed afterwards; likewise the TSan
# build beside the sanitizer tests. A failure stops both.
background_build=
trap '[ -n "$background_build" ] && kill -- "-$background_build" 2>/dev/null; true' EXIT
build_in_background() {  # build dir, log file, cmake --build arguments...
  local log=$2
  setsid nice -n 10 cmake --build "$1" -j "$JOBS" "${@:3}" >"$log" 2>&1 &
  background_build=$!  # its own process group (setsid), so that the trap stops the compilers too
}
finish_background_build() {  # log file
  if ! wait "$background_build"; then
    background_build=
    tail -n 200 "$1"
    echo "build failed (whole log: $1)" >&2
    exit 1
  fi
  background_build=
  tail -n 1 "$1"
}

# Every target's files in one unity unit (TESSERA_UNITY_BATCH_SIZE=0): each header and template the files share is
# compiled once per target, not once per batch of 8 (the release build: 388 s against 586 s on a 2-core VM).
UNITY=-DTESSERA_UNITY_BATCH_SIZE=0

echo "== release build"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DTESSERA_WERROR=ON "$UNITY" >/dev/null
cmake --build build -j "$JOBS"

# clang for libFuzzer; a build-san configured by an earlier GCC-based script is started afresh.
if [ -f build-san/CMakeCache.txt ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang' build-san/CMakeCache.txt; then
  rm -rf build-san
fi
CC=clang CXX=clang++ cmake -S . -B build-san -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTESSERA_WERROR=ON "$UNITY" \
  -DTESSERA_SANITIZE=ON -DTESSERA_FUZZ=ON -DTESSERA_ONLY_UNIT_TESTS=ON -DTESSERA_TEST_SCALE_DIVISOR=20 >/dev/null
echo "== sanitizer build started beside the release tests (clang, ASan + UBSan: the libraries' unit tests, the"
echo "   randomised ones at 1/20 of their cases, and the fuzz targets)"
build_in_background build-san build-san/build.log

# Every step runs through tests/lib/run_ctest.py: a skipped or unrun test fails the step (ctest alone counts a skip as
# a pass), unless it is named in TESSERA_ALLOWED_SKIPS (never under CI=true), and each step expects at least the number
# of tests it has today, so a label that loses its tests fails too. The counts are summed up at the end.
SUMMARY=$(mktemp)
run_tests() {  # step name, build dir, minimum test count, ctest filter arguments...
  python3 tests/lib/run_ctest.py --step "$1" --build "$2" --min "$3" --jobs "$JOBS" --summary "$SUMMARY" -- "${@:4}"
}
if [ -n "${TESSERA_ALLOWED_SKIPS:-}" ]; then
  echo "== tests allowed to skip on this machine (TESSERA_ALLOWED_SKIPS): $TESSERA_ALLOWED_SKIPS"
fi

echo "== release tests"
run_tests release build 716

echo "== sanitizer build"
finish_background_build build-san/build.log

CC=clang CXX=clang++ cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTESSERA_WERROR=ON "$UNITY" \
  -DTESSERA_TSAN=ON -DTESSERA_ONLY_UNIT_TESTS=ON -DTESSERA_TEST_SCALE_DIVISOR=20 >/dev/null
echo "== thread sanitizer build started beside the sanitizer tests (clang, TSan: the coordinator's, the worker's,"
echo "   the client's and the byte stream's unit tests)"
build_in_background build-tsan build-tsan/build.log --target server_tests worker_tests client_tests net_tests

echo "== sanitizer tests"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  run_tests asan+ubsan build-san 574

echo "== thread sanitizer build"
finish_background_build build-tsan/build.log
echo "== thread sanitizer tests"
TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 run_tests tsan build-tsan 257 -L 'server|worker|client|net'

echo "== fuzzing (scene loader, OBJ reader, EXR reader, HTTP handler: 60 s each, all four at once)"
FUZZ_PARALLEL=4 bash tests/fuzz/run.sh build-san 60

echo "== summary"
cat "$SUMMARY"
