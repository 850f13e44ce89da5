#!/usr/bin/env bash
# HTTPS end to end on loopback with throwaway certificates: a coordinator with --tls-cert/--tls-key, tokens and
# --tls-client-ca renders bitwise identically for a worker and a submit that verify it; clients refuse a server they
# cannot verify (unknown CA, wrong host name, plain HTTP behind an https:// URL) with a clear message and the server
# refuses clients without a certificate from its CA; SIGHUP re-reads the certificate (new connections see the new
# one, a lease held across the reload completes, an unreadable key keeps the old one). With a users file, a client
# certificate whose common name is a user's stands for that user without a token.
source "$(dirname "$0")/../farm/common.sh"
# shellcheck source-path=SCRIPTDIR source=../lib/tls.sh
source "$(dirname "$0")/../lib/tls.sh"
# shellcheck source-path=SCRIPTDIR source=../lib/freeze.sh
source "$(dirname "$0")/../lib/freeze.sh"

T=$WORK/tls
mkdir -p "$T"
make_ca "$T" ca
make_ca "$T" ca2
make_ca "$T" rogue
make_cert "$T" ca server "IP:127.0.0.1" serverAuth      # names the address only: https://localhost must fail
make_cert "$T" ca2 server2 "IP:127.0.0.1" serverAuth    # the rotated certificate, from another CA
make_cert "$T" ca client "DNS:worker-1" clientAuth
make_cert "$T" rogue intruder "DNS:intruder" clientAuth
cat "$T/ca.pem" "$T/ca2.pem" >"$T/both.pem"
cp "$T/server.pem" "$T/live.pem"
cp "$T/server.key" "$T/live.key"
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/client.token"
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/worker.token"
chmod 600 "$WORK/client.token" "$WORK/worker.token"
export TESSERA_CLIENT_TOKEN
TESSERA_CLIENT_TOKEN=$(cat "$WORK/client.token")

write_sphere_scene "$WORK/s.json" 24 16 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q

# --lease-seconds 600: the frozen worker below holds its lease across the reload whatever the machine's speed.
start_serve --tls-cert "$T/live.pem" --tls-key "$T/live.key" --tls-client-ca "$T/ca.pem" \
  --client-token-file "$WORK/client.token" --worker-token-file "$WORK/worker.token" --lease-seconds 600
PORT=${URL##*:}
URL="https://127.0.0.1:$PORT"
log_has "$WORK/serve.log" "listening on https://.*client certificates required" || fail "serve did not say it serves HTTPS"
log_has "$WORK/serve.log" "clear text" && fail "a loopback coordinator warned about clear text"
MTLS=(--tls-cert "$T/client.pem" --tls-key "$T/client.key")

# Clients that cannot verify the server, or that the server cannot verify, are refused with the reason.
expect_exit 1 "$WORK/no-ca.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" -q "${MTLS[@]}"
log_has "$WORK/no-ca.log" "certificate is not accepted: (unable to get local issuer certificate|self-signed certificate in certificate chain)" \
  || fail "no clear message for an unknown CA"
expect_exit 1 "$WORK/host.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "https://localhost:$PORT" -q \
  --ca-file "$T/ca.pem" "${MTLS[@]}"
log_has "$WORK/host.log" "certificate is not accepted: [Hh]ostname mismatch" || fail "no clear message for a wrong host name"
expect_exit 1 "$WORK/no-cert.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" -q --ca-file "$T/ca.pem"
log_has "$WORK/no-cert.log" "certificate required.*requires a client certificate" || fail "no clear message without a client certificate"
expect_exit 1 "$WORK/rogue.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" -q --ca-file "$T/ca.pem" \
  --tls-cert "$T/intruder.pem" --tls-key "$T/intruder.key"
log_has "$WORK/rogue.log" "requires a client certificate from a CA it trusts" || fail "a client certificate from another CA was not refused"
expect_exit 2 "$WORK/plain.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "http://127.0.0.1:$PORT" -q
log_has "$WORK/plain.log" "400: this coordinator speaks HTTPS only: use an https:// URL" || fail "no clear answer to plain HTTP"
expect_exit 1 "$WORK/mixed.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "http://127.0.0.1:$PORT" -q \
  --ca-file "$T/ca.pem"
log_has "$WORK/mixed.log" "is plain HTTP: use an https:// URL" || fail "TLS files with an http:// URL were not refused"

# A worker that trusts both CAs (as during a planned rotation) freezes with a lease before its first upload.
freeze_setup
env "${FREEZE_ENV[@]}" "$FREEZE_BIN" worker --coordinator "$URL" --cache "$WORK/cache-w1" --name w1 --threads 1 \
  --ca-file "$T/both.pem" "${MTLS[@]}" --token-file "$WORK/worker.token" >"$WORK/w1.log" 2>&1 &
W1=$!
PIDS+=("$W1")
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 8 -o "$WORK/out.exr" -q --ca-file "$T/ca.pem" "${MTLS[@]}"
wait_for is_stopped "$W1" || fail "the worker never stopped itself before its upload"
HELD_TILE=$(frozen_tile "$WORK/w1.log")

# Rotation: a key that cannot be read is refused and the old certificate stays; then the new pair is taken.
echo "not a key" >"$T/live.key"
kill -HUP "$SERVE_PID"
wait_for log_has "$WORK/serve.log" "SIGHUP: cannot use TLS key.*still serving with the previous certificate" \
  || fail "a bad key on SIGHUP was not reported"
cp "$T/server2.pem" "$T/live.pem"
cp "$T/server2.key" "$T/live.key"
kill -HUP "$SERVE_PID"
wait_for log_has "$WORK/serve.log" "SIGHUP: TLS certificate and key re-read" || fail "SIGHUP did not reload"
kill -0 "$SERVE_PID" || fail "the coordinator died on SIGHUP"
expect_exit 1 "$WORK/old-ca.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" -q --ca-file "$T/ca.pem" \
  "${MTLS[@]}" --detach
log_has "$WORK/old-ca.log" "certificate is not accepted" || fail "new connections still get the old certificate"

# The lease taken before the reload completes after it; the job is bitwise identical.
kill -CONT "$W1"
wait "$SUBMIT_PID" || fail "submit over TLS exited with $?"
log_has "$WORK/w1.log" "$HELD_TILE lease=.*upload accepted" || fail "the lease held across the reload did not complete"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result over TLS differs from the single-process render"
expect_exit 0 "$WORK/new-ca.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" -q --ca-file "$T/ca2.pem" \
  "${MTLS[@]}" -o "$WORK/out2.exr"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out2.exr" || fail "result after the rotation differs"
# `tessera jobs` verifies the server like submit: it lists the two jobs with the CA, and refuses without it.
expect_exit 0 "$WORK/jobs.log" -- "$TESSERA" jobs ls --coordinator "$URL" --ca-file "$T/ca2.pem" "${MTLS[@]}"
[ "$(grep -c ' done ' "$WORK/jobs.log")" -eq 2 ] || fail "jobs ls over TLS did not list the two done jobs"
expect_exit 1 "$WORK/jobs-no-ca.log" -- "$TESSERA" jobs ls --coordinator "$URL" "${MTLS[@]}"
log_has "$WORK/jobs-no-ca.log" "certificate is not accepted" || fail "jobs ls without the CA did not say why"

# A users file beside mutual TLS: the certificate of CN=ben submits as ben with no token; CN=stranger names nobody.
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" || true
make_cert "$T" ca2 ben "DNS:ben" clientAuth
make_cert "$T" ca2 stranger "DNS:stranger" clientAuth
"$TESSERA" users add ben --role user --users "$WORK/users.json" >/dev/null 2>&1 || fail "users add failed"
start_serve --tls-cert "$T/live.pem" --tls-key "$T/live.key" --tls-client-ca "$T/both.pem" --users "$WORK/users.json" \
  --worker-token-file "$WORK/worker.token"
URL="https://127.0.0.1:${URL##*:}"
BEN=(--ca-file "$T/ca2.pem" --tls-cert "$T/ben.pem" --tls-key "$T/ben.key")
JOB=$(env -u TESSERA_CLIENT_TOKEN "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach "${BEN[@]}") \
  || fail "the certificate of a user could not submit without a token"
env -u TESSERA_CLIENT_TOKEN "$TESSERA" jobs ls --mine --coordinator "$URL" "${BEN[@]}" >"$WORK/ben.log" 2>&1 \
  || fail "jobs ls --mine by certificate failed"
log_has "$WORK/ben.log" "^$JOB +queued +ben " || fail "the job submitted by certificate is not ben's: $(cat "$WORK/ben.log")"
expect_exit 2 "$WORK/stranger.log" -- env -u TESSERA_CLIENT_TOKEN "$TESSERA" jobs ls --coordinator "$URL" \
  --ca-file "$T/ca2.pem" --tls-cert "$T/stranger.pem" --tls-key "$T/stranger.key"
log_has "$WORK/stranger.log" "401" || fail "a certificate naming no user was not refused with 401"
grep -q "$(cat "$WORK/worker.token")" "$WORK"/*.log && fail "a token was logged"
echo "PASS"
