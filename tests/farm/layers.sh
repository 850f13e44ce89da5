#!/usr/bin/env bash
# A job with every output layer carried through the farm: two workers, one SIGKILLed in the middle of a tile; the
# result (as `submit -o` saves it and as `jobs wait -o` fetches it) is bitwise the single-process layered render in
# every channel, with the same Cryptomatte manifests; `render --workers --layers --multipart` writes one part per
# layer with the same pixels.
source "$(dirname "$0")/common.sh"

LAYERS=albedo,normal,depth,position,material_id,object_id,variance,crypto_material,crypto_object
write_sphere_scene "$WORK/s.json" 32 32 8
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1 --layers "$LAYERS"
start_serve --lease-seconds 2 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr" --layers "$LAYERS"

FAIL_POINTS=worker.render=pause start_worker victim --threads 2
VICTIM=$WORKER_PID
wait_for paused "$WORK/victim.log" || fail "the victim held no tile"
kill -KILL "$VICTIM"
wait "$VICTIM" 2>/dev/null || true
TILE=$(grep -Eo "tile=[0-9]+ lease=[^:]+: leased window" "$WORK/victim.log" | head -n1 | grep -Eo "tile=[0-9]+")
[ -n "$TILE" ] || fail "no lease in the victim's log"

start_worker survivor --threads 2
wait "$SUBMIT_PID" || fail "submit exited with $?"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the layered result differs from the single-process render"
log_has "$WORK/survivor.log" "$TILE lease=.*upload accepted" || fail "the survivor did not render the victim's $TILE"
for f in ref out; do exrheader "$WORK/$f.exr" | grep -E '^(cryptomatte/|    [A-Za-z_.0-9]+, )' >"$WORK/$f.header"; done
diff "$WORK/ref.header" "$WORK/out.header" || fail "channels or Cryptomatte attributes differ"
grep -q "crypto_object00.R" "$WORK/out.header" || fail "no Cryptomatte channels in the result"

JOB=$(grep -Eo "as j-[^ ]+" "$WORK/submit.log" | head -n1 | cut -c4-)
[ -n "$JOB" ] || fail "no job id in submit's output"
"$TESSERA" jobs wait "$JOB" --coordinator "$URL" -o "$WORK/waited.exr" >"$WORK/wait.log" 2>&1 || fail "jobs wait -o failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/waited.exr" || fail "jobs wait -o saved other pixels"

# A local farm writing one part per layer: merged back to one part, the same bits.
"$TESSERA" render "$WORK/s.json" -o "$WORK/farm.exr" -q --workers 2 --farm-tile 16 --layers "$LAYERS" --multipart \
  >"$WORK/farm.log" 2>&1 || fail "render --workers --layers --multipart failed: $(tail -n 3 "$WORK/farm.log")"
# (into a file first: grep -q stops reading at its match, and under pipefail exrheader's SIGPIPE would fail the line)
exrheader "$WORK/farm.exr" >"$WORK/farm.header"
grep -q '^name (type string): "crypto_material"' "$WORK/farm.header" || fail "no crypto_material part"
"$TESSERA" merge "$WORK/farm.exr" -o "$WORK/farm-one.exr" || fail "merge of the multi-part result failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/farm-one.exr" || fail "the multi-part farm render differs"
echo "PASS"
