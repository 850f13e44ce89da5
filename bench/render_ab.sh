#!/usr/bin/env bash
# Two tessera binaries side by side: 1-thread renders of the same scenes, A and B alternating, best of N, rays per
# CPU-second of the whole process (user + system time from /usr/bin/time, so other processes on a shared machine do
# not count; loading and writing the EXR are included and cost both the same), best and median of N. A scene named
# NAME@path is scenes/NAME.json with its integrator replaced by the path tracer (MIS, max_depth 16, rr_threshold
# 0.1), as bench/vs_cycles names it. For commit messages of optimisations:
#   bash bench/render_ab.sh OLD/tessera NEW/tessera [N]          (N = 3; SCENES="a b" and SPP=n override the set)
set -euo pipefail
A=${1:?usage: render_ab.sh TESSERA_A TESSERA_B [N]}
B=${2:?usage: render_ab.sh TESSERA_A TESSERA_B [N]}
N=${3:-3}
SCENES_DIR=$(cd "$(dirname "$0")/../scenes" && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
[ -x /usr/bin/time ] || { echo "render_ab: needs /usr/bin/time (Debian package time)" >&2; exit 2; }
# Samples per pixel by scene: enough for about a second of rendering.
declare -A SPP_OF=([cbox_no_light]=16 [cbox_no_light_refraction]=16 [cbox_area_light]=64 [cbox_large_light]=64
                   [cbox_env_light]=16 [sky_sun]=16 [cbox_gi]=16 [cbox_glass]=16 [veach_mis]=16
                   [cbox_env_light@path]=4)
scene_file() {  # scene_file SCENE -> the scene file to render (NAME@path written to $WORK, its assets absolute)
  case "$1" in
    *@path)
      python3 - "$SCENES_DIR" "${1%@path}" "$WORK/$1.json" <<'PY'
import json, os, sys
folder, name, out = sys.argv[1:]
with open(os.path.join(folder, name + ".json")) as f:
    desc = json.load(f)
desc.setdefault("integrator", {}).update({"type": "path", "profile": "MIS", "max_depth": 16, "rr_threshold": 0.1})
for part in list(desc.get("objects", [])) + list(desc.get("textures", {}).values()):
    if "path" in part:
        part["path"] = os.path.join(folder, part["path"])
with open(out, "w") as f:
    json.dump(desc, f)
PY
      echo "$WORK/$1.json" ;;
    *@*) echo "render_ab: $1: unknown variant (known: @path)" >&2; exit 2 ;;
    *) echo "$SCENES_DIR/$1.json" ;;
  esac
}
rate() {  # rate BINARY SCENE_FILE SPP -> Mrays per CPU-second
  local out
  out=$( { /usr/bin/time -f "CPU %U %S" "$1" render "$2" -o "$WORK/out.exr" --spp "$3" --threads 1 -q \
             --asset-root "$SCENES_DIR"; } 2>&1 )
  local rays cpu
  rays=$(echo "$out" | sed -nE 's/.*\(([0-9]+) rays\).*/\1/p')
  cpu=$(echo "$out" | awk '/^CPU / { print $2 + $3 }')
  awk -v r="$rays" -v c="$cpu" 'BEGIN { printf "%.4f\n", r / c / 1e6 }'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
echo "render_ab: A = $A, B = $B; best and median of $N, alternating; load $(cut -d' ' -f1-3 /proc/loadavg)"
for s in ${SCENES:-cbox_no_light cbox_no_light_refraction cbox_area_light cbox_env_light sky_sun}; do
  spp=${SPP:-${SPP_OF[$s]:-16}}
  file=$(scene_file "$s")
  rates_a=() rates_b=()
  for _ in $(seq "$N"); do
    rates_a+=("$(rate "$A" "$file" "$spp")")
    rates_b+=("$(rate "$B" "$file" "$spp")")
  done
  best_a=$(printf '%s\n' "${rates_a[@]}" | sort -g | tail -1) best_b=$(printf '%s\n' "${rates_b[@]}" | sort -g | tail -1)
  med_a=$(printf '%s\n' "${rates_a[@]}" | median) med_b=$(printf '%s\n' "${rates_b[@]}" | median)
  awk -v s="$s" -v spp="$spp" -v a="$best_a" -v b="$best_b" -v ma="$med_a" -v mb="$med_b" \
    'BEGIN { printf "  %-26s %4d spp  best A %6.2f  B %6.2f  B/A %.3f   median A %6.2f  B %6.2f  B/A %.3f (Mrays per CPU-s)\n",
             s, spp, a, b, b / a, ma, mb, mb / ma }'
done
echo "load at the end $(cut -d' ' -f1-3 /proc/loadavg)"
