# Shared setup of the shell benchmarks (sourced after BUILD and SHARED are set): T (the tessera binary), a temporary
# WORK folder, PIDS (every background process, stopped with SIGTERM on exit, then WORK is removed), and scene().
# Argument: NAME, the benchmark's name in WORK's folder name (tessera-NAME-bench.XXXXXX).
# shellcheck shell=bash
# shellcheck disable=SC2034  # T is used by the sourcing script
T="$BUILD/cli/tessera"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-$1-bench.XXXXXX")
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

# scene NAME WIDTH HEIGHT SPP: the course's textured Cornell box at a chosen size and spp, as $WORK/NAME/scene.json
# (with its assets).
scene() {
  mkdir -p "$WORK/$1"
  cp -r "$SHARED/compat/rdr171/assets" "$WORK/$1/"
  python3 - "$SHARED/compat/rdr171/cbox_refract_textured.json" "$WORK/$1/scene.json" "$2" "$3" "$4" <<'PY'
import json, sys
src, dst, w, h, spp = sys.argv[1:]
s = json.load(open(src)); s["film"]["resolution"] = [int(w), int(h)]; s["integrator"]["spp"] = int(spp)
json.dump(s, open(dst, "w"))
PY
}
