#!/usr/bin/env bash
# Logs of done tiles: a worker sends its last log lines about a lease with the tile's upload, and `tessera jobs tiles`
# shows them under each done tile, also after a restart of the coordinator. A coordinator whose bound on a job's
# kept tile logs (serve --max-tile-log-bytes) is too small for any log keeps none and says how many it did not keep.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 16 1  # 8 tiles of 8x8
start_serve
ADDRESS=$(head -n1 "$WORK/ready")
start_worker a --threads 1
# submit_and_wait NAME: submits the scene, waits until the job is done and sets JOB to its id.
submit_and_wait() {
  JOB=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --detach 2>"$WORK/submit-$1.log") \
    || fail "submit failed: $(cat "$WORK/submit-$1.log")"
  "$TESSERA" jobs wait "$JOB" --coordinator "$URL" >"$WORK/wait-$1.log" 2>&1 || fail "the job did not finish"
}
submit_and_wait one
JOB1=$JOB
"$TESSERA" jobs tiles "$JOB1" --coordinator "$URL" >"$WORK/tiles-one.txt" 2>&1 || fail "jobs tiles failed"
# Every done tile with the lines its worker logged about the lease: the lease, then the render.
[ "$(grep -cE '^tile [0-7] rendered by w-[^ ]+ \(a\):$' "$WORK/tiles-one.txt")" = 8 ] \
  || fail "not every done tile shows its log: $(cat "$WORK/tiles-one.txt")"
log_has "$WORK/tiles-one.txt" "^  \\| .*job=$JOB1 tile=3 lease=[^ ]+: leased window" || fail "tile 3's log lacks its lease line"
log_has "$WORK/tiles-one.txt" "^  \\| .*job=$JOB1 tile=3 lease=[^ ]+: rendered in [0-9.]+s" \
  || fail "tile 3's log lacks its render line"
log_has "$WORK/tiles-one.txt" "not kept" && fail "a log was not kept under the default bound"

# The same data, a bound of one byte per job: the first job's logs were stored, the second job's are not kept.
kill -TERM "$SERVE_PID" "$WORKER_PID"
wait_for bash -c "! kill -0 $SERVE_PID 2>/dev/null" || fail "the coordinator did not stop"
LISTEN=$ADDRESS start_serve --max-tile-log-bytes 1
"$TESSERA" jobs tiles "$JOB1" --coordinator "$URL" >"$WORK/tiles-one-again.txt" 2>&1 || fail "jobs tiles failed"
[ "$(grep -cE '^tile [0-7] rendered by ' "$WORK/tiles-one-again.txt")" = 8 ] || fail "the logs were lost in the restart"
start_worker b --threads 1
submit_and_wait two
JOB2=$JOB
"$TESSERA" jobs tiles "$JOB2" --coordinator "$URL" >"$WORK/tiles-two.txt" 2>&1 || fail "jobs tiles failed"
log_has "$WORK/tiles-two.txt" "rendered by .*:$" && fail "a log was kept past the bound: $(cat "$WORK/tiles-two.txt")"
log_has "$WORK/tiles-two.txt" "^8 done tiles' logs were not kept" || fail "the tiles not kept are not counted: $(cat "$WORK/tiles-two.txt")"
echo "PASS"
