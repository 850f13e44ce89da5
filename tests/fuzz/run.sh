#!/usr/bin/env bash
# Runs the libFuzzer targets for a bounded time each, FUZZ_PARALLEL (default 2) at a time, on copies of the seed
# corpora (so nothing is written into the repository). Usage: tests/fuzz/run.sh BUILD_DIR [SECONDS_PER_TARGET] [TARGET...]
# Exits non-zero when a target finds a crash, a sanitizer error or a leak; the input that did it is kept in
# BUILD_DIR/fuzz-artifacts/ and its path printed.
set -euo pipefail
BUILD=$(cd "$1" && pwd)
SECONDS_EACH=${2:-60}
shift $(( $# >= 2 ? 2 : $# ))
TARGETS=("$@")
[ ${#TARGETS[@]} -gt 0 ] || TARGETS=(scene_loader obj_reader exr_reader http_handler)
SRC=$(cd "$(dirname "$0")" && pwd)
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-fuzz.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$BUILD/fuzz-artifacts"

run_one() {
  local t=$1 extra=()
  # The HTTP handler's corpus covers about 45,000 coverage features; libFuzzer's entropic schedule then spent 70% of
  # the target's time updating their frequencies (perf), and 20-s runs alone made 58-68 inputs a second with it
  # against 99-480 without, for the same coverage (README, "Fuzzing").
  [ "$t" = http_handler ] && extra=(-entropic=0)
  mkdir -p "$WORK/$t"
  cp -r "$SRC/corpus/$t/." "$WORK/$t/"
  # -timeout: one input taking longer than 10 s is a finding; -rss_limit_mb: so is using more than 2 GiB.
  if ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
     "$BUILD/tests/fuzz/fuzz_$t" "${extra[@]}" -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
       -artifact_prefix="$BUILD/fuzz-artifacts/$t-" "$WORK/$t" >"$WORK/$t.log" 2>&1; then
    echo "fuzz_$t: ok ($(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$WORK/$t.log" | grep -Eo '[0-9]+$') runs in ${SECONDS_EACH} s, corpus $(ls "$WORK/$t" | wc -l) inputs)"
  else
    echo "fuzz_$t: FAILED" >&2
    grep -E 'ERROR|SUMMARY|Test unit written|runtime error' "$WORK/$t.log" | head -n 20 >&2
    tail -n 40 "$WORK/$t.log" >&2
    return 1
  fi
}

status=0
pids=()
for t in "${TARGETS[@]}"; do
  run_one "$t" &
  pids+=($!)
  if [ ${#pids[@]} -ge "${FUZZ_PARALLEL:-2}" ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
