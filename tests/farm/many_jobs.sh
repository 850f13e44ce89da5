#!/usr/bin/env bash
# 100 jobs submitted concurrently (100 `tessera submit` processes at once, each with its own seed) to a coordinator
# with two workers: every job completes, none is lost or duplicated, and every image is bitwise identical to the
# single-process render with the same seed.
source "$(dirname "$0")/common.sh"
N=100

write_sphere_scene "$WORK/scene.json" 16 12 2
start_serve
start_worker w1 --threads 1
start_worker w2 --threads 1

SUBMITS=()
for i in $(seq $N); do
  "$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 8 --seed "$i" -q -o "$WORK/out-$i.exr" \
    >"$WORK/submit-$i.out" 2>&1 &
  SUBMITS+=($!)
done
# Meanwhile the references, two at a time.
seq $N | xargs -P 2 -I{} "$TESSERA" render "$WORK/scene.json" -q --seed {} -o "$WORK/ref-{}.exr"

failed=0
for i in $(seq $N); do
  wait "${SUBMITS[$((i - 1))]}" || { echo "submit $i failed: $(tail -n 3 "$WORK/submit-$i.out")" >&2; failed=$((failed + 1)); }
done
[ $failed = 0 ] || fail "$failed of $N submissions failed"
for i in $(seq $N); do
  "$EXR_COMPARE" "$WORK/ref-$i.exr" "$WORK/out-$i.exr" >/dev/null || fail "job with seed $i differs from its reference"
done

# The coordinator knows exactly N jobs, all done, each with all 4 tiles merged once.
curl -fsS "$URL/v1/jobs" >"$WORK/jobs.json" || fail "cannot list jobs"
python3 - "$WORK/jobs.json" $N <<'PY' || fail "job list check failed"
import json, sys
jobs = json.load(open(sys.argv[1]))["jobs"]
n = int(sys.argv[2])
assert len(jobs) == n, f"{len(jobs)} jobs listed, expected {n}"
assert len({j["id"] for j in jobs}) == n, "duplicate job ids"
bad = [j["id"] for j in jobs if j["state"] != "done" or j["tiles"]["done"] != j["tiles"]["total"] or j["tiles"]["total"] != 4]
assert not bad, f"jobs not cleanly done: {bad[:5]}"
PY
echo "PASS"
