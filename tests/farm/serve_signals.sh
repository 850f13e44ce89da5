#!/usr/bin/env bash
# Coordinator shutdown under repeated signals, as supervisors deliver them (Slurm's scancel signals both the batch
# shell, which passes SIGTERM on, and the coordinator itself): a stream of SIGTERMs (then SIGINTs) sent until the
# process is gone must still end in exit status 0, five times in a row, and the job queued before each stop must be
# resumed by the next start on the same data folder (it was not lost or corrupted by a signal mid-shutdown). The
# helper threads (the step runner's, the webhook sender's) block the signals, as the coordinator's own helpers do.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 8 8 1
for round in 1 2 3 4 5; do
  start_serve --webhook-allow http://127.0.0.1:9/  # the webhook sender's threads run too
  if [ "$round" = 1 ]; then
    # No worker runs, so the job stays queued across every stop.
    "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --detach >"$WORK/submit.log" 2>&1 || fail "submit --detach failed"
  else
    log_has "$WORK/serve.log" "resuming 1 queued and 0 running job" || fail "round $round did not resume the queued job"
  fi
  sig=TERM
  [ $((round % 2)) = 0 ] && sig=INT
  sent=0
  while kill -"$sig" "$SERVE_PID" 2>/dev/null; do sent=$((sent + 1)); done
  rc=0
  wait "$SERVE_PID" || rc=$?
  [ "$rc" = 0 ] || fail "round $round: the coordinator exited with status $rc under $sent SIG$sig signals"
  echo "round $round: exit 0 after $sent SIG$sig signals"
  mv "$WORK/serve.log" "$WORK/serve-$round.log"   # the next round's resume message is looked for in a fresh log
done
echo "PASS"
