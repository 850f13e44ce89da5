#!/usr/bin/env bash
# Farm benchmark: (1) single-process `tessera render` vs `render --workers 1` and `--workers 2`: (1a) the throughput
# ratio of a 2-second render, (1b) the fixed cost of a farm render (start, submission, result hand-over, stop) from a
# one-tile render, (1c) the per-tile tax from a render long enough for the fixed cost to be small, with and without
# it; (2) a farm tile-size sweep 16..256 with 2 workers, (3) for a 3840x2160 image, the time from the start of the
# last tile's upload to the merged EXR on the coordinator's disk and to the client's output file.
# Usage: bench/farm_bench.sh BUILD_DIR [COURSE_DIR]   (prints a report; wall-clock times, so run it on a quiet machine)
set -euo pipefail
BUILD=${1:?usage: farm_bench.sh BUILD_DIR [COURSE_DIR]}
COURSE=${2:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" farm
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }

echo "tessera farm benchmark, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo
# rows REPS SCENE: times `render` single-process and with --workers 1 and 2 (farm tile 64), REPS times, the
# rows alternating so that a passing load spike does not decide a ratio; sets S_single, S_1, S_2 (best of REPS) and
# checks every farm output against the single-process one.
best() { awk 'NR == 1 || $1 < m { m = $1 } END { printf "%.3f", m }'; }
rows() {
  local reps=$1 scene=$2 t0 t1
  declare -A T_ROW=()
  for _ in $(seq "$reps"); do
    t0=$(now); "$T" render "$scene" -o "$WORK/single.exr" -q 2>/dev/null; t1=$(now)
    T_ROW[single]+="$(secs "$t0" "$t1")"$'\n'
    for n in 1 2; do
      t0=$(now); "$T" render "$scene" -o "$WORK/farm$n.exr" -q --workers $n --farm-tile 64 2>/dev/null; t1=$(now)
      T_ROW[$n]+="$(secs "$t0" "$t1")"$'\n'
      "$BUILD/tests/exr_compare" "$WORK/single.exr" "$WORK/farm$n.exr" >/dev/null || echo "  (warning: --workers $n output differs!)"
    done
  done
  S_single=$(printf "%s" "${T_ROW[single]}" | best)
  S_1=$(printf "%s" "${T_ROW[1]}" | best)
  S_2=$(printf "%s" "${T_ROW[2]}" | best)
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; }

echo "== 1. single process vs local farm (textured cbox, farm tile 64)"
scene a 640 480 32
scene one 64 48 1
scene long 640 480 256
rows 5 "$WORK/a/scene.json"
echo "  1a. 640x480, 32 spp, 80 tiles (best of 5, rows alternating; load average $(cut -d' ' -f1-3 /proc/loadavg))"
printf "    %-16s %8ss  1.000x\n" "single process" "$S_single"
for n in 1 2; do v=S_$n; printf "    %-16s %8ss  %sx throughput\n" "--workers $n" "${!v}" "$(ratio "$S_single" "${!v}")"; done
rows 5 "$WORK/one/scene.json"
echo "  1b. fixed cost: 64x48, 1 spp, one tile (best of 5, rows alternating; load average $(cut -d' ' -f1-3 /proc/loadavg))"
printf "    %-16s %8ss\n" "single process" "$S_single"
for n in 1 2; do
  v=S_$n
  printf "    %-16s %8ss  fixed cost %ss\n" "--workers $n" "${!v}" "$(awk -v a="$S_single" -v b="${!v}" 'BEGIN { printf "%.3f", b - a }')"
done
F_1=$(awk -v a="$S_single" -v b="$S_1" 'BEGIN { print b - a }') F_2=$(awk -v a="$S_single" -v b="$S_2" 'BEGIN { print b - a }')
rows 3 "$WORK/long/scene.json"
echo "  1c. per-tile tax: 640x480, 256 spp, 80 tiles (best of 3, rows alternating; load average $(cut -d' ' -f1-3 /proc/loadavg))"
printf "    %-16s %8ss  1.000x\n" "single process" "$S_single"
for n in 1 2; do
  v=S_$n f=F_$n
  printf "    %-16s %8ss  %sx throughput; without the fixed cost %sx, %s ms per tile\n" "--workers $n" "${!v}" \
    "$(ratio "$S_single" "${!v}")" "$(awk -v a="$S_single" -v b="${!v}" -v f="${!f}" 'BEGIN { printf "%.3f", a / (b - f) }')" \
    "$(awk -v a="$S_single" -v b="${!v}" -v f="${!f}" 'BEGIN { printf "%.1f", 1000 * (b - f - a) / 80 }')"
done
echo
echo "== 2. farm tile-size sweep (cbox 640x480, 32 spp, --workers 2)"
for tile in 16 32 64 128 256; do
  t0=$(now); "$T" render "$WORK/a/scene.json" -o "$WORK/sweep.exr" -q --workers 2 --farm-tile $tile 2>/dev/null; t1=$(now)
  tiles=$(( ((640 + tile - 1) / tile) * ((480 + tile - 1) / tile) ))
  printf "  tile %4d: %5d tiles  %8ss\n" $tile $tiles "$(secs "$t0" "$t1")"
done

echo
echo "== 3. 3840x2160, 1 spp, tile 256, 2 workers: last upload -> EXR on disk"
scene big 3840 2160 1
start_serve
for i in 1 2; do
  "$T" worker --coordinator "$URL" --threads 1 --cache "$WORK/cache" --name "bench-$i" >"$WORK/worker$i.log" 2>&1 &
  PIDS+=($!)
done
t0=$(now)
"$T" submit "$WORK/big/scene.json" --coordinator "$URL" --tile 256 -o "$WORK/big.exr" -q >"$WORK/submit.log" 2>&1
t1=$(now)
# The last tile's upload starts right after its "rendered in" line; log times are local wall-clock milliseconds.
last=$(grep -h "rendered in" "$WORK"/worker*.log | sed -E 's/^\[([^]]+)\].*/\1/' | sort | tail -n1)
last_s=$(date -d "$last" +%s.%N)
result=$(ls "$WORK"/data/jobs/*/result.exr)
printf "  total submit -> output:                 %8ss\n" "$(secs "$t0" "$t1")"
printf "  last upload start -> coordinator's EXR: %8ss  (%s bytes)\n" "$(secs "$last_s" "$(stat -c %.9Y "$result")")" \
  "$(stat -c %s "$result")"
printf "  last upload start -> client's -o file:  %8ss  (the client follows the job's events: the result's download and write)\n" \
  "$(secs "$last_s" "$(stat -c %.9Y "$WORK/big.exr")")"
