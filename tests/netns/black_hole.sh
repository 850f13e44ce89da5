#!/usr/bin/env bash
# A coordinator address that drops packets instead of refusing them (a black hole: 10.77.0.99 answers nothing; a
# static neighbour entry sends frames there to a MAC address no host has). Clients must fail each request within
# their timeouts and carry on, never hang: a submit exits with its connect timeout, a worker keeps retrying with its
# own; and a worker whose live coordinator vanishes mid-connection (link cut) times out its kept-alive requests.
source "$(dirname "$0")/../farm/common.sh"
source "$(dirname "$0")/common.sh"
for h in c w1 w2; do add_host "$h"; done
make_tls_files
HOLE=10.77.0.99
for h in w1 w2; do on "$h" ip neigh add "$HOLE" lladdr 02:00:00:00:00:99 dev eth0 nud permanent; done
write_sphere_scene "$WORK/s.json" 8 8 1

# submit: the default 3 s connect timeout ends it (exit 1 with the reason); `timeout 60` would mean a hang (124).
expect_exit 1 "$WORK/submit.log" -- on w1 timeout 60 "$TESSERA" submit "$WORK/s.json" --coordinator "http://$HOLE:8470" -q
log_has "$WORK/submit.log" "cannot connect: timed out after 3000 ms" || fail "submit did not fail by its connect timeout"
expect_exit 1 "$WORK/submit-tls.log" -- on w1 timeout 60 "$TESSERA" submit "$WORK/s.json" \
  --coordinator "https://$HOLE:8470" -q "${CLIENT_TLS[@]}"
log_has "$WORK/submit-tls.log" "cannot connect: timed out after 3000 ms" || fail "an https submit did not time out"

# worker: every attempt ends by its 1 s connect timeout; it keeps retrying and stops cleanly when asked.
worker_on w1 lost "http://$HOLE:8470" --threads 1 --connect-timeout-seconds 1
LOST=$WORKER_PID
wait_for log_has "$WORK/lost.log" "coordinator unreachable \(register\).*cannot connect: timed out after 1000 ms" \
  || fail "the worker did not time out its connection to the black hole"
kill -0 "$LOST" || fail "the worker gave up instead of retrying"
kill -TERM "$LOST"
wait "$LOST" || fail "the worker exited with $? when stopped while retrying"

# A connected worker whose coordinator goes silent (link cut): its next requests end by the 2 s request timeout (on
# the kept-alive connection) or the 1 s connect timeout (on a fresh one), never hang.
serve_on c "$COORD" "${SERVE_TLS[@]}"
worker_on w2 idle "https://$COORD" --threads 1 "${CLIENT_TLS[@]}" --token-file "$WORKER_TOKEN_FILE" \
  --connect-timeout-seconds 1 --request-timeout-seconds 2
wait_for log_has "$WORK/idle.log" "registered as" || fail "the worker did not register"
cut c
wait_for log_has "$WORK/idle.log" "coordinator unreachable \(lease\).*timed out after (2000|1000) ms" \
  || fail "the worker's requests to a silent coordinator did not time out"
reconnect c
wait_for log_has "$WORK/idle.log" "coordinator reachable again" || fail "the worker did not reconnect"
echo "PASS"
