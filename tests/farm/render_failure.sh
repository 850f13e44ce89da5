#!/usr/bin/env bash
# Workers that cannot render report it through /fail: once the same tile failed on 3 different workers the job is
# failed, and submit prints the reason and exits 1. The workers keep running.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 16 16 1
start_serve
for w in a b c; do FAIL_POINTS=worker.render=error start_worker "$w" --threads 1; done
# All three registered before the job exists: a job whose every registered worker is blocklisted fails at once, so a
# worker still starting when the first two failures land would leave the job failed by one worker.
for w in a b c; do wait_for log_has "$WORK/serve.log" "registered '$w'" || fail "worker $w did not register"; done
expect_exit 1 "$WORK/submit.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 -o "$WORK/out.exr"
log_has "$WORK/submit.log" "failed: .*injected error at fail point worker.render" || fail "the failure reason was not printed"
[ ! -e "$WORK/out.exr" ] || fail "an output was written for a failed job"
for w in a b c; do  # each logs it once its /fail is answered, which may come after submit saw the job fail
  wait_for log_has "$WORK/$w.log" "failure reported" || fail "worker $w did not report its failure"
done
for p in "${PIDS[@]:1}"; do kill -0 "$p" || fail "a worker exited after its render failed"; done
echo "PASS"
