#!/usr/bin/env bash
# Steps after the merge (`submit --then`): a one-image job with preview and half, a sequence with preview and
# contact_sheet, a sequence of odd-sized frames with movie at 12 fps. Once done, each job's status lists its outputs;
# the PNGs decode to the image's size (the contact sheet to its grid), the half EXR is the float result rounded to
# half, value for value, and ffprobe counts the MP4's frames (H.264, yuv420p, padded to even) after `tessera jobs
# outputs -o` saved it. Refused at submission with a sentence: a contact sheet or a movie of one image, a movie of
# frames of two sizes, --fps without a movie, and (a coordinator whose PATH has no ffmpeg) any movie. A coordinator
# whose --ffmpeg fails leaves the job done and its movie step failed with the end of ffmpeg's log. Nothing runs a
# shell command. A coordinator stopped while its ffmpeg hangs kills it, and makes the movie after its restart; an
# ffmpeg stalled for --movie-stall-seconds is killed and fails the step.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 24 16 1
for n in 1 2; do write_sphere_scene "$WORK/f_$n.json" 16 16 1; done
for n in 1 2 3; do write_sphere_scene "$WORK/m_$n.json" 15 9 1; done  # odd: the movie pads them to 16x10
write_sphere_scene "$WORK/mixed_1.json" 16 16 1
write_sphere_scene "$WORK/mixed_2.json" 24 16 1
start_serve
ADDRESS=$(head -n1 "$WORK/ready")
start_worker w --threads 1
A=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --then preview,half --detach 2>>"$WORK/submit.log") \
  || fail "submit A"
S=$("$TESSERA" submit "$WORK/f_#.json" --frames 1-2 --coordinator "$URL" --tile 8 --then preview,contact_sheet \
      --detach 2>>"$WORK/submit.log") || fail "submit the sequence"
M=$("$TESSERA" submit "$WORK/m_#.json" --frames 1-3 --coordinator "$URL" --tile 8 --then movie --fps 12 \
      --detach 2>>"$WORK/submit.log") || fail "submit the movie"
expect_exit 2 "$WORK/movie.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --then movie --detach
log_has "$WORK/movie.log" "movie needs a sequence" || fail "a movie of one image was not refused with a sentence"
expect_exit 2 "$WORK/mixed.log" -- "$TESSERA" submit "$WORK/mixed_#.json" --frames 1-2 --coordinator "$URL" \
  --then movie --detach
log_has "$WORK/mixed.log" "movie needs frames of one size: frame 2 is 24x16, frame 1 16x16" \
  || fail "a movie of frames of two sizes was not refused with a sentence"
expect_exit 2 "$WORK/fps.log" -- "$TESSERA" submit "$WORK/f_#.json" --frames 1-2 --coordinator "$URL" \
  --then preview --fps 12 --detach
log_has "$WORK/fps.log" "goes with --then movie" || fail "--fps without a movie was not refused"
expect_exit 2 "$WORK/sheet.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --then contact_sheet --detach
log_has "$WORK/sheet.log" "contact_sheet needs a sequence" || fail "a contact sheet of one image was not refused"

outputs_done() {
  curl -sS -f "$URL/v1/jobs/$1" | python3 -c "
import json, sys
o = json.load(sys.stdin).get('outputs', [])
sys.exit(not (o and all(x['state'] == 'done' for x in o)))"
}
wait_for outputs_done "$A" || fail "A's steps did not finish: $(curl -sS "$URL/v1/jobs/$A")"
wait_for outputs_done "$S" || fail "the sequence's steps did not finish: $(curl -sS "$URL/v1/jobs/$S")"
wait_for outputs_done "$M" || fail "the movie did not finish: $(curl -sS "$URL/v1/jobs/$M")"
curl -sS -f "$URL/v1/jobs/$A" >"$WORK/a.json"
curl -sS -f "$URL/v1/jobs/$S" >"$WORK/s-job.json"
python3 - "$WORK/a.json" "$WORK/s-job.json" <<'PY' || fail "the outputs listed are not the files expected: $(cat "$WORK/a.json" "$WORK/s-job.json")"
import json, sys
a, s = (json.load(open(f))["outputs"] for f in sys.argv[1:3])
assert [(o["step"], o["files"]) for o in a] == [("preview", ["preview.png"]), ("half", ["half.exr"])], a
assert [(o["step"], o["files"]) for o in s] == [("preview", ["preview.f1.png", "preview.f2.png"]),
                                               ("contact_sheet", ["contact_sheet.png"])], s
PY
# The movie: listed, saved by the CLI, served by the outputs route, and three 16x10 H.264 frames at 12 fps.
"$TESSERA" jobs outputs "$M" --coordinator "$URL" -o "$WORK/out" >"$WORK/outputs.log" 2>&1 \
  || fail "jobs outputs -o did not save the movie"
log_has "$WORK/outputs.log" "^movie +done +movie.mp4" || fail "jobs outputs does not list the movie"
curl -sS -f -o "$WORK/route.mp4" "$URL/v1/jobs/$M/outputs/movie.mp4" || fail "GET outputs/movie.mp4 failed"
cmp "$WORK/out/movie.mp4" "$WORK/route.mp4" || fail "the CLI saved another file than the route serves"
ffprobe -v error -count_frames -select_streams v:0 \
  -show_entries stream=codec_name,pix_fmt,width,height,nb_read_frames,r_frame_rate -of json "$WORK/out/movie.mp4" \
  >"$WORK/probe.json" 2>"$WORK/probe.log" || fail "ffprobe cannot read the movie"
python3 - "$WORK/probe.json" <<'PY' || fail "the movie is not 3 H.264 yuv420p frames of 16x10 at 12 fps: $(cat "$WORK/probe.json")"
import json, sys
v = json.load(open(sys.argv[1]))["streams"][0]
assert (v["codec_name"], v["pix_fmt"], v["width"], v["height"]) == ("h264", "yuv420p", 16, 10), v
assert v["nb_read_frames"] == "3" and v["r_frame_rate"] == "12/1", v
PY
get() { curl -sS -f -o "$WORK/$2" "$URL/v1/jobs/$1/outputs/$2" || fail "GET outputs/$2 of $1 failed"; }
get "$A" preview.png
get "$A" half.exr
get "$S" preview.f2.png
get "$S" contact_sheet.png
curl -sS -o /dev/null -w '%{http_code}' "$URL/v1/jobs/$A/outputs/..%2Fresult.exr" >"$WORK/escape-code.txt"
[ "$(cat "$WORK/escape-code.txt")" = 404 ] || fail "an output name leaving the steps' folder was not refused"
curl -sS -f -o "$WORK/result.exr" "$URL/v1/jobs/$A/result.exr" || fail "no result"
"$EXR_COMPARE" --half "$WORK/result.exr" "$WORK/half.exr" || fail "the half EXR is not the result rounded to half"
# Each PNG decodes (zlib over its IDAT chunks) to width x height rows of the size its header says.
python3 - "$WORK" <<'PY' || fail "a PNG does not decode to the image's size"
import struct, sys, zlib
def size(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            channels = {2: 3, 6: 4, 0: 1}[colour]
        if kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    assert len(raw) == h * (1 + w * channels * depth // 8), (path, len(raw), w, h)
    return w, h
d = sys.argv[1]
assert size(f"{d}/preview.png") == (24, 16)
assert size(f"{d}/preview.f2.png") == (16, 16)
assert size(f"{d}/contact_sheet.png") == (2 * 256 + 3 * 2, 256 + 2 * 2)  # two 256-wide cells, 2-pixel gaps
PY

# An ffmpeg that fails: the render stays done, the movie step is failed with the end of its log (the preview is made).
restart_serve() {
  kill -TERM "$SERVE_PID"
  wait "$SERVE_PID" 2>/dev/null || true
  LISTEN=$ADDRESS start_serve "$@"
}
printf '#!/bin/sh\necho "x264 [error]: the encoder broke on purpose" >&2\nexit 3\n' >"$WORK/broken-ffmpeg"
chmod +x "$WORK/broken-ffmpeg"
restart_serve --ffmpeg "$WORK/broken-ffmpeg"
B=$("$TESSERA" submit "$WORK/m_#.json" --frames 1-2 --coordinator "$URL" --tile 8 --then movie,preview \
      --detach 2>>"$WORK/submit.log") || fail "submit the movie to the broken ffmpeg"
steps_settled() {
  curl -sS -f "$URL/v1/jobs/$1" | python3 -c "
import json, sys
o = json.load(sys.stdin).get('outputs', [])
sys.exit(not (o and all(x['state'] != 'pending' for x in o)))"
}
wait_for steps_settled "$B" || fail "the broken movie's steps did not settle: $(curl -sS "$URL/v1/jobs/$B")"
curl -sS -f "$URL/v1/jobs/$B" >"$WORK/b.json"
python3 - "$WORK/b.json" <<'PY' || fail "a failed ffmpeg did not fail the movie step alone, with its log: $(cat "$WORK/b.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["state"] == "done", j["state"]
movie, preview = j["outputs"]
assert movie["step"] == "movie" and movie["state"] == "failed" and movie["files"] == [], movie
assert "exited with status 3" in movie["log"] and "the encoder broke on purpose" in movie["log"], movie["log"]
assert preview["state"] == "done" and preview["files"] == ["preview.f1.png", "preview.f2.png"], preview
PY
expect_exit 1 "$WORK/b-outputs.log" -- "$TESSERA" jobs outputs "$B" --coordinator "$URL"
log_has "$WORK/b-outputs.log" "the encoder broke on purpose" || fail "jobs outputs does not show the failed step's log"
curl -sS -o /dev/null -w '%{http_code}' "$URL/v1/jobs/$B/outputs/movie.mp4" >"$WORK/b-code.txt"
[ "$(cat "$WORK/b-code.txt")" = 404 ] || fail "a failed movie is served ($(cat "$WORK/b-code.txt"))"

# A coordinator stopped while its ffmpeg runs (one that never ends) kills it without failing the movie, which the
# restarted coordinator makes.
printf '#!/bin/sh\n: >"%s"\nexec /bin/sleep 600\n' "$WORK/encoding" >"$WORK/hung-ffmpeg"
chmod +x "$WORK/hung-ffmpeg"
restart_serve --ffmpeg "$WORK/hung-ffmpeg"
H=$("$TESSERA" submit "$WORK/m_#.json" --frames 1-2 --coordinator "$URL" --tile 8 --then movie \
      --detach 2>>"$WORK/submit.log") || fail "submit the movie to the hung ffmpeg"
wait_for test -e "$WORK/encoding" || fail "the hung ffmpeg did not start"
restart_serve
log_has "$WORK/serve.log" "job $H: step movie stopped while ffmpeg finished the movie" \
  || fail "the stop did not interrupt the hung ffmpeg"
wait_for outputs_done "$H" || fail "the interrupted movie was not made after the restart: $(curl -sS "$URL/v1/jobs/$H")"

# An ffmpeg that makes no progress for --movie-stall-seconds is killed: the movie step fails with that sentence, the
# render stays done.
restart_serve --ffmpeg "$WORK/hung-ffmpeg" --movie-stall-seconds 1
rm -f "$WORK/encoding"
K=$("$TESSERA" submit "$WORK/m_#.json" --frames 1-2 --coordinator "$URL" --tile 8 --then movie \
      --detach 2>>"$WORK/submit.log") || fail "submit the movie to the stalling ffmpeg"
wait_for steps_settled "$K" || fail "the stalled movie's step did not settle: $(curl -sS "$URL/v1/jobs/$K")"
curl -sS -f "$URL/v1/jobs/$K" >"$WORK/k.json"
python3 - "$WORK/k.json" <<'PY' || fail "a stalled ffmpeg did not fail the movie step with a sentence: $(cat "$WORK/k.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["state"] == "done", j["state"]
(movie,) = j["outputs"]
assert movie["state"] == "failed" and "did not finish the movie for 1 s and was killed" in movie["log"], movie
PY
restart_serve

# A coordinator whose PATH holds no ffmpeg refuses a movie at submission (the other steps still go).
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
mkdir -p "$WORK/no-tools"
rm -f "$WORK/ready"
(PATH="$WORK/no-tools" exec "$TESSERA" serve --listen "$ADDRESS" --ready-file "$WORK/ready" --data "$WORK/data") \
  >>"$WORK/serve.log" 2>&1 &
SERVE_PID=$!
PIDS+=("$SERVE_PID")
wait_for test -s "$WORK/ready" || fail "the coordinator without ffmpeg did not become ready"
expect_exit 2 "$WORK/no-ffmpeg.log" -- "$TESSERA" submit "$WORK/m_#.json" --frames 1-2 --coordinator "$URL" \
  --then movie --detach
log_has "$WORK/no-ffmpeg.log" "cannot make the movie step: 'ffmpeg' is not found on the coordinator's PATH" \
  || fail "a movie was not refused at submission without ffmpeg"
"$TESSERA" submit "$WORK/m_#.json" --frames 1-2 --coordinator "$URL" --then preview --detach \
  >"$WORK/no-ffmpeg-preview.log" 2>&1 || fail "a preview was refused without ffmpeg"
echo "PASS"
