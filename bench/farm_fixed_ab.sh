#!/usr/bin/env bash
# shellcheck disable=SC2034  # A and B are read as ${!which}, COURSE by bench_common.sh
# Two tessera binaries side by side on a private farm's fixed cost: `render --workers 1` of farm_bench.sh's one-tile
# scene (the course's textured box at 64x48, 1 spp), A and B alternating N times; prints each binary's mean, median
# and minimum wall time. For commit messages of changes to the farm's start, submission, hand-over and stop.
#   bash bench/farm_fixed_ab.sh OLD/tessera NEW/tessera [N] [COURSE_DIR]      (N = 25)
set -euo pipefail
A=${1:?usage: farm_fixed_ab.sh TESSERA_A TESSERA_B [N] [COURSE_DIR]}
B=${2:?usage: farm_fixed_ab.sh TESSERA_A TESSERA_B [N] [COURSE_DIR]}
N=${3:-25}
COURSE=${4:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
BUILD=$(dirname "$(dirname "$B")")  # bench_common.sh wants a build folder; only its scene() and WORK are used here
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" farm-fixed
scene one 64 48 1
declare -A TIMES=([A]="" [B]="")
for _ in $(seq "$N"); do
  for which in A B; do
    bin=${!which}
    t0=$(date +%s.%N)
    "$bin" render "$WORK/one/scene.json" -o "$WORK/out-$which.exr" -q --workers 1 --farm-tile 64 2>/dev/null
    t1=$(date +%s.%N)
    TIMES[$which]+="$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')"$'\n'
  done
done
"$BUILD/tests/exr_compare" "$WORK/out-A.exr" "$WORK/out-B.exr" >/dev/null || echo "warning: the two binaries' images differ"
echo "farm_fixed_ab: render --workers 1 of a 64x48 1-spp textured box, $N runs each alternating; load $(cut -d' ' -f1-3 /proc/loadavg)"
for which in A B; do
  printf "%s" "${TIMES[$which]}" | sort -n | awk -v name="$which ${!which}" '
    { v[NR] = $1; s += $1 }
    END { m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
          printf "  %s: mean %.1f ms, median %.1f ms, min %.1f ms\n", name, 1000 * s / NR, 1000 * m, 1000 * v[1] }'
done
