#!/usr/bin/env bash
# A job's spec comes with a worker's first lease of it: the worker names the jobs whose scenes it holds, and the
# coordinator puts the spec of any other job into the lease's answer, so no worker GETs a spec. Three jobs of nine
# tiles through one worker: each job's scene built once, from a spec sent with its first lease, none fetched; the
# coordinator's metrics count no GET of a spec; every output is bitwise the single-process render.
source "$(dirname "$0")/common.sh"

write_cbox_scene "$WORK/cbox" 24 18 2
start_serve
for seed in 1 2; do "$TESSERA" render "$WORK/cbox/scene.json" -q --seed "$seed" -o "$WORK/ref-$seed.exr"; done

start_worker w1 --threads 1
# job SEED NAME: one job through the running worker, checked against its reference.
job() {
  "$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 8 --seed "$1" -q -o "$WORK/$2.exr" \
    >"$WORK/submit-$2.log" 2>&1 || fail "job $2 failed: $(tail -n 3 "$WORK/submit-$2.log")"
  "$EXR_COMPARE" "$WORK/ref-$1.exr" "$WORK/$2.exr" || fail "job $2 differs from its single-process render"
}
job 1 a
job 2 b
job 1 c
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the worker did not stop cleanly"

specs=$({ grep -o "built the job's scene.*" "$WORK/w1.log" || true; } | { grep -o 'spec [a-z ]*' || true; } | sort | uniq -c | xargs)
[ "$specs" = "3 spec sent with the lease" ] || fail "scenes built from: '$specs', expected 3 from specs sent with leases"
curl -sf "$URL/metrics" >"$WORK/metrics.txt" || fail "no metrics"
if grep -q 'route="GET /v1/jobs/{id}/spec"' "$WORK/metrics.txt"; then
  fail "specs were fetched: $(grep 'spec"}' "$WORK/metrics.txt" | grep _count)"
fi
grep -q 'tessera_http_request_duration_seconds_count{route="POST /v1/workers/{wid}/lease"}' "$WORK/metrics.txt" ||
  fail "the metrics count no lease requests"
echo "PASS"
