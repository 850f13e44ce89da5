#!/usr/bin/env bash
# Scene load time with a large environment map: the project's sky_sun scene with its sky re-made at 2048x1024 and
# 4096x2048 (scenes/tools/make_sky, float EXR), loaded by `render --spp 1 --timing` on 1 thread and on every core.
# Loading decodes the map (OpenEXR's thread pool) and builds its sampling tables (row by row on TBB's threads), all of
# it before the first sample: serial time a render pays once per process, and a farm worker once per job.
# Prints the best of N loads (N = $RUNS, default 5) per map and thread count, and the speed-up on every core. With a
# second binary (OTHER, e.g. an older build's cli/tessera) both run alternately and their ratio is printed.
# Usage: bench/scene_load.sh BUILD_DIR [OTHER_TESSERA]
set -euo pipefail
BUILD=${1:?usage: scene_load.sh BUILD_DIR [OTHER_TESSERA]}
OTHER=${2:-}
COURSE=unused
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" load-time
SCENES=$(cd "$(dirname "$0")/../scenes" && pwd)
RUNS=${RUNS:-5}

echo "scene load, $(date -u +%FT%TZ), commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), nproc $(nproc), load average $(cut -d' ' -f1-3 /proc/loadavg)"
echo "scene: scenes/sky_sun.json with its sky re-made at each width; best of $RUNS loads (render --spp 1 --timing)"
[ -n "$OTHER" ] && echo "other binary: $OTHER (runs alternate with this build's)"
# load_seconds BINARY THREADS: the load time `render --timing` reports.
load_seconds() {
  "$1" render "$WORK/sky_sun.json" -o "$WORK/out.exr" -q --spp 1 --threads "$2" --timing 2>&1 |
    sed -nE 's/^timing: load ([0-9.]+)s.*/\1/p'
}
best() { sort -g | head -n1; }
cp -r "$SCENES/assets" "$WORK/"
cp "$SCENES/sky_sun.json" "$WORK/"
for width in 2048 4096; do
  "$BUILD/scenes/tools/make_sky" -o "$WORK/assets/sky.exr" --width "$width" >/dev/null
  for threads in 1 "$(nproc)"; do
    ours="" theirs=""
    for _ in $(seq "$RUNS"); do
      ours+="$(load_seconds "$T" "$threads")"$'\n'
      [ -n "$OTHER" ] && theirs+="$(load_seconds "$OTHER" "$threads")"$'\n'
    done
    o=$(printf "%s" "$ours" | best)
    [ "$threads" = 1 ] && one=$o
    line=$(printf "  %4dx%-4d on %d thread(s): load %6.3f s" "$width" $((width / 2)) "$threads" "$o")
    [ "$threads" != 1 ] && line+=$(awk -v a="$one" -v b="$o" 'BEGIN { printf "  (%.2fx the 1-thread load)", a / b }')
    if [ -n "$OTHER" ]; then
      t=$(printf "%s" "$theirs" | best)
      line+=$(awk -v a="$o" -v b="$t" 'BEGIN { printf "; other binary %6.3f s, this one %.2fx faster", b, b / a }')
    fi
    echo "$line"
  done
done
