#!/usr/bin/env bash
# Where the coordinator's CPU goes per tile: bench/sim_workers drives a real `tessera serve` with the capacity bench's
# command (bench/results/capacity.txt) while `perf record -g` samples the coordinator for 8 s inside the measured
# window; bench/perf_breakdown.py sorts the samples into costs and gives each in ms per tile (the bench's own
# coordinator CPU per tile, printed above the breakdown). Needs perf, and a build with frame pointers so that the
# coordinator's own frames show their callers:
#   cmake -S . -B build-prof -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS=-fno-omit-frame-pointer
#   ninja -C build-prof tessera sim_workers
# Usage: bench/coordinator_profile.sh BUILD_DIR [WORKERS]   (1000 simulated workers by default)
set -euo pipefail
SHOWN=${1:?usage: coordinator_profile.sh BUILD_DIR [WORKERS]}  # as given, for the report
BUILD=$(cd "$SHOWN" && pwd)
N=${2:-1000}
HERE=$(cd "$(dirname "$0")" && pwd)
command -v perf >/dev/null || { echo "coordinator_profile: perf is not installed" >&2; exit 1; }
WORK=$(mktemp -d)
SIM=""
cleanup() {
  if [[ -n "$SIM" ]] && kill -0 "$SIM" 2>/dev/null; then kill "$SIM" 2>/dev/null || true; wait "$SIM" 2>/dev/null || true; fi
  rm -rf "$WORK"
}
trap cleanup EXIT
echo "coordinator CPU per tile by cost, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$HERE" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "\$ ./$SHOWN/bench/sim_workers --tessera $SHOWN/cli/tessera --workers $N --tile-seconds 1 --seconds 10 --warmup 4 --heartbeat-seconds 5"
"$BUILD/bench/sim_workers" --tessera "$BUILD/cli/tessera" --workers "$N" --tile-seconds 1 --seconds 10 --warmup 4 \
  --heartbeat-seconds 5 >"$WORK/sim.txt" 2>&1 &
SIM=$!
sleep 5  # inside the window (4 s of warm-up)
SERVE=""
for child in $(pgrep -P "$SIM" || true); do
  if tr '\0' ' ' <"/proc/$child/cmdline" 2>/dev/null >"$WORK/cmd" && [[ "$(cat "$WORK/cmd")" == *" serve "* ]]; then SERVE=$child; fi
done
[[ -n "$SERVE" ]] || { echo "coordinator_profile: no tessera serve under sim_workers" >&2; cat "$WORK/sim.txt" >&2; exit 1; }
perf record -g -p "$SERVE" -o "$WORK/perf.data" -- sleep 8 >"$WORK/perf.log" 2>&1
wait "$SIM"
SIM=""
cat "$WORK/sim.txt"
MS=$(awk -v n="$N" '$1 == n && NF >= 11 { print $5 }' "$WORK/sim.txt")
echo
echo "The coordinator's samples by cost (the first cost whose functions are on a sample's stack; ms/tile from the"
echo "run above, $MS ms):"
perf script -i "$WORK/perf.data" 2>/dev/null >"$WORK/stacks.txt"
python3 "$HERE/perf_breakdown.py" "$WORK/stacks.txt" --ms-per-tile "${MS:-0}"
