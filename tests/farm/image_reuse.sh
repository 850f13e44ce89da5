#!/usr/bin/env bash
# A worker keeps the decoded pixels of a job's image textures for later jobs that use the same files (by default up
# to 1 GiB): the second job of the textured Cornell box takes its texture from memory, and both jobs are bitwise the
# single-process renders. With --image-cache-mb 0 every job decodes its images. An environment map's sampling table,
# built from its pixels, is kept with them: the course's glass sphere under its sky, twice through one worker, builds the
# table once, and both jobs are again bitwise the single-process renders.
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
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the worker without a cache did not stop cleanly"
built=$(grep -o "built the job's scene.*" "$WORK/decodes.log" | grep -o '[0-9]* image(s) taken already decoded' | cut -d' ' -f1 | xargs)
[ "$built" = "0 0" ] || fail "with --image-cache-mb 0, scenes built with '$built' images taken already decoded, expected '0 0'"

# The only worker from here on, so both sky jobs' scenes are built by it.
write_cbox_scene "$WORK/sky" 24 18 2 glass_sphere.json
for seed in 1 2; do "$TESSERA" render "$WORK/sky/scene.json" -q --seed "$seed" -o "$WORK/sky-ref-$seed.exr"; done
start_worker sky --threads 2
for seed in 1 2; do
  "$TESSERA" submit "$WORK/sky/scene.json" --coordinator "$URL" --tile 8 --seed "$seed" -q -o "$WORK/sky-$seed.exr" \
    >"$WORK/submit-sky-$seed.log" 2>&1 || fail "sky job with seed $seed failed"
  "$EXR_COMPARE" "$WORK/sky-ref-$seed.exr" "$WORK/sky-$seed.exr" || fail "sky job with seed $seed differs"
done
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the sky worker did not stop cleanly"
kept=$(grep -o "built the job's scene.*" "$WORK/sky.log" | grep -c "the environment's sampling table kept" || true)
[ "$kept" = 1 ] || fail "the sky's sampling table was kept in $kept scene builds, expected 1 (the second job's)"
echo "PASS"
