#!/usr/bin/env bash
# Raising a resumable farm job's spp (docs/resume.md): (1) what `--resumable` costs an ordinary job (wall time, result
# size, database size), (2) a job at N spp raised to 4N against a job submitted at 4N from the start (wall time of the
# raise, which renders only the 3N new samples per pixel), with the results compared bitwise.
# Usage: bench/raise_spp_bench.sh BUILD_DIR [COURSE_DIR] [WIDTH HEIGHT N]   (wall-clock times: run it on a quiet machine)
set -euo pipefail
BUILD=${1:?usage: raise_spp_bench.sh BUILD_DIR [COURSE_DIR] [WIDTH HEIGHT N]}
COURSE=${2:-$(cd "$(dirname "$0")/.." && pwd)/scenes/course}
W=${3:-320} H=${4:-240} N=${5:-16}
M=$((4 * N))
# shellcheck source-path=SCRIPTDIR source=bench_common.sh
source "$(dirname "$0")/bench_common.sh" raise-spp
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

echo "tessera raise-spp benchmark, $(date -u +%FT%TZ), $(nproc) cores, commit $(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "textured Cornell box ${W}x${H}, farm tile 64, 2 workers x 1 thread; N = $N, 4N = $M"
scene a "$W" "$H" "$N"
S="$WORK/a/scene.json"
start_serve
for i in 1 2; do
  "$T" worker --coordinator "$URL" --threads 1 --cache "$WORK/cache" --name "b$i" >"$WORK/w$i.log" 2>&1 &
  PIDS+=($!)
done
db_bytes() { du -cb "$WORK/data"/tessera.db* | tail -n1 | cut -f1; }
submit() {  # OUT SPP [flags]: submits, waits, downloads; prints the wall time
  local out=$1 spp=$2 t0 t1
  shift 2
  t0=$(now)
  "$T" submit "$S" --coordinator "$URL" --spp "$spp" --tile 64 -o "$out" -q "$@" >/dev/null 2>&1
  t1=$(now)
  secs "$t0" "$t1"
}

echo
echo "== 1. the cost of --resumable at $M spp"
db0=$(db_bytes); t_plain=$(submit "$WORK/plain.exr" "$M"); db1=$(db_bytes)
t_res=$(submit "$WORK/fresh.exr" "$M" --resumable); db2=$(db_bytes)
printf "  %-12s %8ss  result %9d bytes  database +%9d bytes\n" "ordinary" "$t_plain" "$(stat -c %s "$WORK/plain.exr")" $((db1 - db0))
printf "  %-12s %8ss  result %9d bytes  database +%9d bytes\n" "--resumable" "$t_res" "$(stat -c %s "$WORK/fresh.exr")" $((db2 - db1))

echo
echo "== 2. $N spp raised to $M against $M from the start"
t_n=$(submit "$WORK/n.exr" "$N" --resumable)
JOB=$(grep -Eo "j-[^ ]+" <<<"$("$T" jobs ls --coordinator "$URL" | sed -n 2p)" | head -n1)
t0=$(now)
"$T" jobs spp "$JOB" "$M" --coordinator "$URL" >/dev/null
until "$T" jobs show "$JOB" --coordinator "$URL" | grep -q '"state": "done"'; do sleep 0.05; done
t1=$(now)
curl -sS -f -o "$WORK/raised.exr" "$URL/v1/jobs/$JOB/result.exr"
t_raise=$(secs "$t0" "$t1")
same=$("$BUILD/tests/exr_compare" "$WORK/fresh.exr" "$WORK/raised.exr" >/dev/null 2>&1 && echo "bitwise identical" || echo "DIFFERENT")
printf "  %-26s %8ss\n" "$N spp (resumable)" "$t_n" "raise $N -> $M" "$t_raise" "$M spp from the start" "$t_res"
printf "  raise / from the start: %s (the 3N new samples are 3/4 of the work); raised result vs fresh: %s\n" \
  "$(awk -v a="$t_raise" -v b="$t_res" 'BEGIN { printf "%.2f", a / b }')" "$same"
