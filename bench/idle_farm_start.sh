#!/usr/bin/env bash
# shellcheck disable=SC2034  # A and B are read as ${!which}
# How long a job takes on an idle farm, two tessera binaries one after the other: for each, one coordinator (`serve
# --durability process`, tokens) and one 2-thread worker on this machine; N times the worker idles IDLE seconds (long
# enough to reach its 2-s polling backoff) and a 1-spp render of scenes/cbox_area_light.json is submitted with -o;
# prints each submission's wall time (submit to result file). For changes to how idle workers learn of new work.
#   bash bench/idle_farm_start.sh OLD/tessera NEW/tessera [N] [IDLE]      (N = 6, IDLE = 4.3)
set -euo pipefail
A=${1:?usage: idle_farm_start.sh TESSERA_A TESSERA_B [N] [IDLE]}
B=${2:?usage: idle_farm_start.sh TESSERA_A TESSERA_B [N] [IDLE]}
N=${3:-6}
IDLE=${4:-4.3}
SCENE=$(cd "$(dirname "$0")/.." && pwd)/scenes/cbox_area_light.json
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-idle-start.XXXXXX")
PIDS=()
cleanup() {
  [ ${#PIDS[@]} -gt 0 ] && kill "${PIDS[@]}" 2>/dev/null
  wait 2>/dev/null
  rm -rf "$WORK"
}
trap cleanup EXIT
echo "idle_farm_start: $N submissions per binary after ${IDLE} s idle each; load $(cut -d' ' -f1-3 /proc/loadavg)"
for which in A B; do
  bin=${!which}
  dir="$WORK/$which"
  mkdir -p "$dir"
  (umask 077 && head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$dir/client.token" &&
    head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$dir/worker.token")
  "$bin" serve --listen 127.0.0.1:0 --ready-file "$dir/ready" --data "$dir/data" --durability process \
    --client-token-file "$dir/client.token" --worker-token-file "$dir/worker.token" >"$dir/serve.log" 2>&1 &
  PIDS=($!)
  while [ ! -s "$dir/ready" ]; do sleep 0.01; done
  url="http://$(cat "$dir/ready")"
  "$bin" worker --coordinator "$url" --threads 2 --cache "$dir/cache" --name idle --token-file "$dir/worker.token" \
    >"$dir/worker.log" 2>&1 &
  PIDS+=($!)
  times=""
  for _ in $(seq "$N"); do
    sleep "$IDLE"
    t0=$(date +%s.%N)
    "$bin" submit "$SCENE" --coordinator "$url" --token-file "$dir/client.token" --spp 1 -o "$dir/out.exr" -q 2>/dev/null
    t1=$(date +%s.%N)
    times+=" $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')"
  done
  kill "${PIDS[@]}"
  wait 2>/dev/null || true
  PIDS=()
  echo "  $which $bin: submit to result$times s"
done
