#!/usr/bin/env bash
# Farm benchmark: (1) single-process `tessera render` vs `render --workers 1` and `--workers 2` (throughput ratio),
# (2) a farm tile-size sweep 16..256 with 2 workers, (3) for a 3840x2160 image, the time from the start of the last
# tile's upload to the merged EXR on the coordinator's disk and to the client's output file.
# Usage: bench/farm_bench.sh BUILD_DIR [SHARED_DIR]   (prints a report; wall-clock times, so run it on a quiet machine)
set -euo pipefail
BUILD=${1:?usage: farm_bench.sh BUILD_DIR [SHARED_DIR]}
SHARED=${2:-$(cd "$(dirname "$0")/../.." && pwd)/shared}
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" farm
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }

echo "tessera farm benchmark, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo
echo "== 1. single process vs local farm (cbox 640x480, 32 spp, farm tile 64)"
scene a 640 480 32
# best of 5 per row, the rows alternating, so that a passing load spike does not decide a ratio
best() { awk 'NR == 1 || $1 < m { m = $1 } END { printf "%.3f", m }'; }
declare -A T_ROW
for _ in 1 2 3 4 5; do
  t0=$(now); "$T" render "$WORK/a/scene.json" -o "$WORK/single.exr" -q 2>/dev/null; t1=$(now)
  T_ROW[single]+="$(secs "$t0" "$t1")"$'\n'
  for n in 1 2; do
    t0=$(now); "$T" render "$WORK/a/scene.json" -o "$WORK/farm$n.exr" -q --workers $n --farm-tile 64 2>/dev/null; t1=$(now)
    T_ROW[$n]+="$(secs "$t0" "$t1")"$'\n'
    "$BUILD/tests/exr_compare" "$WORK/single.exr" "$WORK/farm$n.exr" >/dev/null || echo "  (warning: --workers $n output differs!)"
  done
done
single=$(printf "%s" "${T_ROW[single]}" | best)
printf "  %-22s %8ss  1.00x   (best of 5; load average %s)\n" "single process" "$single" "$(cut -d' ' -f1-3 /proc/loadavg)"
for n in 1 2; do
  s=$(printf "%s" "${T_ROW[$n]}" | best)
  printf "  %-22s %8ss  %sx throughput\n" "--workers $n" "$s" "$(awk -v a="$single" -v b="$s" 'BEGIN { printf "%.2f", a / b }')"
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
"$T" serve --listen 127.0.0.1:0 --ready-file "$WORK/ready" --data "$WORK/data" >"$WORK/serve.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 200); do [ -s "$WORK/ready" ] && break; sleep 0.05; done
URL="http://$(cat "$WORK/ready")"
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
printf "  last upload start -> client's -o file:  %8ss  (includes the client's 200 ms status poll)\n" \
  "$(secs "$last_s" "$(stat -c %.9Y "$WORK/big.exr")")"
