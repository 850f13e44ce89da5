#!/usr/bin/env bash
# serve --listen fd:3 under systemd's socket activation protocol: systemd-socket-activate holds the listening socket and
# starts `tessera serve --listen fd:3` at the first connection (the worker's registration, which waits in the queue
# meanwhile and is answered); a job through it is bitwise the single-process render. (render --workers starts its
# private coordinator on a socket the same way.) Exit 77 (skipped) without systemd-socket-activate.
source "$(dirname "$0")/common.sh"

command -v systemd-socket-activate >/dev/null || { echo "systemd-socket-activate is missing (Debian: systemd)"; exit 77; }
write_sphere_scene "$WORK/scene.json" 20 15 2
"$TESSERA" render "$WORK/scene.json" -o "$WORK/ref.exr" -q

# A free loopback port (systemd-socket-activate takes no port 0); tried again should another program take it first.
for _ in 1 2 3; do
  PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  systemd-socket-activate -l "127.0.0.1:$PORT" "$TESSERA" serve --listen fd:3 --data "$WORK/data" >"$WORK/serve.log" 2>&1 &
  SERVE_PID=$!
  PIDS+=("$SERVE_PID")
  listening() { log_has "$WORK/serve.log" "Listening on 127.0.0.1:$PORT" || ! kill -0 "$SERVE_PID" 2>/dev/null; }
  wait_for listening
  log_has "$WORK/serve.log" "Listening on 127.0.0.1:$PORT" && break
done
log_has "$WORK/serve.log" "Listening on 127.0.0.1:$PORT" || fail "systemd-socket-activate did not listen: $(cat "$WORK/serve.log")"
log_has "$WORK/serve.log" "coordinator listening" && fail "the coordinator started before any connection"
URL="http://127.0.0.1:$PORT"

start_worker w1 --threads 1
"$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 8 -q -o "$WORK/out.exr" >"$WORK/submit.log" 2>&1 ||
  fail "the job failed: $(tail -n 3 "$WORK/submit.log")"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the job differs from the single-process render"
log_has "$WORK/serve.log" "coordinator listening on http://127.0.0.1:$PORT" ||
  fail "the coordinator did not serve the activated socket: $(tail -n 5 "$WORK/serve.log")"
kill -TERM "$WORKER_PID" && wait "$WORKER_PID" || fail "the worker did not stop cleanly"
kill -TERM "$SERVE_PID" && wait "$SERVE_PID" || fail "the coordinator did not stop cleanly"
echo "PASS"
