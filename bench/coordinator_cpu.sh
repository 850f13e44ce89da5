#!/usr/bin/env bash
# Coordinator CPU per job and per tile: one `tessera serve` (--durability none, as `render --workers` runs it; process
# for the figures before 5766e51), one 2-thread worker, and farm_bench.sh's 2-s scene (640x480, 32 spp) submitted at
# tile sizes 64, 32 and 16 (80, 300 and 1200 tiles), twice; the coordinator's utime+stime read from /proc around
# each job. The slope over the tile counts is the per-tile cost, the rest the per-job cost (submission with its scene
# checks, result, the client's event stream).
# Usage: bench/coordinator_cpu.sh BUILD_DIR [COURSE_DIR]   (TILES="64 16" to choose the tile sizes, SPP=N the spp)
set -euo pipefail
BUILD=${1:?usage: coordinator_cpu.sh BUILD_DIR [COURSE_DIR]}
COURSE=${2:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" coordcpu
scene a 640 480 "${SPP:-32}"
echo "tessera coordinator CPU per job and per tile, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
TCK=$(getconf CLK_TCK)
start_serve --durability none
"$T" worker --coordinator "$URL" --cache "$WORK/cache" --name w --threads 2 >"$WORK/w.log" 2>&1 &
PIDS+=($!)
FIT=""
cpu() { awk -v t="$TCK" '{printf "%.4f", ($14 + $15) / t}' /proc/$SERVE_PID/stat; }
# shellcheck disable=SC2086  # TILES is a list of sizes
for tile in ${TILES:-64 32 16 64 32 16}; do
  c0=$(cpu); t0=$(date +%s.%N)
  "$T" submit "$WORK/a/scene.json" --coordinator "$URL" --tile "$tile" -o "$WORK/o.exr" -q
  c1=$(cpu); t1=$(date +%s.%N)
  tiles=$(( ((640 + tile - 1) / tile) * ((480 + tile - 1) / tile) ))
  FIT+="$tiles $(awk -v a="$c0" -v b="$c1" 'BEGIN {print b - a}')"$'\n'
  awk -v a="$c0" -v b="$c1" -v n="$tiles" -v tile="$tile" -v w0="$t0" -v w1="$t1" 'BEGIN {printf "tile %3d: %4d tiles, coordinator CPU %.3f s (%.2f ms/tile), wall %.3f s\n", tile, n, b - a, 1000 * (b - a) / n, w1 - w0}'
done
# Least squares over every job: CPU = per_job + tiles * per_tile.
printf "%s" "$FIT" | awk '{ n++; sx += $1; sy += $2; sxx += $1 * $1; sxy += $1 * $2 }
  END { b = (n * sxy - sx * sy) / (n * sxx - sx * sx); a = (sy - b * sx) / n
        printf "fit over %d jobs: %.0f ms per job + %.2f ms per tile of coordinator CPU\n", n, 1000 * a, 1000 * b }'
