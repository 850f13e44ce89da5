#!/usr/bin/env bash
# A sequence of 6 frames (each at an spp of its own) through 2 workers, with a worker killed (SIGKILL, holding a
# leased tile) and the coordinator killed and restarted mid-sequence: every frame is written by `submit -o` as it
# finishes, bitwise equal to its own single-process render, and no stored tile is rendered again (every tile once,
# plus at most the tiles held at the kills). The hold is by construction: each worker renders one tile, then holds its
# next (fail point worker.render) until the restart. Then a second sequence, cancelled before any worker runs, is
# retried for frames 2-3 only: the worker leases exactly those frames' tiles, `jobs frames` shows them done and the
# rest cancelled, and frame 2's result (GET /v1/jobs/{id}/frames/2/result.exr) equals its single render.
source "$(dirname "$0")/common.sh"

mkdir -p "$WORK/shot" "$WORK/out"
for k in 1 2 3 4 5 6; do
  write_sphere_scene "$WORK/s.json" 32 32 $((2 * k))  # each frame its own spp
  sed "s/\"position\": \[0, 0.3, 4\]/\"position\": [0.$k, 0.3, 4]/" "$WORK/s.json" >"$WORK/shot/frame_0$k.json"
  "$TESSERA" render "$WORK/shot/frame_0$k.json" -o "$WORK/ref_$k.exr" -q --threads 1
done
TILES=24  # 6 frames of 32x32 in 16-pixel tiles
# Bad command lines are refused before anything is sent or rendered (exit 2), each with a sentence.
refused() {  # refused PATTERN COMMAND...: exit 2 and a log line matching PATTERN
  local pattern=$1
  shift
  expect_exit 2 "$WORK/refused.log" -- "$@"
  log_has "$WORK/refused.log" "$pattern" || fail "'$*' did not say: $pattern ($(cat "$WORK/refused.log"))"
}
refused "frame 7: .*frame_07.json does not exist" "$TESSERA" render "$WORK/shot/frame_##.json" --frames 1-7 -o "$WORK/x_##.exr"
refused "needs a frame range \(--frames\)" "$TESSERA" render "$WORK/shot/frame_##.json" -o "$WORK/x_##.exr"
refused "has no run of '#'" "$TESSERA" render "$WORK"/shot/frame_0*.json -o "$WORK/x.exr"
refused "ends before it starts" "$TESSERA" submit "$WORK/shot/frame_##.json" --frames 6-1 --coordinator http://127.0.0.1:9
printf '{"camera": ' >"$WORK/broken_03.json"
cp "$WORK/shot/frame_01.json" "$WORK/broken_01.json"
refused "frame 3: " "$TESSERA" render "$WORK/broken_01.json" "$WORK/broken_03.json" -o "$WORK/x_##.exr"
[ ! -e "$WORK/x_01.exr" ] || fail "a refused sequence wrote frame 1"
start_serve --lease-seconds 4 --heartbeat-seconds 1
ADDRESS=$(head -n1 "$WORK/ready")
start_submit "$WORK/submit.log" "$WORK/shot/frame_##.json" --frames 1-6 --tile 16 -o "$WORK/out/f_##.exr"
wait_for log_has "$WORK/submit.log" "submitted 6 frames \(1 to 6\) as j-" || fail "the sequence was not submitted"
FAIL_POINTS="worker.render=1*off->pause($WORK/go)" start_worker w1 --threads 2
W1=$WORKER_PID
FAIL_POINTS="worker.render=1*off->pause($WORK/go)" start_worker w2 --threads 2

merged() { grep -c ": merged" "$WORK/serve.log" 2>/dev/null || true; }
held() { paused "$WORK/w1.log" && paused "$WORK/w2.log" && [ "$(merged)" -ge 2 ]; }
wait_for held || fail "the workers did not render a tile each and hold their next ones"
kill -KILL "$W1"  # dies holding a leased tile: only that tile is lost
kill -KILL "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
BEFORE=$(merged)
[ "$BEFORE" = 2 ] || fail "$BEFORE tiles merged before the kill, expected 2"
notices() { log_has "$WORK/w2.log" "unreachable|failed"; }
wait_for notices || fail "the surviving worker did not notice the coordinator was gone"
LISTEN=$ADDRESS start_serve --lease-seconds 4 --heartbeat-seconds 1
release go
start_worker w3 --threads 1

wait "$SUBMIT_PID" || fail "submit exited with $? across the kills"
for k in 1 2 3 4 5 6; do
  [ -f "$WORK/out/f_0$k.exr" ] || fail "frame $k was not written"
  "$EXR_COMPARE" "$WORK/ref_$k.exr" "$WORK/out/f_0$k.exr" || fail "frame $k differs from its single render"
done
RENDERED=$(cat "$WORK/w1.log" "$WORK/w2.log" "$WORK/w3.log" | grep -c ": rendered in")
echo "tiles rendered in total: $RENDERED for $TILES tiles ($BEFORE stored before the kills)"
[ "$RENDERED" -ge "$TILES" ] || fail "only $RENDERED renders for $TILES tiles"
[ "$RENDERED" -le $((TILES + 2)) ] || fail "$RENDERED renders for $TILES tiles: stored tiles were rendered again"
# The frames as one contact sheet: 3 columns of 16-px copies, 2-px gaps: 2 + 3 x 18 = 56 by 2 + 2 x 18 = 38 pixels.
"$TESSERA" contact-sheet "$WORK"/out/f_0*.exr -o "$WORK/sheet.png" --thumb-width 16 --columns 3 2>"$WORK/sheet.log" ||
  fail "contact-sheet failed: $(cat "$WORK/sheet.log")"
[ "$(python3 -c 'import struct,sys; d=open(sys.argv[1],"rb").read(24); print(*struct.unpack(">II", d[16:24]))' \
  "$WORK/sheet.png")" = "56 38" ] || fail "the contact sheet is not 56x38"
refused "$WORK/shot/frame_01.json" "$TESSERA" contact-sheet "$WORK/out/f_01.exr" "$WORK/shot/frame_01.json" -o "$WORK/bad.png"
[ ! -e "$WORK/bad.png" ] || fail "a refused contact sheet was written"
SEQ=$(grep -Eo "as j-[^ ]+" "$WORK/submit.log" | head -n1 | cut -c4-)
"$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls.log" "^$SEQ +done .* 24/24 .*\[6/6 frames\]" || fail "jobs ls does not show the sequence as one done job"
[ "$(grep -c "^j-" "$WORK/ls.log")" = 1 ] || fail "jobs ls lists the frames' jobs: $(cat "$WORK/ls.log")"

# Retry of chosen frames: a sequence cancelled before any worker took a tile, retried for frames 2 and 3.
kill -TERM "$WORKER_PID"
for p in "${PIDS[@]}"; do [ "$p" = "$SERVE_PID" ] || kill -TERM "$p" 2>/dev/null || true; done
JOB=$("$TESSERA" submit "$WORK/shot/frame_##.json" --frames 1-6 --tile 16 --coordinator "$URL" --detach \
  2>"$WORK/submit2.log") || fail "the second submission failed"
"$TESSERA" jobs cancel "$JOB" --coordinator "$URL" >"$WORK/cancel.log" 2>&1 || fail "jobs cancel failed"
expect_exit 2 "$WORK/retry-frame-job.log" -- "$TESSERA" jobs retry "$JOB.f2" --coordinator "$URL"
log_has "$WORK/retry-frame-job.log" "is frame 2 of sequence $JOB" || fail "a frame's job was retried on its own"
"$TESSERA" jobs retry "$JOB" --frames 2-3 --coordinator "$URL" >"$WORK/retry.log" 2>&1 || fail "jobs retry --frames failed"
log_has "$WORK/retry.log" "queued again, 2 of 6 frames to render" || fail "retry --frames 2-3 did not queue 2 frames: $(cat "$WORK/retry.log")"
start_worker w4 --threads 1
ended() { "$TESSERA" jobs show "$JOB" --coordinator "$URL" 2>/dev/null | grep -q '"state": "cancelled"'; }
wait_for ended || fail "the retried frames did not finish"
[ "$(grep -c "leased window" "$WORK/w4.log")" = 8 ] ||
  fail "the worker leased $(grep -c "leased window" "$WORK/w4.log") tiles, not the 8 of frames 2 and 3"
"$TESSERA" jobs frames "$JOB" --coordinator "$URL" >"$WORK/frames.log" 2>&1 || fail "jobs frames failed"
for k in 1 4 5 6; do log_has "$WORK/frames.log" "^ +$k +$JOB.f$k +cancelled" || fail "frame $k is not cancelled"; done
for k in 2 3; do log_has "$WORK/frames.log" "^ +$k +$JOB.f$k +done +4/4" || fail "frame $k is not done"; done
curl -sS -f -o "$WORK/f2.exr" "$URL/v1/jobs/$JOB/frames/2/result.exr" || fail "no result for frame 2"
"$EXR_COMPARE" "$WORK/ref_2.exr" "$WORK/f2.exr" || fail "the retried frame 2 differs from its single render"
echo "PASS"
