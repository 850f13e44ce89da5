#!/usr/bin/env bash
# The fixed cost of a render counted in instructions, which other work on the machine does not change (valgrind's
# callgrind counts them, where perf stat has no hardware counters): `tessera render` of scenes/cbox_no_light.json at
# 128x128 at 1 and 8 spp and `tessera --version`, fitted as bench/fixed_cost.sh fits wall times, I = a + b*spp; the
# fixed part is a less the floor (`--version`) and the scene load (load_scene_file, with the scene's hash), and of it
# the EXR's ZIP compression (Tessera's ZipChunkCompressor::compress with libdeflate, or in an older build OpenEXR's
# OutputFile::writePixels with zlib). The kernel's work (page faults, the
# synced write) is not counted: bench/fixed_cost.sh has it in wall time. With OTHER_BUILD_DIR, the same for that
# build beside it.
#   bash bench/fixed_cost_instructions.sh BUILD_DIR [OTHER_BUILD_DIR]
set -euo pipefail
BUILD=${1:?usage: fixed_cost_instructions.sh BUILD_DIR [OTHER_BUILD_DIR]}
OTHER=${2:-}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
command -v valgrind >/dev/null || { echo "fixed_cost_instructions.sh needs valgrind (apt-get install valgrind)" >&2; exit 2; }
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-fixed-instructions.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
cp -r "$ROOT/scenes/assets" "$WORK/"  # the scene's asset paths are relative to it
python3 - "$ROOT/scenes/cbox_no_light.json" "$WORK/cbox128.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["film"]["resolution"] = [128, 128]
json.dump(s, open(sys.argv[2], "w"))
PY

# inclusive PATTERN: the inclusive count of the first (largest) function whose line holds PATTERN, or 0
inclusive() {
  awk -v pat="$1" 'index($0, pat) { gsub(",", "", $1); print $1; found = 1; exit } END { if (!found) print 0 }' \
    "$WORK/annotated"
}
# count BUILD ARGS...: runs tessera ARGS under callgrind; sets TOTAL, LOAD and ZIP (instructions)
count() {
  local build=$1
  shift
  valgrind --tool=callgrind --callgrind-out-file="$WORK/callgrind.out" "$build/cli/tessera" "$@" \
    >/dev/null 2>"$WORK/valgrind.err" || { cat "$WORK/valgrind.err" >&2; exit 1; }
  callgrind_annotate --inclusive=yes --threshold=100 "$WORK/callgrind.out" >"$WORK/annotated" 2>/dev/null
  TOTAL=$(awk '/^totals:/ { print $2 }' "$WORK/callgrind.out")
  LOAD=$(inclusive "tessera::load_scene_file(")
  ZIP=$(($(inclusive "OutputFile::writePixels(") + $(inclusive "ZipChunkCompressor::compress(")))
}
# report BUILD: the fit of one build, one line per figure
report() {
  local build=$1 floor i1 i8 load zip
  count "$build" --version
  floor=$TOTAL
  count "$build" render "$WORK/cbox128.json" -o "$WORK/out.exr" --spp 1 -q
  i1=$TOTAL load=$LOAD zip=$ZIP
  count "$build" render "$WORK/cbox128.json" -o "$WORK/out.exr" --spp 8 -q
  i8=$TOTAL
  echo "== $build: $("$build/cli/tessera" --version)"
  awk -v v="$floor" -v i1="$i1" -v i8="$i8" -v load="$load" -v zip="$zip" 'BEGIN {
      b = (i8 - i1) / 7; a = i1 - b; fixed = a - v - load
      m = 1e6
      printf "  %-62s %9.2f M\n", "floor: tessera --version", v / m
      printf "  %-62s %9.2f M\n", "render --spp 1", i1 / m
      printf "  %-62s %9.2f M\n", "render --spp 8", i8 / m
      printf "  %-62s %9.2f M\n", "fit a + b*spp: b (per spp)", b / m
      printf "  %-62s %9.2f M\n", "scene load (load_scene_file, with the scene hash)", load / m
      printf "  %-62s %9.2f M\n", "FIXED PART = a - floor - scene load", fixed / m
      printf "  %-62s %9.2f M\n", "  of which the EXR ZIP compression (chunks deflated)", zip / m
      printf "  %-62s %9.2f M\n", "  of which the rest", (fixed - zip) / m
    }'
}

# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header fixed_cost_instructions "$ROOT" "$BUILD"
echo "command: bash bench/fixed_cost_instructions.sh $BUILD${OTHER:+ $OTHER}; instructions counted by $(valgrind --version)"
echo "scenes/cbox_no_light.json at 128x128; the counts do not depend on the machine's load"
echo
report "$BUILD"
if [ -n "$OTHER" ]; then
  echo
  report "$OTHER"
fi
