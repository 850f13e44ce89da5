#!/usr/bin/env bash
# Previews never hold a whole frame: with no worker, two 8192 x 8192 jobs wait queued, and eight GETs of their
# preview.png (1024 x 1024 each, the later ones from the cache) raise the coordinator's peak memory (VmHWM) by less
# than 64 MB, where drawing each from a full frame would take 768 MB per job; /healthz answers meanwhile.
source "$(dirname "$0")/common.sh"

start_serve
write_sphere_scene "$WORK/scene.json" 8192 8192 1
JOBS=()
for i in 1 2; do
  JOBS+=("$("$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --detach -q)") || fail "submission $i failed"
done
rss_kb() { awk -v k="$1:" '$1 == k {print $2}' "/proc/$SERVE_PID/status"; }
echo 5 >"/proc/$SERVE_PID/clear_refs" || fail "cannot reset the coordinator's peak memory"
BEFORE=$(rss_kb VmRSS)
for round in 1 2 3 4; do
  for job in "${JOBS[@]}"; do
    curl -sf -o "$WORK/preview.png" "$URL/v1/jobs/$job/preview.png" || fail "the preview of $job failed"
    size=$(od -An -tu1 -j16 -N8 "$WORK/preview.png" | awk '{print $3 * 256 + $4, $7 * 256 + $8}')
    [ "$size" = "1024 1024" ] || fail "the preview of $job is $size, not 1024 x 1024"
  done
done
curl -sf -o /dev/null "$URL/healthz" || fail "/healthz does not answer"
PEAK=$(rss_kb VmHWM)
echo "coordinator memory: $((BEFORE / 1024)) MB before eight previews of two queued 8192 x 8192 jobs, peak $((PEAK / 1024)) MB"
[ $(((PEAK - BEFORE) / 1024)) -lt 64 ] || fail "the previews raised the coordinator's peak memory by $(((PEAK - BEFORE) / 1024)) MB"
echo PASS
