#!/usr/bin/env bash
# Raising a resumable job's spp (PATCH /v1/jobs/{id} {"spp": M}, `tessera jobs spp ID M`): the done job runs again,
# every tile is leased again and its worker continues from the tile's stored exact sums, and the result is bitwise the
# single-process `render --resumable --spp M` and a farm job submitted at M from the start (path-traced scene with
# glass, odd tiles). Raised again while running (a worker holds a tile, fail point worker.render, until the raise
# revokes its lease), it ends identical to M2 from the start. The farm result refines locally too (`render --resume`).
# With 2 replicates, raised across a SIGKILL of the coordinator, it is identical to render --replicates 2 --spp M.
# Refusals: a job not submitted as resumable, an adaptive one, a lower spp (409 with a sentence).
source "$(dirname "$0")/common.sh"

N=$(spp 2) M=$(spp 8 2) M2=$(spp 16 4)  # M2 > M > N at any TESSERA_TEST_SPP_SCALE
write_cbox_scene "$WORK/g" 24 20 2 glass_sphere.json
S="$WORK/g/scene.json"
for n in "$N" "$M" "$M2"; do
  "$TESSERA" render "$S" -o "$WORK/ref-$n.exr" --spp "$n" --seed 5 --resumable -q || fail "reference render at $n spp"
done
start_serve --lease-seconds 5 --heartbeat-seconds 1

# Uploads to a resumable job by hand: a tile without its sums and one at another spp are refused (422) with the reason;
# the tile as `render --resumable --crop` writes it is accepted. (Two hand workers: two refusals would blocklist one.)
HAND=$("$TESSERA" submit "$S" --coordinator "$URL" --spp "$N" --seed 5 --tile 7 --resumable --detach 2>"$WORK/submit-hand.log") \
  || fail "submit --resumable failed"
hand_upload() {  # "WORKER_ID SECRET" RENDER_FLAGS... : leases a tile, renders it with the flags, uploads it; prints the answer
  local wid secret lease_json lease
  read -r wid secret <<<"$1"
  shift
  lease_json=$(curl -sS -f -X POST -H "X-Tessera-Worker-Secret: $secret" "$URL/v1/workers/$wid/lease") || fail "no lease"
  echo "$lease_json" | grep -q '"resumable":true' || fail "a resumable job's lease does not say so: $lease_json"
  lease=$(echo "$lease_json" | grep -Eo '"lease":"[^"]+"' | cut -d'"' -f4)
  read -r X0 Y0 X1 Y1 <<<"$(echo "$lease_json" | grep -Eo '"window":\[[0-9,]+\]' | grep -Eo '[0-9]+' | tr '\n' ' ')"
  "$TESSERA" render "$S" -o "$WORK/hand.exr" -q --seed 5 --crop "$X0" "$Y0" "$X1" "$Y1" "$@" || fail "hand render"
  curl -sS -X PUT -H "X-Tessera-Worker-Secret: $secret" --data-binary @"$WORK/hand.exr" -H 'Content-Type: image/x-exr' \
    "$URL/v1/leases/$lease/result"
}
hand_worker() {  # NAME: registers a worker; prints its id and secret
  curl -sS -f -X POST -d "{\"name\": \"$1\"}" "$URL/v1/workers" | grep -Eo '"(id|secret)":"[^"]+"' | cut -d'"' -f4 | tr '\n' ' '
}
HA=$(hand_worker hand-a) HB=$(hand_worker hand-b)
hand_upload "$HA" --spp "$N" | grep -q "needs its exact sums" || fail "a tile without its sums was not refused"
hand_upload "$HB" --spp "$M" --resumable | grep -q "$M samples at tile pixel (0, 0), the job has $N spp" \
  || fail "a tile at another spp was not refused"
hand_upload "$HA" --spp "$N" --resumable | grep -q accepted || fail "a tile with its sums was not accepted"
"$TESSERA" jobs cancel "$HAND" --coordinator "$URL" >"$WORK/cancel-hand.log" 2>&1 || fail "cancel failed"

FAIL_POINTS="worker.render=1*off->1*pause->off" start_worker w1 --threads 2
W1_PID=$WORKER_PID

# Submitted at N and finished: identical to render --resumable at N (state channels included).
JOB=$("$TESSERA" submit "$S" --coordinator "$URL" --spp "$N" --seed 5 --tile 7 --resumable --detach 2>"$WORK/submit.log") \
  || fail "submit --resumable failed"
wait_for log_has "$WORK/w1.log" "tile=0 .*upload accepted" || fail "no tile finished"
wait_for paused "$WORK/w1.log" || fail "the second tile was not held"
# Raised while running (tile 0 done at N, tile 1 held): the held lease is revoked, the worker drops the tile.
"$TESSERA" jobs spp "$JOB" "$M" --coordinator "$URL" >"$WORK/raise-running.log" 2>&1 || fail "jobs spp (running) failed"
log_has "$WORK/raise-running.log" "^$JOB: running at $M spp, 12 of 12 tiles to continue" \
  || fail "jobs spp did not report the running job at $M spp"
wait_for log_has "$WORK/w1.log" "tile=1 .*lease revoked, tile dropped" || fail "the held tile was not dropped"
start_worker w2 --threads 2
W2_PID=$WORKER_PID
job_done() { "$TESSERA" jobs show "$JOB" --coordinator "$URL" 2>/dev/null | grep -q '"state": "done"'; }
wait_for job_done || fail "the job raised while running did not finish"
log_has "$WORK/w1.log" "tile=0 .*at $M spp continuing from $N" || log_has "$WORK/w2.log" "tile=0 .*at $M spp continuing from $N" \
  || fail "tile 0 was not continued from its state at $N spp"
curl -sS -f -o "$WORK/farm-$M.exr" "$URL/v1/jobs/$JOB/result.exr" || fail "no result at $M"
"$EXR_COMPARE" "$WORK/ref-$M.exr" "$WORK/farm-$M.exr" || fail "raised while running: differs from render --spp $M"

# Raised when done: every tile continues from its state at M.
"$TESSERA" jobs spp "$JOB" "$M2" --coordinator "$URL" >"$WORK/raise-done.log" 2>&1 || fail "jobs spp (done) failed"
log_has "$WORK/raise-done.log" "^$JOB: running at $M2 spp, 12 of 12 tiles to continue" || fail "jobs spp on a done job"
wait_for job_done || fail "the job raised when done did not finish"
[ "$(cat "$WORK"/w[12].log | grep -c "at $M2 spp continuing from $M")" = 12 ] || fail "not every tile continued from $M spp"
curl -sS -f -o "$WORK/farm-$M2.exr" "$URL/v1/jobs/$JOB/result.exr" || fail "no result at $M2"
"$EXR_COMPARE" "$WORK/ref-$M2.exr" "$WORK/farm-$M2.exr" || fail "raised when done: differs from render --spp $M2"
# ... and from a resumable farm job submitted at M2 from the start.
"$TESSERA" submit "$S" --coordinator "$URL" --spp "$M2" --seed 5 --tile 7 --resumable -o "$WORK/fresh-$M2.exr" -q \
  >"$WORK/submit-fresh.log" 2>&1 || fail "submit at $M2 failed"
"$EXR_COMPARE" "$WORK/fresh-$M2.exr" "$WORK/farm-$M2.exr" || fail "raised job differs from a job submitted at $M2"
# The farm result refines locally as a --resumable render does.
"$TESSERA" render "$S" -o "$WORK/local.exr" --resume "$WORK/farm-$M.exr" --spp "$M2" -q || fail "render --resume of a farm result"
"$EXR_COMPARE" "$WORK/ref-$M2.exr" "$WORK/local.exr" || fail "a farm result refined locally differs"

# With replicates (a submission by hand: `submit` has no --replicates), raised when done, after a SIGKILL of the
# coordinator with no worker running: the raised spp and the tiles' states come back from the database.
R=$(python3 - "$S" "$N" <<'PY'
import hashlib, json, os, sys
scene = json.load(open(sys.argv[1]))
def paths(v):  # every "path" value in the scene: its assets (uploaded by the submissions above)
    if isinstance(v, dict):
        for k, x in v.items():
            yield from ([x] if k == "path" and isinstance(x, str) else paths(x))
    elif isinstance(v, list):
        for x in v:
            yield from paths(x)
base = os.path.dirname(sys.argv[1])
assets = {p: hashlib.sha256(open(os.path.join(base, p), "rb").read()).hexdigest() for p in paths(scene)}
print(json.dumps({"scene": scene, "assets": assets, "spp": int(sys.argv[2]), "seed": 5, "tile_size": 7,
                  "replicates": 2, "resumable": True}))
PY
)
REP=$(curl -sS -f -X POST -H 'Content-Type: application/json' -d "$R" "$URL/v1/jobs" | grep -Eo '"id":"[^"]+"' | cut -d'"' -f4)
[ -n "$REP" ] || fail "the submission with replicates was refused"
rep_done() { "$TESSERA" jobs show "$REP" --coordinator "$URL" 2>/dev/null | grep -q '"state": "done"'; }
wait_for rep_done || fail "the job with replicates did not finish"
kill -TERM "$W1_PID" "$W2_PID"  # asked to stop: no tile renders before the restart
"$TESSERA" jobs spp "$REP" "$M" --coordinator "$URL" >"$WORK/raise-rep.log" 2>&1 || fail "jobs spp (replicates) failed"
kill -KILL "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
start_serve --lease-seconds 5 --heartbeat-seconds 1
start_worker w3 --threads 2
wait_for rep_done || fail "the raised job with replicates did not finish after the restart"
[ "$(grep -c "at $M spp continuing from $N" "$WORK/w3.log")" = 12 ] || fail "not every tile continued after the restart"
curl -sS -f -o "$WORK/rep-$M.exr" "$URL/v1/jobs/$REP/result.exr" || fail "no result with replicates"
"$TESSERA" render "$S" -o "$WORK/rep-ref-$M.exr" --spp "$M" --seed 5 --replicates 2 --resumable -q || fail "render --replicates"
"$EXR_COMPARE" "$WORK/rep-ref-$M.exr" "$WORK/rep-$M.exr" || fail "raised job with replicates differs from render --spp $M"

# render --workers --resumable writes the file render --resumable writes (state channels included).
"$TESSERA" render "$S" -o "$WORK/workers-$N.exr" --spp "$N" --seed 5 --resumable --workers 2 --farm-tile 7 -q \
  >"$WORK/render-workers.log" 2>&1 || fail "render --workers --resumable failed"
"$EXR_COMPARE" "$WORK/ref-$N.exr" "$WORK/workers-$N.exr" || fail "render --workers --resumable differs from render --resumable"

# Refusals, with their sentences.
PLAIN=$("$TESSERA" submit "$S" --coordinator "$URL" --spp "$N" --seed 5 --tile 7 --detach 2>"$WORK/submit-plain.log") \
  || fail "submit failed"
expect_exit 2 "$WORK/raise-plain.log" -- "$TESSERA" jobs spp "$PLAIN" "$M" --coordinator "$URL"
log_has "$WORK/raise-plain.log" "was not submitted as resumable" || fail "raising a plain job did not say why"
expect_exit 2 "$WORK/raise-lower.log" -- "$TESSERA" jobs spp "$JOB" "$M" --coordinator "$URL"
log_has "$WORK/raise-lower.log" "has $M2 spp: it can only be raised" || fail "lowering the spp did not say why"
ADAPTIVE=$("$TESSERA" submit "$S" --coordinator "$URL" --target-error 0.2 --min-spp 2 --max-spp 8 --tile 7 --detach \
  2>"$WORK/submit-adaptive.log") || fail "adaptive submit failed"
expect_exit 2 "$WORK/raise-adaptive.log" -- "$TESSERA" jobs spp "$ADAPTIVE" "$M" --coordinator "$URL"
log_has "$WORK/raise-adaptive.log" "uses adaptive sampling" || fail "raising an adaptive job did not say why"
expect_exit 2 "$WORK/submit-adaptive-resumable.log" -- "$TESSERA" submit "$S" --coordinator "$URL" --target-error 0.2 \
  --resumable --detach
log_has "$WORK/submit-adaptive-resumable.log" "'resumable' needs a fixed spp" || fail "resumable adaptive submit accepted"
echo "PASS"
