#!/usr/bin/env bash
# The coordinator's data folder on a small file system of its own (a tmpfs in a private mount namespace).
#   full:  a worker holds a rendered tile when a filler file fills the disk. Reads (job list, job, tiles, /healthz)
#          still answer 200, /healthz says the disk is full; a submission, a blob upload and the held tile's upload
#          answer 507 with a sentence (the worker keeps the tile and retries). Once the filler is removed the job
#          completes by itself, with the same coordinator process, bitwise identical to a single-process render.
#   floor: with less free than --min-free-disk (but room left), a submission and a blob upload answer 507 naming the
#          flag, /healthz says "low", and the job admitted before renders to the end.
# Needs a mount namespace (root, or an unprivileged user namespace): where the kernel refuses one, the test is
# skipped (exit 77) saying why.
if [ -z "${TESSERA_DISK_FULL_NS:-}" ]; then
  if ! why=$(unshare -rm true 2>&1); then
    echo "SKIP: cannot make a private mount namespace here (unshare -rm): $why" >&2
    exit 77
  fi
  TESSERA_DISK_FULL_NS=1 exec unshare -rm bash "$0" "$@"
fi
source "$(dirname "$0")/common.sh"
CASE=${5:?usage: disk_full.sh TESSERA EXR_COMPARE COURSE_DIR TESSERA_FP full|floor}

mkdir -p "$WORK/data"
mount -t tmpfs -o size=8m tmpfs "$WORK/data" || fail "cannot mount a tmpfs in the private mount namespace"
disk_cleanup() {
  local rc=$?
  touch "$WORK/stop-filling"
  for p in "${PIDS[@]}"; do kill -CONT "$p" 2>/dev/null || true; done
  stop_pids 50 "${PIDS[@]}"
  umount "$WORK/data" 2>/dev/null || true
  cleanup
  exit "$rc"
}
trap disk_cleanup EXIT

# status METHOD PATH [curl args...]: the HTTP status of the request; its body goes to $WORK/body.
status() {
  local method=$1 path=$2
  shift 2
  curl -sS -o "$WORK/body" -w '%{http_code}' -X "$method" "$@" "$URL$path"
}
# expect STATUS TEXT METHOD PATH [curl args...]: the request answers STATUS with TEXT in its body.
expect() {
  local want=$1 text=$2 got
  shift 2
  got=$(status "$@")
  [ "$got" = "$want" ] || fail "$1 $2 answered $got, not $want: $(cat "$WORK/body")"
  grep -qF -- "$text" "$WORK/body" || fail "$1 $2: the answer does not say '$text': $(cat "$WORK/body")"
}
health() { curl -sS "$URL/healthz" | python3 -c "import json,sys; print(json.load(sys.stdin)['$1'])"; }
job_state() { curl -sS "$URL/v1/jobs/$JOB" | python3 -c "import json,sys; print(json.load(sys.stdin)['state'])"; }
job_done() { [ "$(job_state)" = done ]; }
disk_is() { [ "$(health disk)" = "$1" ]; }
# A blob upload of 256 KiB of fresh random bytes (never stored before).
put_blob() {
  head -c 262144 /dev/urandom >"$WORK/blob"
  status PUT "/v1/blobs/$(sha256sum "$WORK/blob" | cut -c1-64)" --data-binary "@$WORK/blob"
}

write_sphere_scene "$WORK/scene.json" 48 32 4
"$TESSERA" render "$WORK/scene.json" -o "$WORK/ref.exr" -q
python3 -c "
import json, sys
print(json.dumps({'scene': json.load(open(sys.argv[1]))}))" "$WORK/scene.json" >"$WORK/job.json"

if [ "$CASE" = full ]; then
  start_serve --min-free-disk 0
  SERVE_STARTED=$SERVE_PID
  start_submit "$WORK/submit.log" "$WORK/scene.json" --tile 8 --detach
  wait "$SUBMIT_PID" || fail "the submission failed"
  JOB=$(tail -n1 "$WORK/submit.log")
  # The worker stores three tiles, then holds the fourth, rendered, before its upload.
  FAIL_POINTS="worker.upload=3*off->pause($WORK/go)" start_worker w1
  wait_for paused "$WORK/w1.log" worker.upload || fail "the worker did not hold its fourth tile"

  # A filler keeps the disk full: whatever the coordinator frees (its log, cut by a checkpoint) is taken again.
  (
    while [ ! -e "$WORK/stop-filling" ]; do
      dd if=/dev/zero bs=4096 oflag=append conv=notrunc of="$WORK/data/filler" >/dev/null 2>&1 || true
      sleep 0.05
    done
  ) &
  FILLER_PID=$!
  PIDS+=("$FILLER_PID")
  full_now() { [ "$(stat -f -c %a "$WORK/data")" = 0 ]; }
  wait_for full_now || fail "the filler did not fill the disk"
  # A blob upload finds no room: 507, and from then on the coordinator knows the disk is full.
  got=$(put_blob)
  [ "$got" = 507 ] || fail "a blob upload on a full disk answered $got, not 507: $(cat "$WORK/body")"
  grep -q "disk is full" "$WORK/body" || fail "the 507 does not say the disk is full: $(cat "$WORK/body")"
  full_and_degraded() { disk_is full && [ "$(health status)" = degraded ]; }
  wait_for full_and_degraded || fail "/healthz does not say the disk is full: $(curl -sS "$URL/healthz")"

  # Reads answer; new work is refused with a sentence.
  expect 200 '"jobs"' GET /v1/jobs
  expect 200 "\"id\":\"$JOB\"" GET "/v1/jobs/$JOB"
  expect 200 '"tiles"' GET "/v1/jobs/$JOB/tiles"
  expect 200 "tessera_jobs" GET /metrics
  expect 507 "disk is full" POST /v1/jobs -H 'Content-Type: application/json' --data-binary "@$WORK/job.json"
  got=$(put_blob)
  [ "$got" = 507 ] || fail "a blob upload answered $got, not 507"
  # The held tile's upload is refused too; the worker keeps the tile and tries again later.
  release go
  wait_for log_has "$WORK/w1.log" "upload attempt [0-9]+ answered 507: the coordinator's disk is full" ||
    fail "the worker's upload was not answered 507"
  kill -0 "$SERVE_PID" || fail "the coordinator died on the full disk"

  # Space returns: the coordinator resumes by itself.
  touch "$WORK/stop-filling"
  wait "$FILLER_PID"
  rm -f "$WORK/data/filler"
  wait_for job_done || fail "the job did not complete after space was freed (state $(job_state))"
  [ "$SERVE_PID" = "$SERVE_STARTED" ] && kill -0 "$SERVE_PID" || fail "the coordinator was restarted"
  log_has "$WORK/serve.log" "has room again" || fail "the coordinator did not log the end of the full disk"
  wait_for disk_is ok || fail "/healthz still says $(health disk)"
  expect 200 "" GET "/v1/jobs/$JOB/result.exr"
  cp "$WORK/body" "$WORK/farm.exr"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/farm.exr" || fail "the job's image differs from the single-process render"
  # The tile refused while the disk was full was stored in the end; every tile was merged once.
  log_has "$WORK/w1.log" "upload accepted" || fail "no upload was accepted"
  [ "$(grep -c ': merged' "$WORK/serve.log")" = 24 ] || fail "not every tile was merged exactly once"
elif [ "$CASE" = floor ]; then
  start_serve --min-free-disk 6000000
  start_submit "$WORK/submit.log" "$WORK/scene.json" --tile 8 --detach
  wait "$SUBMIT_PID" || fail "the submission failed"
  JOB=$(tail -n1 "$WORK/submit.log")
  # Under the floor, with room left: 4 MiB of the 8 taken.
  dd if=/dev/zero of="$WORK/data/filler" bs=1M count=4 2>/dev/null || fail "cannot write the filler"
  below_floor() { [ "$(( $(stat -f -c '%a * %S' "$WORK/data") ))" -lt 6000000 ]; }
  below_floor || fail "the filler did not take the free space below the floor"
  expect 507 "--min-free-disk" POST /v1/jobs -H 'Content-Type: application/json' --data-binary "@$WORK/job.json"
  got=$(put_blob)
  [ "$got" = 507 ] || fail "a blob upload below the floor answered $got, not 507"
  grep -q -- "--min-free-disk" "$WORK/body" || fail "the 507 does not name --min-free-disk: $(cat "$WORK/body")"
  [ "$(health disk)" = low ] || fail "/healthz does not say the disk is low"
  expect 200 '"jobs"' GET /v1/jobs
  # The job admitted before renders to the end: its tiles are not new work.
  start_worker w1
  wait_for job_done || fail "the admitted job did not complete below the floor (state $(job_state))"
  expect 200 "" GET "/v1/jobs/$JOB/result.exr"
  cp "$WORK/body" "$WORK/farm.exr"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/farm.exr" || fail "the job's image differs from the single-process render"
  rm -f "$WORK/data/filler"
  wait_for disk_is ok || fail "/healthz still says $(health disk) after the filler was removed"
  expect 201 '"id"' POST /v1/jobs -H 'Content-Type: application/json' --data-binary "@$WORK/job.json"
else
  fail "unknown case '$CASE' (full or floor)"
fi
echo "PASS"
