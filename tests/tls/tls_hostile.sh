#!/usr/bin/env bash
# Hostile input against an HTTPS coordinator: half a TLS setup (a key or client CA without a certificate, a key of
# another certificate) refused at start; random bytes and a plain HTTP request instead of a handshake, a
# handshake that stalls (whole or after its first bytes) and one with a client certificate from the wrong CA are
# refused and closed, a stalled handshake is closed by the read timeout and holds a slot of --max-connections while
# it lasts, and the coordinator keeps serving throughout.
source "$(dirname "$0")/../farm/common.sh"
# shellcheck source-path=SCRIPTDIR source=../lib/tls.sh
source "$(dirname "$0")/../lib/tls.sh"

T=$WORK/tls
mkdir -p "$T"
make_ca "$T" ca
make_ca "$T" rogue
make_cert "$T" ca server "IP:127.0.0.1" serverAuth
make_cert "$T" ca client "DNS:client" clientAuth
make_cert "$T" rogue intruder "DNS:intruder" clientAuth
write_sphere_scene "$WORK/s.json" 8 8 1
GOOD=(--ca-file "$T/ca.pem" --tls-cert "$T/client.pem" --tls-key "$T/client.key")

# probe LOG [submit flags]: a submit that must be answered (the coordinator is serving).
probe() {
  local log=$1
  shift
  expect_exit 0 "$log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach "$@"
}

# 0. Half a TLS setup is refused at start, never served as plain HTTP.
expect_exit 2 "$WORK/half1.log" -- "$TESSERA" serve --listen 127.0.0.1:0 --data "$WORK/d0" --tls-client-ca "$T/ca.pem"
log_has "$WORK/half1.log" "--tls-client-ca needs --tls-cert and --tls-key" || fail "a client CA without a certificate was accepted"
expect_exit 2 "$WORK/half2.log" -- "$TESSERA" serve --listen 127.0.0.1:0 --data "$WORK/d0" --tls-key "$T/server.key"
log_has "$WORK/half2.log" "needs both --tls-cert and --tls-key" || fail "a key without a certificate was accepted"
expect_exit 2 "$WORK/half3.log" -- "$TESSERA" serve --listen 127.0.0.1:0 --data "$WORK/d0" --tls-cert "$T/server.pem" \
  --tls-key "$T/client.key"
log_has "$WORK/half3.log" "cannot use TLS key.*mismatch" || fail "a key of another certificate was accepted"

# 1. Read timeout 1 s: garbage, plain HTTP and stalled handshakes are closed, the coordinator serves on.
start_serve --tls-cert "$T/server.pem" --tls-key "$T/server.key" --tls-client-ca "$T/ca.pem" --read-timeout-seconds 1
PORT=${URL##*:}
URL="https://127.0.0.1:$PORT"
# closed_after NAME ANSWER: sends what stands on stdin on a fresh connection, then expects the server to close it (EOF,
# or a reset: cat's status 0 or 1, not timeout's 124) having answered ANSWER in plain HTTP ("" for nothing in plain
# HTTP at all).
closed_after() {
  local rc=0
  exec 3<>"/dev/tcp/127.0.0.1/$PORT"
  cat >&3 2>/dev/null || true  # the server may close before all of it is written
  timeout 30 cat <&3 >"$WORK/$1.out" 2>/dev/null || rc=$?
  exec 3<&-
  [ $rc -le 1 ] || fail "a connection sending $1 was not closed (status $rc)"
  if [ -z "$2" ]; then
    ! grep -qa "HTTP/1" "$WORK/$1.out" || fail "a connection sending $1 got a plain HTTP answer"
  else
    grep -qa "^$2" "$WORK/$1.out" || fail "a connection sending $1 was not answered '$2': $(head -c 200 "$WORK/$1.out")"
  fi
}
head -c 65536 /dev/urandom | closed_after garbage ""
# A plain HTTP request on the TLS port is told so in plain HTTP, then closed.
printf 'GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n' | closed_after plain-http "HTTP/1.1 400"
probe "$WORK/probe1.log" "${GOOD[@]}"

# A connection that sends nothing, and one that stops after a TLS record header: both closed by the server (EOF on
# our side) well before `timeout` would end the wait.
exec 3<>"/dev/tcp/127.0.0.1/$PORT"
rc=0; timeout 30 cat <&3 >/dev/null || rc=$?
[ $rc = 0 ] || fail "a silent connection was not closed by the read timeout (status $rc)"
exec 3<&-
exec 3<>"/dev/tcp/127.0.0.1/$PORT"
printf '\x16\x03\x01\x02\x00' >&3
rc=0; timeout 30 cat <&3 >/dev/null || rc=$?
[ $rc = 0 ] || fail "a handshake stalled after its first bytes was not closed (status $rc)"
exec 3<&-

# A client certificate from another CA, and none at all: refused at the handshake; the coordinator serves on.
expect_exit 1 "$WORK/rogue.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach --ca-file "$T/ca.pem" \
  --tls-cert "$T/intruder.pem" --tls-key "$T/intruder.key"
log_has "$WORK/rogue.log" "requires a client certificate from a CA it trusts" || fail "the wrong CA's client certificate was not refused"
expect_exit 1 "$WORK/none.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach --ca-file "$T/ca.pem"
log_has "$WORK/none.log" "certificate required" || fail "a client without a certificate was not refused"
probe "$WORK/probe2.log" "${GOOD[@]}"
kill -0 "$SERVE_PID" || fail "the coordinator died"
stop_pids 50 "$SERVE_PID"

# 2. One connection allowed: a stalled handshake holds it (a second client is closed without a handshake) until the
# stalled one goes away. The 60 s read timeout only has to outlast the one submit below.
start_serve --tls-cert "$T/server.pem" --tls-key "$T/server.key" --max-connections 1 --read-timeout-seconds 60
URL="https://127.0.0.1:${URL##*:}"
exec 3<>"/dev/tcp/127.0.0.1/${URL##*:}"
expect_exit 1 "$WORK/limit.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach --ca-file "$T/ca.pem"
log_has "$WORK/limit.log" "TLS handshake failed" || fail "a connection over the limit was not closed"
wait_for log_has "$WORK/serve.log" "connection refused: 1 connections open" || fail "the refusal was not logged"
exec 3<&-
probe_ok() { "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach --ca-file "$T/ca.pem" >"$WORK/probe3.log" 2>&1; }
wait_for probe_ok || fail "the slot of the stalled connection was not freed"
echo "PASS"
