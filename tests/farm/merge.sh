#!/usr/bin/env bash
# tessera merge: crops from `render --crop` reassemble bitwise; a missing tile and a conflicting overlap are errors
# naming the pixel rectangles; an identical overlap is accepted.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 30 20 2 2  # at 1 spp a pixel of the conflict below agrees under both seeds
R() { "$TESSERA" render "$WORK/s.json" -q "$@"; }
R -o "$WORK/full.exr"
R -o "$WORK/a.exr" --crop 0 0 16 20
R -o "$WORK/b.exr" --crop 16 0 30 10
R -o "$WORK/c.exr" --crop 16 10 30 20
R -o "$WORK/overlap.exr" --crop 10 5 20 15          # same seed: identical where it overlaps a, b and c
R -o "$WORK/other-seed.exr" --crop 12 8 18 12 --seed 7

"$TESSERA" merge "$WORK/a.exr" "$WORK/b.exr" "$WORK/c.exr" -o "$WORK/m.exr" >"$WORK/merge-ok.log" 2>&1 || fail "merge failed"
"$EXR_COMPARE" "$WORK/full.exr" "$WORK/m.exr" || fail "merged image differs from the full render"

"$TESSERA" merge "$WORK/c.exr" "$WORK/a.exr" "$WORK/overlap.exr" "$WORK/b.exr" -o "$WORK/m2.exr" >"$WORK/merge-ident.log" 2>&1 \
  || fail "identical overlap refused"
log_has "$WORK/merge-ident.log" "100 overlapping pixels, identical" || fail "overlap not reported"
"$EXR_COMPARE" "$WORK/full.exr" "$WORK/m2.exr" || fail "merge with identical overlap differs"

expect_exit 2 "$WORK/merge-gap.log" -- "$TESSERA" merge "$WORK/a.exr" "$WORK/c.exr" -o "$WORK/gap.exr"
log_has "$WORK/merge-gap.log" 'pixels covered by no tile: \[16,30\) x \[0,10\) \(140 pixels\)' || fail "gap message"
[ ! -e "$WORK/gap.exr" ] || fail "output written despite the error"

expect_exit 2 "$WORK/merge-conflict.log" -- "$TESSERA" merge "$WORK/a.exr" "$WORK/b.exr" "$WORK/c.exr" \
  "$WORK/other-seed.exr" -o "$WORK/conflict.exr"
log_has "$WORK/merge-conflict.log" "conflicting overlap of $WORK/a.exr and $WORK/other-seed.exr \(different values\): \[12,16\) x \[8,12\)" \
  || fail "conflict message (a)"
# Where b and other-seed overlap, some pixels (in shadow) are 0 under either seed: only the differing ones are listed.
log_has "$WORK/merge-conflict.log" "conflicting overlap of $WORK/b.exr and $WORK/other-seed.exr \(different values\): \[" \
  || fail "conflict message (b)"
[ ! -e "$WORK/conflict.exr" ] || fail "output written despite the conflict"
echo "PASS"
