#!/usr/bin/env bash
# The release binary holds no test hook: none of the fail point names listed in failpoint/failpoint.h, nor the
# variable that sets them, nor the environment hooks they replaced, appears among its strings; the test binary
# tessera-failpoints, built from the same sources with TESSERA_FAILPOINTS, holds every name the sources use (so this
# check can fail). Arguments: TESSERA TESSERA_FAILPOINTS SOURCE_DIR.
set -euo pipefail
RELEASE=$1
TEST_BINARY=$2
SOURCE=$3
HEADER=$SOURCE/failpoint/failpoint.h

# The names between "kNames = {" and "};" in the header, one per line.
mapfile -t NAMES < <(sed -n '/kNames = {/,/};/p' "$HEADER" | grep -Eo '^ *"[a-z_.]+"' | tr -d ' "')
[ "${#NAMES[@]}" -ge 5 ] || { echo "FAIL: found only ${#NAMES[@]} fail point names in $HEADER" >&2; exit 1; }
HOOKS=(TESSERA_FAIL_POINTS "fail point" TESSERA_WORKER_FAIL_RENDER TESSERA_WORKER_CORRUPT_UPLOAD
       TESSERA_WORKER_STOP_BEFORE_UPLOAD TESSERA_WORKER_UPLOAD_TWICE)

WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-release-binary.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
strings -n 4 "$RELEASE" >"$WORK/release.txt"
strings -n 4 "$TEST_BINARY" >"$WORK/test.txt"
failed=0
for s in "${NAMES[@]}" "${HOOKS[@]}"; do
  if grep -qF -- "$s" "$WORK/release.txt"; then
    echo "FAIL: the release binary contains '$s'" >&2
    failed=1
  fi
done
# The names the coordinator and worker sources pass to the macros.
mapfile -t USED < <(grep -rhoE 'TESSERA_FAIL_POINT[A-Z_]*\("[a-z_.]+"' "$SOURCE"/server "$SOURCE"/worker "$SOURCE"/cli |
  grep -Eo '"[a-z_.]+"' | tr -d '"' | sort -u)
# No names found means the grep no longer matches how the sources name their fail points: the positive control below
# would then check nothing, so that is a failure, not a pass.
[ "${#USED[@]}" -gt 0 ] || { echo "FAIL: found no fail-point names in the sources (is the grep still right?)" >&2; exit 1; }
USED+=(TESSERA_FAIL_POINTS "fail point")
for s in "${USED[@]}"; do
  grep -qF -- "$s" "$WORK/test.txt" || { echo "FAIL: the test binary lacks '$s' (is the check looking right?)" >&2; failed=1; }
done
[ $failed = 0 ] || exit 1
echo "PASS: ${#NAMES[@]} fail point names and ${#HOOKS[@]} hook names absent from $RELEASE; the ${#USED[@]} used ones present in $TEST_BINARY"
