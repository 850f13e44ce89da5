#!/usr/bin/env bash
# render --workers N for several farm tile sizes (dividing the image or not, 1-pixel tiles) and worker counts gives
# R,G,B bitwise identical to the single-process render; also with a scene that has OBJ and EXR assets, and with
# path-traced scenes.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/spheres.json" 37 23 3
"$TESSERA" render "$WORK/spheres.json" -o "$WORK/ref.exr" -q
for case in "1 64" "2 7" "2 16" "3 10"; do
  set -- $case
  "$TESSERA" render "$WORK/spheres.json" -o "$WORK/farm-$1-$2.exr" --workers "$1" --farm-tile "$2" -q \
    >"$WORK/render-$1-$2.log" 2>&1 || fail "render --workers $1 --farm-tile $2 failed"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/farm-$1-$2.exr" || fail "workers $1 tile $2 differs from the single-process render"
done

# Adaptive sampling (a job option): each pixel's sample count depends on its own samples only, so odd farm tiles
# still give the single-process bits, samples channel aside.
"$TESSERA" render "$WORK/spheres.json" -o "$WORK/adaptive-ref.exr" --target-error 0.05 --min-spp "$(spp 2)" \
  --max-spp "$(spp 64)" -q
"$TESSERA" render "$WORK/spheres.json" -o "$WORK/adaptive-farm.exr" --target-error 0.05 --min-spp "$(spp 2)" \
  --max-spp "$(spp 64)" --workers 2 --farm-tile 7 -q >"$WORK/render-adaptive.log" 2>&1 || fail "render --workers --target-error failed"
"$EXR_COMPARE" "$WORK/adaptive-ref.exr" "$WORK/adaptive-farm.exr" || fail "adaptive farm render differs"
expect_exit 1 "$WORK/compare-adaptive.log" -- "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/adaptive-ref.exr"  # 1: they differ

# 1-pixel tiles on a tiny image: 20 tiles.
write_sphere_scene "$WORK/tiny.json" 5 4 2
"$TESSERA" render "$WORK/tiny.json" -o "$WORK/tiny-ref.exr" -q
"$TESSERA" render "$WORK/tiny.json" -o "$WORK/tiny-farm.exr" --workers 2 --farm-tile 1 -q >"$WORK/render-tiny.log" 2>&1 \
  || fail "1-pixel tiles failed"
"$EXR_COMPARE" "$WORK/tiny-ref.exr" "$WORK/tiny-farm.exr" || fail "1-pixel tiles differ"

# The private coordinator's folder (under TMPDIR) on another file system than the output: the result is copied out
# of it instead of moved (a rename across file systems fails with EXDEV), and an older output is replaced.
if [ -d /dev/shm ] && [ -w /dev/shm ] && [ "$(stat -f -c %T /dev/shm)" != "$(stat -f -c %T "$WORK")" ]; then
  echo "old" >"$WORK/tiny-copied.exr"
  TMPDIR=/dev/shm "$TESSERA" render "$WORK/tiny.json" -o "$WORK/tiny-copied.exr" --workers 1 -q \
    >"$WORK/render-copied.log" 2>&1 || fail "render --workers with its folder on another file system failed"
  "$EXR_COMPARE" "$WORK/tiny-ref.exr" "$WORK/tiny-copied.exr" || fail "the result copied across file systems differs"
else
  echo "note: /dev/shm is missing or on the file system of $WORK; the cross-file-system copy of the result is not tested"
fi

# Assets (meshes and an EXR texture) travel by hash; another seed and spp override go through the protocol.
write_cbox_scene "$WORK/cbox" 30 22 4
"$TESSERA" render "$WORK/cbox/scene.json" -o "$WORK/cbox-ref.exr" --spp "$(spp 2)" --seed 9 -q
"$TESSERA" render "$WORK/cbox/scene.json" -o "$WORK/cbox-farm.exr" --spp "$(spp 2)" --seed 9 --workers 2 --farm-tile 8 -q \
  >"$WORK/render-cbox.log" 2>&1 || fail "cbox render --workers failed"
"$EXR_COMPARE" "$WORK/cbox-ref.exr" "$WORK/cbox-farm.exr" || fail "cbox differs"
# The course's bdpt box, rendered with the direct integrator on request (the job's "integrator" key).
write_cbox_scene "$WORK/bdpt" 20 20 2 cbox.json
"$TESSERA" render "$WORK/bdpt/scene.json" -o "$WORK/bdpt-ref.exr" --integrator direct -q
"$TESSERA" render "$WORK/bdpt/scene.json" -o "$WORK/bdpt-farm.exr" --integrator direct --workers 1 --farm-tile 9 -q \
  >"$WORK/render-bdpt.log" 2>&1 || fail "bdpt box with --integrator direct failed"
"$EXR_COMPARE" "$WORK/bdpt-ref.exr" "$WORK/bdpt-farm.exr" || fail "bdpt box differs"
# Path-traced scenes (global illumination, glass, an EXR environment): the course's bdpt box and glass sphere.
for course in cbox.json glass_sphere.json; do
  write_cbox_scene "$WORK/path-$course" 24 20 4 "$course"
  "$TESSERA" render "$WORK/path-$course/scene.json" -o "$WORK/path-$course-ref.exr" --seed 3 -q
  "$TESSERA" render "$WORK/path-$course/scene.json" -o "$WORK/path-$course-farm.exr" --seed 3 --workers 2 --farm-tile 7 -q \
    >"$WORK/render-path-$course.log" 2>&1 || fail "path-traced $course through the farm failed"
  "$EXR_COMPARE" "$WORK/path-$course-ref.exr" "$WORK/path-$course-farm.exr" || fail "path-traced $course differs"
done
# ... and adaptive sampling on a path-traced scene.
G="$WORK/path-glass_sphere.json"
"$TESSERA" render "$G/scene.json" -o "$G/adaptive-ref.exr" --target-error 0.1 --min-spp 2 --max-spp 16 -q
"$TESSERA" render "$G/scene.json" -o "$G/adaptive-farm.exr" --target-error 0.1 --min-spp 2 --max-spp 16 \
  --workers 2 --farm-tile 5 -q >"$WORK/render-path-adaptive.log" 2>&1 || fail "adaptive path-traced farm render failed"
"$EXR_COMPARE" "$G/adaptive-ref.exr" "$G/adaptive-farm.exr" || fail "adaptive path-traced farm render differs"
echo "PASS"
