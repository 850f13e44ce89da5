#!/usr/bin/env bash
# shellcheck disable=SC2034,SC2119  # A and B are read as ${!which}, COURSE by bench_common.sh; start_serve takes no flags here
# What round trips cost a submission: `tessera submit --detach` of farm_bench.sh's one-tile scene (the course's
# textured box: 9 assets) through a link of fixed latency (tests/soak/fault_proxy.py --latency, no faults) to a fresh
# coordinator of binary B, once with every asset missing and once more with all of them stored; clients A and B
# alternating, N rounds. Prints each submission's wall time.
#   bash bench/submit_latency.sh OLD/tessera NEW/tessera [ONE_WAY_SECONDS] [N] [COURSE_DIR]   (0.01 s, N = 3)
set -euo pipefail
A=${1:?usage: submit_latency.sh TESSERA_A TESSERA_B [ONE_WAY_SECONDS] [N] [COURSE_DIR]}
B=${2:?usage: submit_latency.sh TESSERA_A TESSERA_B [ONE_WAY_SECONDS] [N] [COURSE_DIR]}
LATENCY=${3:-0.01}
N=${4:-3}
COURSE=${5:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
BUILD=$(dirname "$(dirname "$B")")
PROXY="$(dirname "$0")/../tests/soak/fault_proxy.py"
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" submit-latency
scene one 64 48 1
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }
echo "submit_latency: submit --detach of a 9-asset scene through a link of ${LATENCY} s each way; coordinator $B;" \
  "load $(cut -d' ' -f1-3 /proc/loadavg)"
for round in $(seq "$N"); do
  for which in A B; do
    rm -rf "$WORK/data" "$WORK/ready" "$WORK/proxy-ready"
    start_serve
    python3 "$PROXY" --target "$(head -n1 "$WORK/ready")" --seed 1 --ready-file "$WORK/proxy-ready" \
      --stats-file "$WORK/proxy-stats" --faults-off "$WORK/no-such-file" --delay 0 --reset 0 --half-open 0 \
      --latency "$LATENCY" 2>/dev/null &
    PROXY_PID=$!
    PIDS+=("$PROXY_PID")
    for _ in $(seq 200); do [ -s "$WORK/proxy-ready" ] && break; sleep 0.05; done
    url="http://127.0.0.1:$(head -n1 "$WORK/proxy-ready")"
    t0=$(now)
    "${!which}" submit "$WORK/one/scene.json" --coordinator "$url" --detach -q >/dev/null
    t1=$(now)
    "${!which}" submit "$WORK/one/scene.json" --coordinator "$url" --detach -q >/dev/null
    t2=$(now)
    printf "  round %d, client %s: every asset missing %s s, all stored %s s\n" "$round" "$which" "$(secs "$t0" "$t1")" \
      "$(secs "$t1" "$t2")"
    kill -TERM "$PROXY_PID" "$SERVE_PID"
    wait "$PROXY_PID" "$SERVE_PID" 2>/dev/null || true
  done
done
echo "  A = $A, B = $B"
