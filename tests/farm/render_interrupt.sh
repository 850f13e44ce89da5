#!/usr/bin/env bash
# render --workers stops its coordinator and workers whatever happens: after Ctrl-C (SIGINT) in the middle of a
# render it exits 130 and none of its children is left; a scene the coordinator refuses is reported with the
# coordinator's message and leaves no child behind either.
source "$(dirname "$0")/common.sh"

children_of() { ps -o pid= --ppid "$1" 2>/dev/null | tr -d ' '; }
# Processes started by a render --workers of this test (their command lines name its temporary folder).
leftovers() { pgrep -f -- "$WORK/tessera-render" || true; }
export TMPDIR=$WORK

write_sphere_scene "$WORK/slow.json" 64 64 4096
"$TESSERA" render "$WORK/slow.json" -o "$WORK/slow.exr" --workers 2 --farm-tile 16 >"$WORK/render.log" 2>&1 &
RENDER=$!
PIDS+=("$RENDER")
has_three_children() { [ "$(children_of "$RENDER" | wc -l)" -ge 3 ]; }
wait_for has_three_children || fail "render --workers did not start a coordinator and 2 workers"
wait_for log_has "$WORK/render.log" "submitted" || fail "nothing submitted"
KIDS=$(children_of "$RENDER")
kill -INT "$RENDER"
set +e
wait "$RENDER"
rc=$?
set -e
[ $rc = 130 ] || fail "interrupted render exited with $rc, not 130"
for k in $KIDS; do
  if kill -0 "$k" 2>/dev/null; then fail "child $k of the interrupted render is still running"; fi
done
[ -z "$(leftovers)" ] || fail "processes of the interrupted render are still running: $(leftovers)"
[ ! -e "$WORK/slow.exr" ] || fail "an interrupted render wrote its output"

write_sphere_scene "$WORK/bad.json" 8 8 1
sed -i 's/"radius": 0.7/"radius": -1/' "$WORK/bad.json"
"$TESSERA" render "$WORK/bad.json" -o "$WORK/bad.exr" --workers 1 >"$WORK/render-bad.log" 2>&1 &
BAD=$!
PIDS+=("$BAD")
set +e
wait "$BAD"
rc=$?
set -e
[ $rc != 0 ] || fail "a refused scene rendered"
log_has "$WORK/render-bad.log" "radius" || fail "the coordinator's message was not shown"
[ -z "$(leftovers)" ] || fail "processes of the failed render are still running: $(leftovers)"
echo "PASS"
