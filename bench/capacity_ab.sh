#!/usr/bin/env bash
# Two coordinators side by side at the capacity bench's command: bench/sim_workers against each binary's `tessera
# serve` (durable, --durability machine), A B A B..., each run at every farm size; prints the run's header, the load
# average before each run and each run's table. For changes to the coordinator's cost per tile.
#   bash bench/capacity_ab.sh BUILD TESSERA_A TESSERA_B [ROUNDS] [WORKERS]      (ROUNDS = 2, WORKERS = 1000,2000)
set -euo pipefail
BUILD=${1:?usage: capacity_ab.sh BUILD TESSERA_A TESSERA_B [ROUNDS] [WORKERS]}
A=${2:?usage: capacity_ab.sh BUILD TESSERA_A TESSERA_B [ROUNDS] [WORKERS]}
B=${3:?usage: capacity_ab.sh BUILD TESSERA_A TESSERA_B [ROUNDS] [WORKERS]}
ROUNDS=${4:-2}
WORKERS=${5:-1000,2000}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header capacity_ab "$ROOT" "$BUILD"
echo "A: $A ($("$A" --version))"
echo "B: $B ($("$B" --version))"
echo "\$ $BUILD/bench/sim_workers --tessera A|B --workers $WORKERS --tile-seconds 1 --seconds 10 --warmup 4 --heartbeat-seconds 5"
echo "(simulator and coordinator share this machine's cores with whatever else runs: see the load before each run)"
for round in $(seq "$ROUNDS"); do
  for which in A B; do
    echo
    echo "== round $round, $which; load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
    "$BUILD/bench/sim_workers" --tessera "${!which}" --workers "$WORKERS" --tile-seconds 1 --seconds 10 --warmup 4 \
      --heartbeat-seconds 5 2>&1 | sed -n '/^ *N  *tiles/,/^$/p'
  done
done
