#!/usr/bin/env bash
# Webhook receivers that never answer against the scheduler: bench/sim_workers --hanging-webhooks runs the same
# simulated-worker load four times, A B A B (A: no webhooks; B: serve --webhook to a receiver that accepts connections
# and never answers, with at least 100 deliveries pending), and prints tiles/s and the p99 of lease and upload requests
# for each and B / A.
# Writes the report, with its header (commit, machine, flags, load average), to stdout.
# Usage: bench/webhook_hang_bench.sh BUILD_DIR [WORKERS] [SECONDS]
set -euo pipefail
BUILD=${1:?usage: webhook_hang_bench.sh BUILD_DIR [WORKERS] [SECONDS]}
WORKERS=${2:-200}
SECS=${3:-15}
FLAGS=(--tessera "$BUILD/cli/tessera" --workers "$WORKERS" --tile-seconds 0.5 --seconds "$SECS" --warmup 6
       --heartbeat-seconds 5 --hanging-webhooks 100)
commit=$(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)
git -C "$(dirname "$0")" diff --quiet HEAD -- 2>/dev/null || commit="$commit (modified)"
cpu=$(awk -F': ' '/^model name/ {print $2; exit}' /proc/cpuinfo)
echo "# Hanging webhook receivers against the scheduler: bench/webhook_hang_bench.sh"
echo "# commit $commit, $(date -u '+%F %H:%M UTC'); machine: $(nproc) cores ($cpu), load average at the start:" \
     "$(cut -d' ' -f1-3 /proc/loadavg) (other processes share the cores; the variants alternate A B A B)"
echo "\$ $BUILD/bench/sim_workers ${FLAGS[*]}"
echo
"$BUILD/bench/sim_workers" "${FLAGS[@]}"
echo
echo "# load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
