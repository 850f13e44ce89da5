#!/usr/bin/env bash
# tessera submit end to end: a scene with OBJ and EXR assets is uploaded once (a second submission uploads nothing;
# each submission asks which assets are missing in one request, not one per asset),
# rendered by two workers and downloaded identical to the single-process render, also with every sampling option
# `render` has; the coordinator's 400 message is printed with exit status 2; an unreachable coordinator is a clear
# error.
source "$(dirname "$0")/common.sh"

write_cbox_scene "$WORK/cbox" 32 24 2
"$TESSERA" render "$WORK/cbox/scene.json" -o "$WORK/ref.exr" -q --seed 3
start_serve
start_worker w1 --threads 1
start_worker w2 --threads 1
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 10 --seed 3 -o "$WORK/out.exr" \
  >"$WORK/submit1.log" 2>&1 || fail "submit failed"
log_has "$WORK/submit1.log" "\(10 assets, 10 uploaded\)|\([0-9]+ assets, [1-9][0-9]* uploaded\)" || fail "assets were not uploaded"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 10 --seed 3 --priority 5 -o "$WORK/out2.exr" \
  >"$WORK/submit2.log" 2>&1 || fail "second submit failed"
log_has "$WORK/submit2.log" "assets, 0 uploaded\)" || fail "the second submission uploaded assets again"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out2.exr" || fail "second result differs"
curl -sf "$URL/metrics" >"$WORK/metrics.txt" || fail "no metrics"
grep -q 'tessera_http_request_duration_seconds_count{route="POST /v1/blobs"} 2$' "$WORK/metrics.txt" ||
  fail "not one blob query per submission: $(grep 'route="POST /v1/blobs"' "$WORK/metrics.txt" | grep _count)"
if grep -q 'route="HEAD /v1/blobs/{sha256}"' "$WORK/metrics.txt"; then fail "assets were checked one by one"; fi

# Every sampling option `render` has goes with a submitted job too: the result is bitwise the single-process render
# with the same options, which differs from the plain one.
SAMPLING=(--seed 5 --target-error 0.2 --min-spp 2 --max-spp "$(spp 8 2)" --error-floor 0.05 --replicates 2
  --area-sampling area --bvh median)
"$TESSERA" render "$WORK/cbox/scene.json" -o "$WORK/ref-sampling.exr" -q "${SAMPLING[@]}"
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 10 -o "$WORK/out-sampling.exr" "${SAMPLING[@]}" \
  >"$WORK/submit-sampling.log" 2>&1 || fail "submit with every sampling option failed"
"$EXR_COMPARE" "$WORK/ref-sampling.exr" "$WORK/out-sampling.exr" || fail "the job with sampling options differs"
expect_exit 1 "$WORK/compare-sampling.log" -- "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/ref-sampling.exr"
# ... and `jobs show` tells them (from the job's spec).
JOB=$(sed -nE 's/^submitted .* as (j-[^ ]+) .*/\1/p' "$WORK/submit-sampling.log")
[ -n "$JOB" ] || fail "no job id in the submission's output"
"$TESSERA" jobs show "$JOB" --coordinator "$URL" >"$WORK/show-sampling.json" || fail "jobs show failed"
python3 - "$WORK/show-sampling.json" <<'PY' || fail "jobs show does not tell the job's sampling settings"
import json, sys
s = json.load(open(sys.argv[1]))["sampling"]
assert (s["seed"], s["replicates"], s["area_sampling"], s["bvh"]) == (5, 2, "area", "median"), s
assert (s["target_error"], s["min_spp"], s["error_floor"]) == (0.2, 2, 0.05), s
PY

write_sphere_scene "$WORK/bad.json" 8 8 1
sed -i 's/"radius": 0.7/"radius": -1/' "$WORK/bad.json"
expect_exit 2 "$WORK/submit-bad.log" -- "$TESSERA" submit "$WORK/bad.json" --coordinator "$URL" -o "$WORK/bad.exr"
log_has "$WORK/submit-bad.log" "answered 400: .*radius" || fail "the coordinator's message was not printed"

kill -TERM "$SERVE_PID"
wait "$SERVE_PID" || true
expect_exit 1 "$WORK/submit-down.log" -- "$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" -o "$WORK/none.exr"
log_has "$WORK/submit-down.log" "cannot connect" || fail "no clear message for an unreachable coordinator"
echo "PASS"
