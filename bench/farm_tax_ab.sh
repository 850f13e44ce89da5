#!/usr/bin/env bash
# shellcheck disable=SC2034  # A and B are read as ${!which}, COURSE by bench_common.sh
# Two tessera binaries side by side on a private farm's overhead: `render --workers 1` of farm_bench.sh's 1a scene
# (the course's textured box at 640x480, 32 spp, 80 tiles of 64 px), A and B alternating N times with A's single
# process between them. Besides wall time it reads the machine's CPU time from /proc/stat around each run: the busy
# seconds (user + system of every process, both CPUs) and the idle ones. The busy time a farm spends beyond the single
# process is its work (coordinator, parent, worker's requests and encoding); its extra idle time is waiting. Both
# vary less from run to run on a shared VM than wall time does. For commit messages of changes to the farm's per-tile
# path.
#   bash bench/farm_tax_ab.sh OLD/tessera NEW/tessera [N] [COURSE_DIR]      (N = 8)
set -euo pipefail
A=${1:?usage: farm_tax_ab.sh TESSERA_A TESSERA_B [N] [COURSE_DIR]}
B=${2:?usage: farm_tax_ab.sh TESSERA_A TESSERA_B [N] [COURSE_DIR]}
N=${3:-8}
COURSE=${4:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
BUILD=$(dirname "$(dirname "$B")")  # bench_common.sh wants a build folder; only its scene() and WORK are used here
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" farm-tax
scene a 640 480 32
# idle (idle + iowait) and busy (user + nice + system + irq + softirq) ticks of all CPUs, in USER_HZ (100 per second)
ticks() { awk '/^cpu / { print $5 + $6, $2 + $3 + $4 + $7 + $8 }' /proc/stat; }
ROWS=""
for _ in $(seq "$N"); do
  for which in single A B; do
    read -r idle0 busy0 < <(ticks)
    t0=$(date +%s.%N)
    if [ "$which" = single ]; then
      "$A" render "$WORK/a/scene.json" -o "$WORK/single.exr" -q 2>/dev/null
    else
      "${!which}" render "$WORK/a/scene.json" -o "$WORK/out-$which.exr" -q --workers 1 --farm-tile 64 2>/dev/null
    fi
    t1=$(date +%s.%N)
    read -r idle1 busy1 < <(ticks)
    ROWS+="$which $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }') $((idle1 - idle0)) $((busy1 - busy0))"$'\n'
  done
done
for which in A B; do
  "$BUILD/tests/exr_compare" "$WORK/single.exr" "$WORK/out-$which.exr" >/dev/null || echo "warning: $which's image differs from the single process's"
done
echo "farm_tax_ab: render --workers 1 of a 640x480 32-spp textured box (80 tiles), $N runs each alternating with the single process; load $(cut -d' ' -f1-3 /proc/loadavg)"
printf "%s" "$ROWS" | awk -v a="$A" -v b="$B" '
  { wall[$1] += $2; idle[$1] += $3 / 100; busy[$1] += $4 / 100; n[$1]++ }
  END {
    name["single"] = "single process (A)"; name["A"] = "A " a; name["B"] = "B " b
    for (i = 1; i <= 3; i++) {
      k = (i == 1) ? "single" : (i == 2) ? "A" : "B"
      printf "  %-40s mean wall %.3f s, busy %.3f CPU-s, idle %.3f CPU-s", name[k], wall[k] / n[k], busy[k] / n[k], idle[k] / n[k]
      if (k != "single")
        printf "; %.3fx the single process'"'"'s throughput, %+.3f CPU-s busy and %+.3f idle beyond it", (wall["single"] / n["single"]) / (wall[k] / n[k]),
               (busy[k] - busy["single"]) / n[k], (idle[k] - idle["single"]) / n[k]
      printf "\n"
    }
  }'
