# A worker that freezes itself (SIGSTOP) once, after rendering a tile and before uploading it (sourced; needs
# $TESSERA): the test binary tessera-failpoints beside tessera, frozen by its fail point worker.upload.
# shellcheck shell=bash

# freeze_setup: sets FREEZE_BIN (the binary to run) and FREEZE_ENV (environment assignments for `env`).
freeze_setup() {
  FREEZE_BIN="$(dirname "$TESSERA")/tessera-failpoints"
  [ -x "$FREEZE_BIN" ] || fail "no test binary $FREEZE_BIN (built with the tests)"
  FREEZE_ENV=("TESSERA_FAIL_POINTS=worker.upload=1*stop")
}

# frozen_tile LOG: "tile=N" of the tile whose upload froze the worker: the first it rendered, since uploads go in the
# order of the renders and the fail point stops the first (the render of the next tile, begun ahead on threads the
# first left idle, may have ended too before the upload began).
frozen_tile() { grep -Eo "tile=[0-9]+ lease=[^:]+: rendered in" "$1" | head -n1 | grep -Eo "tile=[0-9]+"; }
