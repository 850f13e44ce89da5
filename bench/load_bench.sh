#!/usr/bin/env bash
# Load benchmark: the coordinator's status endpoints under load while jobs render on the same machine.
# Starts `tessera serve` with client and worker tokens, two workers (one thread each), submits 8 jobs (textured
# Cornell box 320x240, 16 spp, tile 32) and, while they render, runs bench/load_client with C connections for S seconds
# against /healthz, a job's status, the job list and /metrics. Prints requests/s and p50/p99 latency per endpoint.
# Usage: bench/load_bench.sh BUILD_DIR [COURSE_DIR] [CONNECTIONS] [SECONDS]
set -euo pipefail
BUILD=${1:?usage: load_bench.sh BUILD_DIR [COURSE_DIR] [CONNECTIONS] [SECONDS]}
COURSE=${2:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
CONNS=${3:-16}
SECS=${4:-10}
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" load

head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/client.token"
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/worker.token"
chmod 600 "$WORK"/*.token
scene scene 320 240 16

start_serve --client-token-file "$WORK/client.token" --worker-token-file "$WORK/worker.token"
for i in 1 2; do
  "$T" worker --coordinator "$URL" --threads 1 --cache "$WORK/cache" --token-file "$WORK/worker.token" \
    >"$WORK/worker$i.log" 2>&1 &
  PIDS+=($!)
done
export TESSERA_CLIENT_TOKEN
TESSERA_CLIENT_TOKEN=$(cat "$WORK/client.token")
JOB=""
for i in $(seq 8); do
  id=$("$T" submit "$WORK/scene/scene.json" --coordinator "$URL" --tile 32 --seed "$i" --detach 2>/dev/null)
  JOB=${JOB:-$id}
done

echo "tessera load benchmark, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "coordinator + 2 workers (1 thread each) rendering 8 jobs while the load runs; $CONNS connections, ${SECS} s"
cpu0=$(awk '{print $14 + $15}' "/proc/$SERVE_PID/stat")
"$BUILD/bench/load_client" --url "$URL" --connections "$CONNS" --seconds "$SECS" --token-file "$WORK/client.token" \
  /healthz "/v1/jobs/$JOB" /v1/jobs /metrics
cpu1=$(awk '{print $14 + $15}' "/proc/$SERVE_PID/stat")
echo "coordinator CPU during the run: $(awk -v a="$cpu0" -v b="$cpu1" -v s="$SECS" -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%.0f%%", 100 * (b - a) / hz / s }') of one core"
done_tiles=$(curl -s -H "Authorization: Bearer $TESSERA_CLIENT_TOKEN" "$URL/v1/jobs" | python3 -c 'import json,sys; print(sum(j["tiles"]["done"] for j in json.load(sys.stdin)["jobs"]))')
echo "tiles merged meanwhile: $done_tiles"
