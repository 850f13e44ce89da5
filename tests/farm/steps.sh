#!/usr/bin/env bash
# Steps after the merge (`submit --then`): a one-image job with preview and half, a sequence with preview and
# contact_sheet. Once done, each job's status lists its outputs; the PNGs decode to the image's size (the contact
# sheet to its grid), and the half EXR is the float result rounded to half, value for value. A movie is refused at
# submission with a sentence, so is a contact sheet of one image; nothing runs a shell command.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 24 16 1
for n in 1 2; do write_sphere_scene "$WORK/f_$n.json" 16 16 1; done
start_serve
start_worker w --threads 1
A=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --then preview,half --detach 2>>"$WORK/submit.log") \
  || fail "submit A"
S=$("$TESSERA" submit "$WORK/f_#.json" --frames 1-2 --coordinator "$URL" --tile 8 --then preview,contact_sheet \
      --detach 2>>"$WORK/submit.log") || fail "submit the sequence"
expect_exit 2 "$WORK/movie.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --then movie --detach
log_has "$WORK/movie.log" "does not offer the movie step" || fail "a movie was not refused with a sentence"
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
curl -sS -f "$URL/v1/jobs/$A" >"$WORK/a.json"
curl -sS -f "$URL/v1/jobs/$S" >"$WORK/s-job.json"
python3 - "$WORK/a.json" "$WORK/s-job.json" <<'PY' || fail "the outputs listed are not the files expected: $(cat "$WORK/a.json" "$WORK/s-job.json")"
import json, sys
a, s = (json.load(open(f))["outputs"] for f in sys.argv[1:3])
assert [(o["step"], o["files"]) for o in a] == [("preview", ["preview.png"]), ("half", ["half.exr"])], a
assert [(o["step"], o["files"]) for o in s] == [("preview", ["preview.f1.png", "preview.f2.png"]),
                                               ("contact_sheet", ["contact_sheet.png"])], s
PY
get() { curl -sS -f -o "$WORK/$2" "$URL/v1/jobs/$1/outputs/$2" || fail "GET outputs/$2 of $1 failed"; }
get "$A" preview.png
get "$A" half.exr
get "$S" preview.f2.png
get "$S" contact_sheet.png
curl -sS -o /dev/null -w '%{http_code}' "$URL/v1/jobs/$A/outputs/..%2Fresult.exr" | grep -q 404 \
  || fail "an output name leaving the steps' folder was not refused"
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
echo "PASS"
