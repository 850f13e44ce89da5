#!/usr/bin/env bash
# A shared farm (docs/protocol.md, "Sharing the farm"): WORKERS simulated workers with 1-s tiles; user ana submits a
# 10,000-tile job at the start and user ben a 200-tile job every minute. Two runs of SECONDS each: two users with
# equal weights, then both jobs submitted as one user (strict priority, then age). Each prints the tile rate, each
# user's part of the worker time while ben has work, and the time to each small job's first tile.
# usage: bench/fair_share_bench.sh [BUILD_DIR] [WORKERS] [SECONDS]
set -euo pipefail
BUILD=${1:-build}
WORKERS=${2:-16}
SECONDS_=${3:-600}
for mode in "" --one-user; do
  echo "## ${mode:-two users}"
  "$BUILD/bench/sim_workers" --tessera "$BUILD/cli/tessera" --share $mode --workers "$WORKERS" --seconds "$SECONDS_" \
    --warmup 5 --tile-seconds 1 --tile 16 --big-tiles-edge 100 --small-tiles 200 --small-every 60
  echo
done
