#!/usr/bin/env bash
# Bearer tokens end to end: a coordinator with client and worker tokens refuses submits and workers without the right
# token (exit 2 with the coordinator's reason; a worker with a bad token stops instead of retrying forever), renders
# bitwise identically with the right ones, listens beyond loopback only with both tokens, and never logs a token.
source "$(dirname "$0")/common.sh"

head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/client.token"
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/worker.token"
chmod 600 "$WORK/client.token" "$WORK/worker.token"
CLIENT_TOKEN=$(cat "$WORK/client.token")
WORKER_TOKEN=$(cat "$WORK/worker.token")

# Beyond loopback without tokens: refused with the reason.
expect_exit 2 "$WORK/open.log" -- "$TESSERA" serve --listen 0.0.0.0:0 --data "$WORK/data-open"
log_has "$WORK/open.log" "without access tokens" || fail "no reason given for refusing 0.0.0.0"

LISTEN=0.0.0.0:0 start_serve --client-token-file "$WORK/client.token" --worker-token-file "$WORK/worker.token"
URL="http://127.0.0.1:${URL##*:}"

write_sphere_scene "$WORK/scene.json" 24 16 2
"$TESSERA" render "$WORK/scene.json" -o "$WORK/ref.exr" -q --seed 9

# A worker with the client token is refused and exits (status 2) with the reason; 124 would mean it kept retrying.
expect_exit 2 "$WORK/bad-worker.log" -- timeout 20 "$TESSERA" worker --coordinator "$URL" --cache "$WORK/cache-bad" \
  --token-file "$WORK/client.token"
log_has "$WORK/bad-worker.log" "refused with 403" || fail "the worker did not say why it stopped"

# A submit without a token or with the worker token is refused.
expect_exit 2 "$WORK/submit-none.log" -- "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" -q
log_has "$WORK/submit-none.log" "401.*client token" || fail "no reason for the missing token"
TESSERA_CLIENT_TOKEN=$WORKER_TOKEN expect_exit 2 "$WORK/submit-wrong.log" -- "$TESSERA" submit "$WORK/scene.json" \
  --coordinator "$URL" -q
log_has "$WORK/submit-wrong.log" "403" || fail "no 403 for the worker token"

# With the right tokens (a file for the worker, the environment for the client) the render is bitwise identical.
start_worker w1 --threads 2 --token-file "$WORK/worker.token"
TESSERA_CLIENT_TOKEN=$CLIENT_TOKEN "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 8 --seed 9 \
  -o "$WORK/out.exr" -q >"$WORK/submit.log" 2>&1 || fail "submit with the client token failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"

# No log line anywhere contains a token.
for f in "$WORK"/*.log; do
  if grep -Fq -e "$CLIENT_TOKEN" -e "$WORKER_TOKEN" "$f"; then fail "a token appears in $f"; fi
done
echo "PASS"
