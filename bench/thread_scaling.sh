#!/usr/bin/env bash
# Thread scaling of one render: the project's cbox_area_light at 1024x1024 and 64 spp on 1 thread and on every core
# (`render --timing`), printing where the wall time goes (load with the BVH build, film set-up, the threaded render
# and its idle thread time, the write) and the speed-up. Best of N per thread count (N = $RUNS, default 3).
# Usage: bench/thread_scaling.sh BUILD_DIR
set -euo pipefail
BUILD=${1:?usage: thread_scaling.sh BUILD_DIR}
COURSE=unused
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" threads
SCENES=$(cd "$(dirname "$0")/../scenes" && pwd)
RUNS=${RUNS:-3}
# Written beside the scene: its assets are named relative to its folder.
SCENE="$SCENES/.thread_scaling_$$.json"
trap 'rm -f "$SCENE"; cleanup' EXIT
python3 - "$SCENES/cbox_area_light.json" "$SCENE" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); s["film"]["resolution"] = [1024, 1024]; s["integrator"]["spp"] = 64
json.dump(s, open(sys.argv[2], "w"))
PY

echo "thread scaling, $(date -u +%FT%TZ), commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), nproc $(nproc), load average $(cut -d' ' -f1-3 /proc/loadavg)"
echo "scene: scenes/cbox_area_light.json at 1024x1024, 64 spp; best of $RUNS by wall time"
declare -A BEST
for threads in 1 "$(nproc)"; do
  best=""
  for _ in $(seq "$RUNS"); do
    line=$("$T" render "$SCENE" -o "$WORK/out.exr" -q --threads "$threads" --timing 2>&1 | grep '^timing:')
    total=$(echo "$line" | sed -E 's/.*= ([0-9.]+)s;.*/\1/')
    if [ -z "$best" ] || awk -v a="$total" -v b="${best%% *}" 'BEGIN { exit !(a < b) }'; then best="$total $line"; fi
  done
  BEST[$threads]=${best%% *}
  echo "  $threads thread(s): ${best#* }"
done
awk -v a="${BEST[1]}" -v b="${BEST[$(nproc)]}" -v n="$(nproc)" \
  'BEGIN { printf "speed-up on %d threads: %.2fx (efficiency %.0f%%)\n", n, a / b, 100 * a / b / n }'
