#!/usr/bin/env bash
# Two tessera binaries side by side: 1-thread renders of the same scenes, A and B alternating, best of N, rays per
# CPU-second of the whole process (user + system time from /usr/bin/time, so other processes on a shared machine do
# not count; loading and writing the EXR are included and cost both the same). For commit messages of optimisations:
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
                   [cbox_env_light]=16 [sky_sun]=16 [cbox_gi]=16 [cbox_glass]=16 [veach_mis]=16)
rate() {  # rate BINARY SCENE SPP -> Mrays per CPU-second
  local out
  out=$( { /usr/bin/time -f "CPU %U %S" "$1" render "$SCENES_DIR/$2.json" -o "$WORK/out.exr" --spp "$3" --threads 1 -q; } 2>&1 )
  local rays cpu
  rays=$(echo "$out" | sed -nE 's/.*\(([0-9]+) rays\).*/\1/p')
  cpu=$(echo "$out" | awk '/^CPU / { print $2 + $3 }')
  awk -v r="$rays" -v c="$cpu" 'BEGIN { printf "%.4f\n", r / c / 1e6 }'
}
echo "render_ab: A = $A, B = $B; best of $N, alternating; load $(cut -d' ' -f1-3 /proc/loadavg)"
for s in ${SCENES:-cbox_no_light cbox_no_light_refraction cbox_area_light cbox_env_light sky_sun}; do
  spp=${SPP:-${SPP_OF[$s]:-16}}
  best_a=0 best_b=0
  for _ in $(seq "$N"); do
    best_a=$(awk -v x="$best_a" -v y="$(rate "$A" "$s" "$spp")" 'BEGIN { print (y > x) ? y : x }')
    best_b=$(awk -v x="$best_b" -v y="$(rate "$B" "$s" "$spp")" 'BEGIN { print (y > x) ? y : x }')
  done
  awk -v s="$s" -v spp="$spp" -v a="$best_a" -v b="$best_b" \
    'BEGIN { printf "  %-26s %4d spp  A %6.2f  B %6.2f Mrays per CPU-s  B/A %.3f\n", s, spp, a, b, b / a }'
done
echo "load at the end $(cut -d' ' -f1-3 /proc/loadavg)"
