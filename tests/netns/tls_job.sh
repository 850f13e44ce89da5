#!/usr/bin/env bash
# Four hosts on a virtual LAN (coordinator, two workers, a submitting client, each its own network namespace): a job
# over HTTPS with tokens and client certificates completes bitwise identical to a single-process render; a
# coordinator serving plain HTTP beyond loopback warns at start that tokens travel in clear text.
source "$(dirname "$0")/../farm/common.sh"
source "$(dirname "$0")/common.sh"
for h in c w1 w2 w3; do add_host "$h"; done
make_tls_files

write_sphere_scene "$WORK/s.json" 48 32 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --seed 5

serve_on c "$COORD" "${SERVE_TLS[@]}"
log_has "$WORK/serve.log" "clear text" && fail "a TLS coordinator warned about clear text"
URL=https://$COORD
worker_on w1 w1 "$URL" --threads 2 "${CLIENT_TLS[@]}" --token-file "$WORKER_TOKEN_FILE"
worker_on w2 w2 "$URL" --threads 2 "${CLIENT_TLS[@]}" --token-file "$WORKER_TOKEN_FILE"
both_registered() { log_has "$WORK/w1.log" "registered as" && log_has "$WORK/w2.log" "registered as"; }
wait_for both_registered || fail "the workers did not register over TLS"
expect_exit 0 "$WORK/submit.log" -- on w3 "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 5 -q \
  -o "$WORK/out.exr" "${CLIENT_TLS[@]}" --token-file "$CLIENT_TOKEN_FILE"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the job over TLS differs from the single-process render"
# Which worker renders how many tiles is up to the machine's speed; together they rendered all 24.
[ $(($(count "$WORK/w1.log" "upload accepted") + $(count "$WORK/w2.log" "upload accepted"))) = 24 ] \
  || fail "the workers' accepted uploads do not add up to the job's 24 tiles"

# The same host, a second coordinator on plain HTTP: it starts, and says that tokens travel in clear text.
PLAIN_LOG=$WORK/serve.log
DATA=$WORK/data-plain serve_on c "${ADDR[c]}:8471" --client-token-file "$CLIENT_TOKEN_FILE" \
  --worker-token-file "$WORKER_TOKEN_FILE"
log_has "$PLAIN_LOG" "plain HTTP on ${ADDR[c]}:8471: access tokens and job data travel in clear text" \
  || fail "no clear-text warning for plain HTTP beyond loopback"
echo "PASS"
