#!/usr/bin/env bash
# A shared farm from the command line: `tessera users` makes and checks the users file (bad names, roles, files and
# duplicates refused with a sentence; the token printed once, stored nowhere); a real worker with tags renders a job
# that requires them, bitwise as a single render, while a job requiring a tag no worker has waits and says so in
# `jobs ls`; `jobs ls --mine` lists only the caller's jobs; `jobs cancel` of another user's job is refused (exit 2,
# the owner named) and changes nothing; `workers ls` shows the tags; `tessera audit` works for admins only.
source "$(dirname "$0")/common.sh"

USERS="$WORK/users.json"
add_user() { "$TESSERA" users add "$1" --role "$2" --users "$USERS" 2>"$WORK/add-$1.log" | tail -n1 >"$WORK/$1.token"; }
add_user ana admin
add_user ben user
add_user bea user
add_user farm worker
chmod 600 "$WORK"/*.token
for name in ana ben bea farm; do
  [ "$(wc -c <"$WORK/$name.token")" = 49 ] || fail "users add $name did not print a 48-digit token as its last line"
  if grep -qF "$(cat "$WORK/$name.token")" "$USERS" "$WORK/add-$name.log"; then fail "$name's token was stored or logged"; fi
done
expect_exit 2 "$WORK/dup.log" -- "$TESSERA" users add ben --users "$USERS"
log_has "$WORK/dup.log" "user 'ben' is already in" || fail "adding ben twice was not refused with a sentence"
expect_exit 2 "$WORK/reserved.log" -- "$TESSERA" users add client --users "$USERS"
log_has "$WORK/reserved.log" "is reserved" || fail "the reserved name 'client' was accepted"
expect_exit 2 "$WORK/badname.log" -- "$TESSERA" users add "b en" --users "$USERS"
log_has "$WORK/badname.log" "may contain only" || fail "a user name with a space was accepted"
expect_exit 2 "$WORK/rm.log" -- "$TESSERA" users rm nobody --users "$USERS"
log_has "$WORK/rm.log" "no user 'nobody'" || fail "removing an unknown user was not refused"
echo '{"users": [' >"$WORK/broken.json"
expect_exit 2 "$WORK/broken.log" -- "$TESSERA" users ls --users "$WORK/broken.json"
log_has "$WORK/broken.log" "not JSON" || fail "a broken users file was not refused with a sentence"
"$TESSERA" users ls --users "$USERS" >"$WORK/ls-users.log" 2>&1 || fail "users ls failed"
log_has "$WORK/ls-users.log" "^bea +user " || fail "users ls does not list bea: $(cat "$WORK/ls-users.log")"

start_serve --users "$USERS"
as() { TESSERA_CLIENT_TOKEN=$(cat "$WORK/$1.token") "${@:2}"; }

write_sphere_scene "$WORK/scene.json" 24 16 2
"$TESSERA" render "$WORK/scene.json" -o "$WORK/ref.exr" -q --seed 9

expect_exit 2 "$WORK/badreq.log" -- as ben "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --require "Big Mem"
log_has "$WORK/badreq.log" "may contain only" || fail "a bad --require was not refused with a sentence"
expect_exit 2 "$WORK/badtags.log" -- "$TESSERA" worker --coordinator "$URL" --tags "GPU" --token-file "$WORK/farm.token"
log_has "$WORK/badtags.log" "may contain only" || fail "a bad --tags was not refused with a sentence"

WAITING=$(as bea "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --detach --require gpu --name waits)
start_worker w1 --threads 2 --tags bigmem,site-a --token-file "$WORK/farm.token"
as ben "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 8 --seed 9 --require bigmem --max-workers 1 \
  -o "$WORK/out.exr" -q >"$WORK/submit.log" 2>&1 || fail "ben's submission requiring bigmem failed: $(cat "$WORK/submit.log")"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the result differs from a single render"

as bea "$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls.log" "^$WAITING +queued +bea .*waits \(waiting for a worker with tags gpu\)" \
  || fail "the job requiring gpu does not say what it waits for: $(cat "$WORK/ls.log")"
as bea "$TESSERA" jobs ls --mine --coordinator "$URL" >"$WORK/mine.log" 2>&1 || fail "jobs ls --mine failed"
[ "$(grep -c "^j-" "$WORK/mine.log")" = 1 ] && log_has "$WORK/mine.log" "^$WAITING " \
  || fail "jobs ls --mine as bea lists other jobs: $(cat "$WORK/mine.log")"

expect_exit 2 "$WORK/cancel.log" -- as ben "$TESSERA" jobs cancel "$WAITING" --coordinator "$URL"
log_has "$WORK/cancel.log" "403.*belongs to bea" || fail "ben's cancel of bea's job was not refused naming its owner"
as ana "$TESSERA" jobs show "$WAITING" --coordinator "$URL" | grep -q '"state": "queued"' \
  || fail "the refused cancel changed bea's job"
as ana "$TESSERA" jobs cancel "$WAITING" --coordinator "$URL" >"$WORK/cancel-admin.log" 2>&1 \
  || fail "an admin could not cancel bea's job"

as ana "$TESSERA" workers ls --coordinator "$URL" >"$WORK/workers.log" 2>&1 || fail "workers ls failed"
log_has "$WORK/workers.log" "bigmem,site-a +w1" || fail "workers ls does not show the tags: $(cat "$WORK/workers.log")"

expect_exit 2 "$WORK/audit-ben.log" -- as ben "$TESSERA" audit --coordinator "$URL"
log_has "$WORK/audit-ben.log" "403" || fail "a user could read the audit trail"
as ana "$TESSERA" audit --coordinator "$URL" >"$WORK/audit.log" 2>&1 || fail "tessera audit failed for an admin"
log_has "$WORK/audit.log" " ben +user +DELETE /v1/jobs/\{id\} +$WAITING +403 " || fail "the refused cancel is not audited: $(cat "$WORK/audit.log")"
log_has "$WORK/audit.log" " ana +admin +DELETE /v1/jobs/\{id\} +$WAITING +200 " || fail "the admin's cancel is not audited"
for name in ana ben bea farm; do
  if grep -qF "$(cat "$WORK/$name.token")" "$WORK"/*.log; then fail "$name's token appears in a log"; fi
done
echo "PASS"
