# Shared setup of the network-namespace farm tests (sourced after tests/farm/common.sh): a virtual LAN of separate
# network stacks on this machine, built here and removed on exit. One namespace holds a bridge (the "switch"); every
# host (coordinator c, workers w1..w3) is a namespace joined to it by a veth pair, with its own address in
# 10.77.0.0/24. Cutting a host's link (its switch port down) drops its packets without refusing them, as a real
# partition does. Where the kernel refuses namespaces for want of privilege (no root, no CAP_SYS_ADMIN / CAP_NET_ADMIN)
# the test exits 77 (ctest SKIP, which the test command counts as a failure unless allowed); any other failure to build
# the LAN is a failure.
# shellcheck shell=bash
# shellcheck source-path=SCRIPTDIR source=../lib/tls.sh
source "$(dirname "${BASH_SOURCE[0]}")/../lib/tls.sh"
# shellcheck source-path=SCRIPTDIR source=../lib/freeze.sh
source "$(dirname "${BASH_SOURCE[0]}")/../lib/freeze.sh"

NS=tsr$$-                 # namespace prefix, unique per test process
SWITCH=${NS}sw
NETNS_MADE=()
declare -A ADDR=([c]=10.77.0.1 [w1]=10.77.0.11 [w2]=10.77.0.12 [w3]=10.77.0.13)
COORD=${ADDR[c]}:8470     # the coordinator's address as workers see it

skip() {
  echo "SKIP: $*" >&2
  exit 77
}

remove_namespaces() {
  local n
  for n in "${NETNS_MADE[@]}"; do ip netns del "$n" 2>/dev/null || true; done
}

# Runs on exit: processes first (farm/common.sh's cleanup), then the namespaces.
netns_cleanup() {
  cleanup
  remove_namespaces
}
trap netns_cleanup EXIT

# need_privilege WHAT COMMAND...: runs the command; skips when the kernel refused it for want of privilege, fails
# (exit 1, with the command's error) for any other reason.
need_privilege() {
  local what=$1 err
  shift
  if err=$("$@" 2>&1); then return 0; fi
  if grep -qiE "operation not permitted|permission denied" <<<"$err"; then skip "cannot $what here: $err"; fi
  echo "FAIL: cannot $what: $err" >&2
  exit 1
}

command -v ip >/dev/null || { echo "FAIL: the ip command (iproute2) is not installed" >&2; exit 1; }
need_privilege "create network namespaces" ip netns add "$SWITCH"
NETNS_MADE+=("$SWITCH")
need_privilege "create a bridge in a network namespace" ip -n "$SWITCH" link add br0 type bridge
ip -n "$SWITCH" link set br0 up

# add_host NAME: namespace ${NS}NAME with eth0 at ADDR[NAME]/24 on the switch (port p-NAME) and loopback up.
add_host() {
  local name=$1 ns=${NS}$1
  ip netns add "$ns"
  NETNS_MADE+=("$ns")
  ip -n "$SWITCH" link add "p-$name" type veth peer name eth0 netns "$ns"
  ip -n "$SWITCH" link set "p-$name" master br0 up
  ip -n "$ns" addr add "${ADDR[$name]}/24" dev eth0
  ip -n "$ns" link set eth0 up
  ip -n "$ns" link set lo up
}

# cut NAME / reconnect NAME: the host's switch port down (its packets vanish) / up again.
cut() { ip -n "$SWITCH" link set "p-$1" down; }
reconnect() { ip -n "$SWITCH" link set "p-$1" up; }

# on NAME COMMAND...: runs the command inside the host's namespace (in the foreground: a function started with & runs
# in a subshell, so the starters below call `ip netns exec` themselves and $! is the process itself).
on() {
  local ns=${NS}$1
  shift
  ip netns exec "$ns" "$@"
}

# make_tls_files: a throwaway CA, the coordinator's certificate (IP SAN 10.77.0.1), a worker/client certificate and
# both tokens, in $WORK/tls; sets SERVE_TLS and CLIENT_TLS (flag arrays) for serve and for worker/submit.
make_tls_files() {
  local t=$WORK/tls
  mkdir -p "$t"
  make_ca "$t" ca
  make_cert "$t" ca coordinator "IP:${ADDR[c]}" serverAuth
  make_cert "$t" ca member "DNS:member" clientAuth
  head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$t/client.token"
  head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$t/worker.token"
  chmod 600 "$t/client.token" "$t/worker.token"
  SERVE_TLS=(--tls-cert "$t/coordinator.pem" --tls-key "$t/coordinator.key" --tls-client-ca "$t/ca.pem"
             --client-token-file "$t/client.token" --worker-token-file "$t/worker.token")
  CLIENT_TLS=(--ca-file "$t/ca.pem" --tls-cert "$t/member.pem" --tls-key "$t/member.key")
  WORKER_TOKEN_FILE=$t/worker.token
  CLIENT_TOKEN_FILE=$t/client.token
}

# serve_on NAME LISTEN [serve flags...]: the coordinator in host NAME (data in $DATA, default $WORK/data); sets
# SERVE_PID, waits until it listens.
serve_on() {
  local name=$1 listen=$2
  shift 2
  rm -f "$WORK/ready"
  ip netns exec "${NS}$name" "$TESSERA" serve --listen "$listen" --ready-file "$WORK/ready" --data "${DATA:-$WORK/data}" "$@" \
    >>"$WORK/serve.log" 2>&1 &
  SERVE_PID=$!
  PIDS+=("$SERVE_PID")
  serve_ready() { test -s "$WORK/ready" || ! kill -0 "$SERVE_PID" 2>/dev/null; }
  wait_for serve_ready && test -s "$WORK/ready" || fail "the coordinator did not become ready"
}

# worker_on HOST NAME URL [worker flags...]: a worker in HOST logging to $WORK/NAME.log; sets WORKER_PID.
worker_on() {
  local host=$1 name=$2 url=$3
  shift 3
  ip netns exec "${NS}$host" "$TESSERA" worker --coordinator "$url" --cache "$WORK/cache-$name" --name "$name" "$@" \
    >"$WORK/$name.log" 2>&1 &
  WORKER_PID=$!
  PIDS+=("$WORKER_PID")
}

# submit_on HOST LOG SCENE URL [submit flags...]: `tessera submit` in HOST in the background; sets SUBMIT_PID.
submit_on() {
  local host=$1 log=$2 scene=$3 url=$4
  shift 4
  ip netns exec "${NS}$host" "$TESSERA" submit "$scene" --coordinator "$url" "$@" >"$log" 2>&1 &
  SUBMIT_PID=$!
  PIDS+=("$SUBMIT_PID")
}

# count LOG PATTERN: how many lines of LOG match the extended regex.
count() { grep -Ec -- "$2" "$1" 2>/dev/null || true; }

# merged_once TILES: every tile 0..TILES-1 of the (only) job was merged exactly once, by the coordinator's log (a
# worker's log cannot tell: a request written before a cut can still arrive, and be merged, after the link returns).
merged_once() {
  local t n
  for t in $(seq 0 $(($1 - 1))); do
    n=$(count "$WORK/serve.log" "tile $t worker [^ ]+: merged")
    [ "$n" = 1 ] || fail "tile $t was merged $n times"
  done
}

# start_short_lease_farm SUBMIT_HOST: hosts c, w1, w2, w3 with TLS files; a 24x16 scene of 6 tiles of 8 px
# ($WORK/s.json) and its single-process render ($WORK/ref.exr); the coordinator on c with 2 s leases and 1 s
# heartbeats; the job submitted from SUBMIT_HOST in the background (SUBMIT_PID, result $WORK/out.exr). Sets URL,
# SUBMIT (submit flags) and WORKER (worker flags: 1 s connect and 2 s request timeouts, so cut-off requests fail fast).
start_short_lease_farm() {
  local h
  for h in c w1 w2 w3; do add_host "$h"; done
  make_tls_files
  write_sphere_scene "$WORK/s.json" 24 16 4
  "$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
  serve_on c "$COORD" "${SERVE_TLS[@]}" --lease-seconds 2 --heartbeat-seconds 1
  URL=https://$COORD
  SUBMIT=("${CLIENT_TLS[@]}" --token-file "$CLIENT_TOKEN_FILE" --tile 8 -q)
  WORKER=(--threads 2 "${CLIENT_TLS[@]}" --token-file "$WORKER_TOKEN_FILE" --connect-timeout-seconds 1
          --request-timeout-seconds 2)
  submit_on "$1" "$WORK/submit.log" "$WORK/s.json" "$URL" "${SUBMIT[@]}" -o "$WORK/out.exr"
}

# start_frozen_worker HOST NAME: a worker that leases a tile, renders it and freezes itself (SIGSTOP, see
# tests/lib/freeze.sh) before uploading; returns once it is frozen, holding the lease. Sets FROZEN_PID and
# FROZEN_TILE ("tile=N").
start_frozen_worker() {
  freeze_setup
  env "${FREEZE_ENV[@]}" ip netns exec "${NS}$1" "$FREEZE_BIN" worker --coordinator "$URL" --cache "$WORK/cache-$2" \
    --name "$2" "${WORKER[@]}" >"$WORK/$2.log" 2>&1 &
  FROZEN_PID=$!
  PIDS+=("$FROZEN_PID")
  wait_for is_stopped "$FROZEN_PID" || fail "$2 never froze before its upload"
  FROZEN_TILE=$(frozen_tile "$WORK/$2.log")
  [ -n "$FROZEN_TILE" ] || fail "$2 froze before rendering a tile"
}
