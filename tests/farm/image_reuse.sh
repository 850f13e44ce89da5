#!/usr/bin/env bash
# A worker keeps the decoded pixels of a job's image textures for later jobs that use the same files (by default up
# to 1 GiB): the second job of the textured Cornell box takes its texture from memory, and both jobs are bitwise the
# single-process renders. With --image-cache-mb 0 every job decodes its images.
source "$(dirname "$0")/common.sh"

write_cbox_scene "$WORK/cbox" 24 18 2
start_serve
# run_jobs WORKER: two jobs (seeds 1 and 2) through the running worker, each checked against its reference.
run_jobs() {
  local seed
  for seed in 1 2; do
    "$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 8 --seed "$seed" -q -o "$WORK/$1-$seed.exr" \
      >"$WORK/submit-$1-$seed.log" 2>&1 || fail "job with seed $seed through $1 failed"
    "$EXR_COMPARE" "$WORK/ref-$seed.exr" "$WORK/$1-$seed.exr" || fail "job with seed $seed through $1 differs"
  done
}
for seed in 1 2; do "$TESSERA" render "$WORK/cbox/scene.json" -q --seed "$seed" -o "$WORK/ref-$seed.exr"; done

start_worker keeps --threads 1
run_jobs keeps
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the worker did not stop cleanly"
built=$(grep -o "built the job's scene.*" "$WORK/keeps.log" | grep -o '[0-9]* image(s) taken already decoded' | cut -d' ' -f1 | xargs)
[ "$built" = "0 1" ] || fail "scenes built with '$built' images taken already decoded, expected '0 1'"

start_worker decodes --threads 1 --image-cache-mb 0
run_jobs decodes
built=$(grep -o "built the job's scene.*" "$WORK/decodes.log" | grep -o '[0-9]* image(s) taken already decoded' | cut -d' ' -f1 | xargs)
[ "$built" = "0 0" ] || fail "with --image-cache-mb 0, scenes built with '$built' images taken already decoded, expected '0 0'"
echo "PASS"
