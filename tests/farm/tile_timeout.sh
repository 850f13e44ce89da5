#!/usr/bin/env bash
# A hung render loses its lease after the job's tile_timeout_seconds even though its heartbeats keep coming: worker a
# hangs in every render (fail point worker.render=pause), the job has `--tile-timeout 2`; the coordinator revokes the
# lease as a failure of a ("tile timed out after 2 s"), a's next heartbeat gets 410 and it abandons the tile, the tiles
# endpoint shows the failure, and worker b finishes the job bitwise identical to a single-process render.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 16 8 4  # 2 tiles of 8x8
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --seed 5
start_serve --lease-seconds 10 --heartbeat-seconds 1
JOB=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 5 --tile-timeout 2 --detach \
  2>"$WORK/submit.log") || fail "submit failed"
"$TESSERA" jobs show "$JOB" --coordinator "$URL" | grep -q '"tile_timeout_seconds": 2' || fail "the job has no 2 s timeout"
FAIL_POINTS=worker.render=pause start_worker a --threads 2
wait_for log_has "$WORK/serve.log" "worker w-[^ ]+: lease [^ ]+ revoked: tile timed out after 2 s" \
  || fail "the coordinator did not revoke the hung lease"
wait_for log_has "$WORK/a.log" "heartbeat answered 410" || fail "worker a's heartbeat was not answered 410"
wait_for log_has "$WORK/a.log" "lease revoked, tile dropped" || fail "worker a did not abandon the tile"
"$TESSERA" jobs tiles "$JOB" --coordinator "$URL" >"$WORK/tiles.txt" 2>&1 || fail "jobs tiles failed"
log_has "$WORK/tiles.txt" "^tile 0 failed on w-[^ ]+ \\(a\\): tile timed out after 2 s" \
  || fail "the tile table does not show the timeout: $(cat "$WORK/tiles.txt")"
start_worker b --threads 2
job_done() { "$TESSERA" jobs show "$JOB" --coordinator "$URL" 2>/dev/null | grep -q '"state": "done"'; }
wait_for job_done || fail "worker b did not finish the job"
curl -sS -f -o "$WORK/out.exr" "$URL/v1/jobs/$JOB/result.exr" || fail "no result"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the result differs from a single-process render"
echo "PASS"
