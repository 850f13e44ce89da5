#!/usr/bin/env bash
# The cost of each output layer: `tessera render` of one scene with no layer, then with each layer alone, then all of
# them, best of N by the process's CPU time (user + system from /usr/bin/time, so that other processes on a shared
# machine do not count; loading and writing included), and the EXR's bytes (ZIP, one part; and all layers with
# --multipart). Usage:
#   bash bench/layers_bench.sh TESSERA [WIDTH HEIGHT SPP [N]]    (default 480 270 16 3; SCENE=name of scenes/)
set -euo pipefail
T=${1:?usage: layers_bench.sh TESSERA [WIDTH HEIGHT SPP [N]]}
W=${2:-480}
H=${3:-270}
SPP=${4:-16}
N=${5:-3}
SCENE=${SCENE:-cbox_area_light}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
python3 - "$ROOT/scenes/$SCENE.json" "$WORK/scene.json" "$W" "$H" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s.setdefault("film", {})["resolution"] = [int(sys.argv[3]), int(sys.argv[4])]
json.dump(s, open(sys.argv[2], "w"))
PY
cp -r "$ROOT/scenes/assets" "$WORK/" 2>/dev/null || true
best() {  # best ARGS... -> "seconds bytes" (CPU seconds, best of N; bytes of the last output)
  local b=1e9 s
  for _ in $(seq "$N"); do
    s=$( { /usr/bin/time -f "CPU %U %S" "$T" render "$WORK/scene.json" -o "$WORK/out.exr" --spp "$SPP" -q "$@"; } 2>&1 |
        awk '/^CPU / { print $2 + $3 }')
    b=$(awk -v x="$b" -v y="$s" 'BEGIN { print (y < x) ? y : x }')
  done
  echo "$b $(stat -c %s "$WORK/out.exr")"
}
echo "layers bench, $(date -u +%Y-%m-%dT%H:%M:%SZ), commit $(git -C "$ROOT" rev-parse --short HEAD)"
echo "machine: $(lscpu | sed -nE 's/^Model name: +//p'), nproc $(nproc), load average $(cut -d' ' -f1-3 /proc/loadavg)"
echo "scene: scenes/$SCENE.json at ${W}x${H}, $SPP spp, all threads; best of $N by CPU seconds (user + system)"
read -r base_s base_b <<<"$(best)"
printf "  %-16s %8.3fs  %10d bytes\n" "(none)" "$base_s" "$base_b"
for layer in albedo normal depth position material_id object_id variance crypto_material crypto_object; do
  read -r s b <<<"$(best --layers "$layer")"
  awk -v l="$layer" -v s="$s" -v b="$b" -v s0="$base_s" -v b0="$base_b" 'BEGIN {
    printf "  %-16s %8.3fs  %10d bytes   +%5.1f%% time  +%9d bytes\n", l, s, b, 100 * (s - s0) / s0, b - b0 }'
done
ALL=albedo,normal,depth,position,material_id,object_id,variance,crypto_material,crypto_object
read -r s b <<<"$(best --layers "$ALL")"
awk -v s="$s" -v b="$b" -v s0="$base_s" -v b0="$base_b" 'BEGIN {
  printf "  %-16s %8.3fs  %10d bytes   +%5.1f%% time  +%9d bytes\n", "all", s, b, 100 * (s - s0) / s0, b - b0 }'
read -r s b <<<"$(best --layers "$ALL" --multipart)"
awk -v s="$s" -v b="$b" -v s0="$base_s" -v b0="$base_b" 'BEGIN {
  printf "  %-16s %8.3fs  %10d bytes   +%5.1f%% time  +%9d bytes\n", "all, multipart", s, b, 100 * (s - s0) / s0, b - b0 }'
