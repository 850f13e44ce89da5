#!/usr/bin/env bash
# The fixed cost of a render, beside a process that renders nothing, in one run:
#  (1) `tessera render` of scenes/cbox_no_light.json at 128x128 on every core: wall time at 1 and 8 spp fitted as
#      a + b*spp per round; the fixed part is a minus the floor (`tessera --version`: the same binary started, its
#      libraries linked, ended) minus the scene load `--timing` reports; with the --timing spans of the 1-spp render;
#  (2) a farm worker's overhead per 64x64 tile: `render --workers 1 --threads 1` of the same 512x512 image at 1 spp
#      cut into 64 tiles of 64x64 (--farm-tile 64) and into 4 of 256x256 (--farm-tile 256): the same pixels and
#      samples, so (F64 - F256) / 60 is what each further tile costs (lease, scene look-up, render set-up, encode,
#      upload, merge), beside the single process `render --threads 1` of the image.
# Every round runs all of them, one after the other; medians and minimums over N rounds.
#   bash bench/fixed_cost.sh BUILD_DIR [N]      (N = 15)
set -euo pipefail
BUILD=${1:?usage: fixed_cost.sh BUILD_DIR [N]}
N=${2:-15}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
T="$BUILD/cli/tessera"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-fixed-cost.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
cp -r "$ROOT/scenes/assets" "$WORK/"  # the scenes' asset paths are relative to them
for size in 128 512; do
  python3 - "$ROOT/scenes/cbox_no_light.json" "$WORK/cbox$size.json" "$size" <<'PY'
import json, sys
src, dst, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
s = json.load(open(src))
s["film"]["resolution"] = [n, n]
json.dump(s, open(dst, "w"))
PY
done
now() { date +%s.%N; }
# run NAME CMD...: appends CMD's wall time in ms to $WORK/NAME; its stderr is kept in $WORK/NAME.err
run() {
  local name=$1 t0 t1
  shift
  t0=$(now)
  "$@" >/dev/null 2>"$WORK/$name.err"
  t1=$(now)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f\n", 1000 * (b - a) }' >>"$WORK/$name"
}
# timing NAME FIELD: a figure of the last --timing line in $WORK/NAME.err, in ms, appended to $WORK/NAME.FIELD
timing() {
  sed -nE "s/.*$2 ([0-9.]+)s.*/\1/p" "$WORK/$1.err" | tail -n1 | awk '{ printf "%.3f\n", 1000 * $1 }' >>"$WORK/$1.$2"
}
render() { "$T" render "$WORK/$1" -o "$WORK/$2.exr" -q "${@:3}"; }

# shellcheck source-path=SCRIPTDIR source=run_header.sh
source "$(dirname "$0")/run_header.sh"
run_header fixed_cost "$ROOT" "$BUILD"
echo "command: bash bench/fixed_cost.sh $BUILD $N; $N rounds, each running every command below once in turn"
echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)"

for _ in $(seq "$N"); do
  run floor "$T" --version
  run r1 render cbox128.json r1 --spp 1 --timing
  for f in load film "threaded render" write; do timing r1 "$f"; done
  run r8 render cbox128.json r8 --spp 8 --timing
  timing r8 load
  run s512 render cbox512.json s512 --spp 1 --threads 1
  run f64 render cbox512.json f64 --spp 1 --threads 1 --workers 1 --farm-tile 64
  run f256 render cbox512.json f256 --spp 1 --threads 1 --workers 1 --farm-tile 256
done
for f in f64 f256; do
  "$BUILD/tests/exr_compare" "$WORK/s512.exr" "$WORK/$f.exr" >/dev/null || echo "warning: the farm's $f image differs from the single process's"
done

# Per round: the fit, the fixed part, the farm's per-tile overhead.
paste "$WORK/floor" "$WORK/r1" "$WORK/r8" "$WORK/r1.load" "$WORK/r8.load" "$WORK/f64" "$WORK/f256" | awk '{
    floor = $1; w1 = $2 - $4; w8 = $3 - $5       # wall time without the scene load
    b = (w8 - w1) / 7; a = w1 - b
    printf "%.3f %.3f %.3f %.3f\n", a, a - floor, b, ($6 - $7) / 60
  }' >"$WORK/derived"
stats() {  # stats FILE [COLUMN]: median and minimum
  awk -v c="${2:-1}" '{ print $c }' "$1" | sort -g | awk '{ v[NR] = $1 } END {
    m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
    printf "median %8.3f ms  min %8.3f ms", m, v[1] }'
}
echo
echo "== 1. tessera render, scenes/cbox_no_light.json at 128x128, all cores (wall time of the process)"
printf "  %-58s %s\n" "floor: tessera --version (start, link, exit; no work)" "$(stats "$WORK/floor")"
printf "  %-58s %s\n" "render --spp 1" "$(stats "$WORK/r1")"
printf "  %-58s %s\n" "render --spp 8" "$(stats "$WORK/r8")"
printf "  %-58s %s\n" "  of which the scene load (--timing 'load')" "$(stats "$WORK/r1.load")"
printf "  %-58s %s\n" "fit a + b*spp without the load: b (per spp)" "$(stats "$WORK/derived" 3)"
printf "  %-58s %s\n" "fit a + b*spp without the load: a" "$(stats "$WORK/derived" 1)"
printf "  %-58s %s\n" "FIXED PART = a - floor (scene load excluded)" "$(stats "$WORK/derived" 2)"
echo "  --timing spans of the 1-spp render:"
printf "  %-58s %s\n" "  film set-up" "$(stats "$WORK/r1.film")"
printf "  %-58s %s\n" "  threaded render (thread start, samples, EXR bands)" "$(stats "$WORK/r1.threaded render")"
printf "  %-58s %s\n" "  write (last EXR rows, header, file sync, rename)" "$(stats "$WORK/r1.write")"
echo
echo "== 2. a farm worker's overhead per 64x64 tile, 1 spp, 1 thread (wall time of the process)"
printf "  %-58s %s\n" "single process, 512x512" "$(stats "$WORK/s512")"
printf "  %-58s %s\n" "--workers 1, 512x512 in 64 tiles of 64x64 (F64)" "$(stats "$WORK/f64")"
printf "  %-58s %s\n" "--workers 1, 512x512 in 4 tiles of 256x256 (F256)" "$(stats "$WORK/f256")"
printf "  %-58s %s\n" "PER-TILE OVERHEAD = (F64 - F256) / 60" "$(stats "$WORK/derived" 4)"
echo
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
