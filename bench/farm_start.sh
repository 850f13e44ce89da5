#!/usr/bin/env bash
# What a private farm adds to a render: `tessera render --threads 1 SCENE` (one process) and
# `tessera render --workers 1 --threads 1 SCENE` (a private coordinator and one worker), N alternating pairs; prints
# each pair's wall times and their difference, then the median and minimum of each column, and of each side's CPU time
# (user + system of the command with its coordinator and worker, from /usr/bin/time: on a machine shared with other
# work it varies less than wall time), checking that the two images have the same pixels.
#   bash bench/farm_start.sh BUILD_DIR [N] [SCENE]      (N = 11, SCENE = scenes/cbox_area_light.json; SPP=n renders at
#                                                        n spp instead of the scene's)
set -euo pipefail
BUILD=${1:?usage: farm_start.sh BUILD_DIR [N] [SCENE]}
N=${2:-11}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SCENE=${3:-$ROOT/scenes/cbox_area_light.json}
T="$BUILD/cli/tessera"
[ -x /usr/bin/time ] || { echo "farm_start: needs /usr/bin/time (Debian package time)" >&2; exit 2; }
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-farm-start.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
now() { date +%s.%N; }
ms() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", 1000 * (b - a) }'; }

# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header farm_start "$ROOT" "$BUILD"
spp=()
[ -n "${SPP:-}" ] && spp=(--spp "$SPP")
echo "command: ${SPP:+SPP=$SPP }bash bench/farm_start.sh $BUILD $N ${SCENE#"$ROOT"/}"
echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
printf "  %4s  %12s  %12s  %12s  %14s  %14s\n" pair "single ms" "workers 1 ms" "difference" "single CPU ms" "workers 1 CPU"
for i in $(seq "$N"); do
  # Odd pairs run the single process first, even pairs the farm, so that neither always follows the other.
  for side in $([ $((i % 2)) -eq 1 ] && echo "single farm" || echo "farm single"); do
    extra=(${spp[@]+"${spp[@]}"})
    [ "$side" = farm ] && extra+=(--workers 1)
    t0=$(now)
    /usr/bin/time -o "$WORK/cpu" -f "%U %S" "$T" render "$SCENE" -o "$WORK/$side.exr" -q --threads 1 \
      ${extra[@]+"${extra[@]}"} 2>/dev/null
    t1=$(now)
    printf -v "ms_$side" "%s" "$(ms "$t0" "$t1")"
    printf -v "cpu_$side" "%s" "$(awk '{ printf "%.0f", 1000 * ($1 + $2) }' "$WORK/cpu")"
  done
  # shellcheck disable=SC2154  # set by printf -v above
  d=$(awk -v s="$ms_single" -v f="$ms_farm" 'BEGIN { printf "%.1f", f - s }')
  # shellcheck disable=SC2154
  printf "  %4d  %12s  %12s  %12s  %14s  %14s\n" "$i" "$ms_single" "$ms_farm" "$d" "$cpu_single" "$cpu_farm"
  echo "$ms_single $ms_farm $d $cpu_single $cpu_farm" >>"$WORK/pairs"
done
"$BUILD/tests/exr_compare" "$WORK/single.exr" "$WORK/farm.exr" >/dev/null && same="the same pixels" ||
  same="DIFFERENT PIXELS"
stats() {
  awk -v c="$1" '{ print $c }' "$WORK/pairs" | sort -g | awk '{ v[NR] = $1 } END {
    m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
    printf "median %7.1f ms  min %7.1f ms", m, v[1] }'
}
echo
echo "  single process        $(stats 1)"
echo "  --workers 1           $(stats 2)"
echo "  difference (per pair) $(stats 3)"
echo "  CPU, single process   $(stats 4)"
echo "  CPU, --workers 1      $(stats 5)"
echo "  images: $same"
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
