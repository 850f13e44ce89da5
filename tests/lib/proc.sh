# Process helpers shared by the shell tests (sourced; pure functions, no side effects when sourced).
# shellcheck shell=bash

# stop_pids GRACE_TENTHS PID...: SIGTERM to each pid in the order given, then up to GRACE_TENTHS x 0.1 s for all of
# them to exit (polled with kill -0), then SIGKILL to any left. Never fails, so it is safe in EXIT traps under set -e.
stop_pids() {
  local tenths=$1 p alive
  shift
  for p; do kill -TERM "$p" 2>/dev/null || true; done
  for _ in $(seq "$tenths"); do
    alive=0
    for p; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ $alive = 0 ] && break
    sleep 0.1
  done
  for p; do kill -KILL "$p" 2>/dev/null || true; done
  return 0
}
