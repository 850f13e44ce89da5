#!/usr/bin/env bash
# Sequences: (1) a FRAMES-frame sequence (scenes/tools/make_sequence.py, 128x128) rendered one frame after another in
# one process with 2 threads, against the same frames through 2 local workers of 1 thread each (render --workers 2),
# in order and with --frame-order any, alternating for ROUNDS rounds (their medians compared), with each wall time and
# the time per frame spent outside rendering (wall time minus the frames' own render times, per frame); (2) a 10,000-frame sequence (16x16 frames)
# submitted to a coordinator: the submission's time (its assets already uploaded), `jobs ls` and `jobs frames` times,
# and the database's size per frame. Every frame of the two renders is checked bitwise against the first.
# usage: bench/sequence_bench.sh [BUILD_DIR] [FRAMES] [SPP] [ROUNDS]
set -euo pipefail
BUILD=${1:-build}
FRAMES=${2:-240}
SPP=${3:-4}
ROUNDS=${4:-5}
SOURCE=$(cd "$(dirname "$0")/.." && pwd)
COURSE="$SOURCE/scenes/course"
# shellcheck source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" sequence
now() { date +%s.%N; }

python3 "$SOURCE/scenes/tools/make_sequence.py" "$WORK/seq" --frames "$FRAMES" --resolution 128 --spp "$SPP" >/dev/null
PATTERN="$WORK/seq/frame_####.json"
echo "# $FRAMES frames of 128x128 at $SPP spp (cbox_gi camera move), 2 cores; $ROUNDS rounds, the three ways alternating"
printf "| round | one process, 2 threads (s) | --workers 2 in_order (s) | --workers 2 any (s) |\n|---|---|---|---|\n"
declare -A ALL
for run in $(seq "$ROUNDS"); do
  for mode in single in_order any; do
    rm -rf "$WORK/$mode" && mkdir -p "$WORK/$mode"
    t0=$(now)
    if [ "$mode" = single ]; then
      "$T" render "$PATTERN" --frames "1-$FRAMES" --threads 2 -o "$WORK/$mode/f_####.exr" >"$WORK/$mode.log" 2>&1
    else
      "$T" render "$PATTERN" --frames "1-$FRAMES" --workers 2 --threads 1 --frame-order "$mode" -q \
        -o "$WORK/$mode/f_####.exr" >"$WORK/$mode.log" 2>&1
    fi
    t1=$(now)
    eval "T_$mode=$(echo "$t1 - $t0" | bc -l)"
    ALL[$mode]+="$(echo "$t1 - $t0" | bc -l) "
  done
  for f in "$WORK"/single/f_*.exr; do
    for mode in in_order any; do
      "$BUILD/tests/exr_compare" "$f" "$WORK/$mode/$(basename "$f")" >/dev/null || { echo "frame $f differs ($mode)"; exit 1; }
    done
  done
  # Outside rendering, one process: its wall time less the frames' own render times (the summary lines' "render").
  RENDER=$(grep -Eo '[0-9.]+s render' "$WORK/single.log" | awk '{s += $1} END {print s}')
  printf "| %d | %.2f (%.1f ms/frame outside rendering) | %.2f | %.2f |\n" "$run" "$T_single" \
    "$(echo "($T_single - $RENDER) * 1000 / $FRAMES" | bc -l)" "$T_in_order" "$T_any"
done
median() { tr ' ' '\n' | grep . | sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
M_single=$(echo "${ALL[single]}" | median)
M_in_order=$(echo "${ALL[in_order]}" | median)
M_any=$(echo "${ALL[any]}" | median)
printf "\nmedians: one process %.2f s, --workers 2 in_order %.2f s (%.3fx), any %.2f s (%.3fx)\n" "$M_single" \
  "$M_in_order" "$(echo "$M_in_order / $M_single" | bc -l)" "$M_any" "$(echo "$M_any / $M_single" | bc -l)"

echo
echo "# A 10,000-frame sequence (16x16 frames) submitted to a coordinator (--durability machine)"
python3 "$SOURCE/scenes/tools/make_sequence.py" "$WORK/big" --frames 10000 --resolution 16 --spp 1 >/dev/null
start_serve --max-json-bytes 64000000 --max-queued-jobs 10
"$T" submit "$WORK/big/frame_00001.json" --coordinator "$URL" --detach >/dev/null 2>&1  # uploads the assets
t0=$(now)
JOB=$("$T" submit "$WORK/big/frame_#####.json" --frames 1-10000 --coordinator "$URL" --detach 2>"$WORK/submit.log")
t1=$(now)
"$T" jobs ls --coordinator "$URL" >/dev/null; t2=$(now)
"$T" jobs frames "$JOB" --coordinator "$URL" >/dev/null; t3=$(now)
DB=$(du -cb "$WORK"/data/tessera.db* | tail -n1 | cut -f1)
printf "submit (read 10,000 files, hash, send, check, store): %.2f s; jobs ls: %.3f s; jobs frames (10,000 lines): %.2f s\n" \
  "$(echo "$t1 - $t0" | bc -l)" "$(echo "$t2 - $t1" | bc -l)" "$(echo "$t3 - $t2" | bc -l)"
printf "database: %d bytes, %.0f bytes per frame\n" "$DB" "$(echo "$DB / 10000" | bc -l)"
grep -Eo "submitted sequence .*" "$WORK/serve.log" | head -n1 || true
