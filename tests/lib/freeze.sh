# A worker that freezes itself (SIGSTOP) once, after rendering a tile and before uploading it (sourced; needs
# $TESSERA). Builds with fail points have the test binary tessera-failpoints beside tessera, frozen by the fail point
# worker.upload; older builds have only the release binary's hook TESSERA_WORKER_STOP_BEFORE_UPLOAD.
# shellcheck shell=bash

# freeze_setup: sets FREEZE_BIN (the binary to run) and FREEZE_ENV (environment assignments for `env`).
freeze_setup() {
  local test_binary
  test_binary="$(dirname "$TESSERA")/tessera-failpoints"
  if [ -x "$test_binary" ]; then
    FREEZE_BIN=$test_binary
    FREEZE_ENV=("TESSERA_FAIL_POINTS=worker.upload=1*stop")
  else
    FREEZE_BIN=$TESSERA
    FREEZE_ENV=("TESSERA_WORKER_STOP_BEFORE_UPLOAD=1")
  fi
}

# frozen_tile LOG: "tile=N" of the tile a frozen worker rendered last (the one waiting for its upload).
frozen_tile() { grep -Eo "tile=[0-9]+ lease=[^:]+: rendered in" "$1" | tail -n1 | grep -Eo "tile=[0-9]+"; }
