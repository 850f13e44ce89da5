#!/usr/bin/env bash
# The chaos soak of a Tessera farm (tests/soak/soak.py; docs/operations.md, "Sustained faults").
#   bash tests/soak/run.sh [--minutes N] [--build DIR] [soak.py options: --seed S, --jobs J, --workers W, --keep ...]
# --minutes N: N minutes of faults (default 1.25, the CI version); --jobs defaults to 12 per minute of faults.
# Uses DIR/cli/tessera and DIR/tests/exr_compare (DIR: build, from the repository's root). Exit status 0: pass.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=$ROOT/build
MINUTES=1.25
ARGS=()
JOBS=
while [ $# -gt 0 ]; do
  case $1 in
    --minutes) MINUTES=$2; shift 2 ;;
    --build) BUILD=$2; shift 2 ;;
    --jobs) JOBS=$2; shift 2 ;;
    *) ARGS+=("$1"); shift ;;
  esac
done
SECONDS_OF_FAULTS=$(python3 -c "print(round(float('$MINUTES') * 60))")
[ -n "$JOBS" ] || JOBS=$(python3 -c "print(max(4, round(float('$MINUTES') * 12)))")
exec python3 "$ROOT/tests/soak/soak.py" --tessera "$BUILD/cli/tessera" --exr-compare "$BUILD/tests/exr_compare" \
  --course "$ROOT/scenes/course" --seconds "$SECONDS_OF_FAULTS" --jobs "$JOBS" "${ARGS[@]}"
