#!/usr/bin/env bash
# Coordinator capacity (bench/results/capacity.txt): bench/sim_workers with 1000 and 2000 simulated workers on 1-s
# tiles against the build's `tessera serve`, ROUNDS times. With OTHER, another binary runs beside this build's,
# alternating (other, this) at each size, so that both meet the same load from other processes: `sim:PATH` another
# sim_workers (e.g. built from another commit) against this build's coordinator, for changes to the simulator;
# `tessera:PATH` another coordinator binary driven by this build's simulator, for changes to the coordinator. Prints
# the header (commit, machine, flags), then for every run the load average before it, tiles/s, lease and upload p99,
# the coordinator's and the simulator's CPU (share of a core, ms per accepted tile) and, for simulators that print it,
# the event loops' lag p99. The simulated workers ask for their next lease with each upload (sim_workers' default: one
# request per tile; its --two-requests is the other form).
# The coordinators keep their data under TMPDIR (default /tmp): TMPDIR=/dev/shm measures them without the disk.
#   bash bench/capacity_bench.sh BUILD_DIR [ROUNDS] [sim:PATH | tessera:PATH]      (ROUNDS = 2)
set -euo pipefail
USAGE="usage: capacity_bench.sh BUILD_DIR [ROUNDS] [sim:PATH | tessera:PATH]"
BUILD=${1:?$USAGE}
ROUNDS=${2:-2}
OTHER=${3:-}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
case "$OTHER" in
  "") ;;
  sim:* | tessera:*) [[ -x "${OTHER#*:}" ]] || { echo "capacity_bench: ${OTHER#*:} is not an executable" >&2; exit 2; } ;;
  *) echo "capacity_bench: OTHER must be sim:PATH or tessera:PATH ($USAGE)" >&2; exit 2 ;;
esac
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-capacity.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
FLAGS=(--tile-seconds 1 --seconds 10 --warmup 4 --heartbeat-seconds 5)

# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header capacity "$ROOT" "$BUILD"
echo "command: bash bench/capacity_bench.sh $BUILD $ROUNDS${OTHER:+ $OTHER}; each run:"
echo "\$ $BUILD/bench/sim_workers --tessera $BUILD/cli/tessera --workers N ${FLAGS[*]}"
echo "(the simulated workers ask for their next lease with each upload: one request per tile)"
echo "coordinators' data folders under ${TMPDIR:-/tmp} ($(stat -f -c %T "${TMPDIR:-/tmp}") file system; TMPDIR=DIR puts them elsewhere)"
case "$OTHER" in
  sim:*) echo "other: ${OTHER#sim:} as the simulator (same flags, same coordinator binary)" ;;
  tessera:*) echo "other: ${OTHER#tessera:} as the coordinator ($("${OTHER#tessera:}" --version); same simulator and flags)" ;;
esac
echo
printf "| %5s | %-5s | %4s | %-14s | %8s | %12s | %12s | %16s | %16s | %12s | %6s |\n" round run N "load (1/5/15)" \
  tiles/s "lease p99 ms" "upld p99 ms" "coord CPU, ms/t" "sim CPU, ms/t" "lag p99 ms" errors
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for round in $(seq "$ROUNDS"); do
  for n in 1000 2000; do
    # Each run: name, simulator, coordinator.
    runs=("this $BUILD/bench/sim_workers $BUILD/cli/tessera")
    case "$OTHER" in
      sim:*) runs=("other ${OTHER#sim:} $BUILD/cli/tessera" "${runs[@]}") ;;
      tessera:*) runs=("other $BUILD/bench/sim_workers ${OTHER#tessera:}" "${runs[@]}") ;;
    esac
    for entry in "${runs[@]}"; do
      read -r name sim coordinator <<<"$entry"
      load=$(cut -d' ' -f1-3 /proc/loadavg)
      "$sim" --tessera "$coordinator" --workers "$n" "${FLAGS[@]}" >"$WORK/run.txt" 2>&1 ||
        { cat "$WORK/run.txt" >&2; exit 1; }
      # The row of N: N tiles/s ideal/s coord-CPU% ms/tile client% lease-p50 lease-p99 upld-p50 upld-p99 errors
      # [client ms/tile, lag p99] (the last two only from simulators that print them).
      awk -v n="$n" -v r="$round" -v s="$name" -v load="$load" '$1 == n && NF >= 11 {
            client = $6 + 0; coord = $4 + 0
            printf "| %5s | %-5s | %4d | %-14s | %8.1f | %12.2f | %12.2f | %6.1f%%, %6.3f | %6.1f%%, %6.3f | %12s | %6d |\n",
                   r, s, n, load, $2, $8, $10, coord, $5, client, ($2 > 0 ? 10 * client / $2 : 0),
                   (NF >= 13 ? $13 : "-"), $11 }' "$WORK/run.txt"
    done
  done
done
echo
echo "load (1/5/15): /proc/loadavg before the run; CPU: utime+stime over the 10-s window (100% = one core); ms/t: that"
echo "CPU per accepted tile; lag p99: how late the simulator's event loops ran its workers' naps after their due time."
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
