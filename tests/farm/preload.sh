#!/usr/bin/env bash
# worker --preload: a worker told the submission it is about to be leased loads that scene from its cache at start,
# and the job with the same scene, assets and loading settings (any seed and spp) renders from it without loading
# it again, bitwise as the single-process render; a job of another scene, or loaded another way (--bvh median), is
# built as usual. (render --workers tells its workers the job it submits this way.)
source "$(dirname "$0")/common.sh"

write_cbox_scene "$WORK/cbox" 24 18 2
start_serve
"$TESSERA" render "$WORK/cbox/scene.json" -q --seed 4 --spp "$(spp 3)" -o "$WORK/ref.exr"
"$TESSERA" render "$WORK/cbox/scene.json" -q --bvh median -o "$WORK/ref-median.exr"

# A first worker renders one job, which puts the scene's assets in its cache.
start_worker w1 --threads 1
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 8 -q -o "$WORK/first.exr" >"$WORK/first.log" 2>&1 ||
  fail "the first job failed: $(tail -n 3 "$WORK/first.log")"
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the first worker did not stop cleanly"

# The submission `tessera submit` would send for the scene (its assets by hash, as the scene names them).
python3 - "$WORK/cbox" "$WORK/expected.json" <<'PY'
import hashlib, json, os, sys
folder, out = sys.argv[1:]
scene = json.load(open(os.path.join(folder, "scene.json")))
paths = set()
def walk(v):
    if isinstance(v, dict):
        for k, x in v.items():
            if k == "path" and isinstance(x, str): paths.add(x)
            else: walk(x)
    elif isinstance(v, list):
        for x in v: walk(x)
walk(scene)
assets = {p: hashlib.sha256(open(os.path.join(folder, p), "rb").read()).hexdigest() for p in sorted(paths)}
json.dump({"scene": scene, "assets": assets, "name": "expected"}, open(out, "w"))
PY

cp -r "$WORK/cache-w1" "$WORK/cache-w2"
start_worker w2 --threads 1 --preload "$WORK/expected.json"
# Same scene, another seed and spp than the submission's: it renders from the preloaded scene.
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 8 --seed 4 --spp "$(spp 3)" -q -o "$WORK/a.exr" \
  >"$WORK/a.log" 2>&1 || fail "job a failed: $(tail -n 3 "$WORK/a.log")"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/a.exr" || fail "the job rendered from the preloaded scene differs"
log_has "$WORK/w2.log" "took the job's scene loaded at start \(--preload\)" ||
  fail "the preloaded scene was not taken: $(grep "job's scene" "$WORK/w2.log")"
# Loaded another way: built for the job (the preload was taken already, and would not match).
"$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 8 --bvh median -q -o "$WORK/b.exr" \
  >"$WORK/b.log" 2>&1 || fail "job b failed: $(tail -n 3 "$WORK/b.log")"
"$EXR_COMPARE" "$WORK/ref-median.exr" "$WORK/b.exr" || fail "job b differs"
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the second worker did not stop cleanly"
[ "$(grep -c "took the job's scene loaded at start" "$WORK/w2.log")" = 1 ] || fail "the preload was taken more than once"
[ "$(grep -c "built the job's scene" "$WORK/w2.log")" = 1 ] || fail "job b's scene was not built"

# A submission that does not parse is refused at start.
echo '{"scene": 1}' >"$WORK/bad.json"
expect_exit 2 "$WORK/bad-preload.log" -- "$TESSERA" worker --coordinator "$URL" --preload "$WORK/bad.json"
log_has "$WORK/bad-preload.log" "--preload $WORK/bad.json: " || fail "no clear error for a bad --preload: $(cat "$WORK/bad-preload.log")"
echo "PASS"
