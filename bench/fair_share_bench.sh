#!/usr/bin/env bash
# A shared farm (docs/protocol.md, "Sharing the farm"), with simulated workers (bench/sim_workers --share):
# (1) WORKERS workers with 1-s tiles; user ana submits a 10,000-tile job at the start and user ben a 200-tile job every
#     minute, for SECONDS: two users with equal weights, then both jobs submitted as one user (strict priority, then
#     age). Each prints the tile rate, each user's part of the worker time while ben has work, and the time to each
#     small job's first tile.
# (2) The coordinator's own rate with 1000 workers on 1-s tiles (a 90,000-tile job and a 200-tile job every 5 s), two
#     users against one user, alternating for ROUNDS rounds of 30 s: the cost of choosing by share.
# usage: bench/fair_share_bench.sh [BUILD_DIR] [WORKERS] [SECONDS] [ROUNDS]
set -euo pipefail
BUILD=${1:-build}
WORKERS=${2:-16}
SECONDS_=${3:-600}
ROUNDS=${4:-2}
SIM=("$BUILD/bench/sim_workers" --tessera "$BUILD/cli/tessera" --share --tile-seconds 1 --tile 16 --small-tiles 200)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header fair_share "$ROOT" "$BUILD"
echo "command: bash bench/fair_share_bench.sh $BUILD $WORKERS $SECONDS_ $ROUNDS"
echo
for mode in "" --one-user; do
  echo "## (1) ${mode:-two users}"
  "${SIM[@]}" $mode --workers "$WORKERS" --seconds "$SECONDS_" --warmup 5 --big-tiles-edge 100 --small-every 60
  echo
done
for round in $(seq "$ROUNDS"); do
  for mode in "" --one-user; do
    echo "## (2) round $round, ${mode:-two users}"
    "${SIM[@]}" $mode --workers 1000 --seconds 30 --warmup 10 --big-tiles-edge 300 --small-every 5 | sed -n '3,5p'
  done
done
