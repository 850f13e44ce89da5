#!/usr/bin/env bash
# Tessera against Blender Cycles at equal error (direct lighting and path tracing), optional and not in CI.
# Usage: bench/vs_cycles/run.sh [--tessera PATH] [options of vs_cycles.py, e.g. --threads 2 --repeats 3]
# Writes bench/results/vs_cycles.txt unless --out is given. Needs Debian's `blender` (3.4); skipped without it.
set -euo pipefail
if ! command -v blender >/dev/null 2>&1; then
  echo "vs_cycles: skipped: blender not installed (apt-get install blender)"
  exit 0
fi
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
tessera="$repo/build/cli/tessera"
out="$repo/bench/results/vs_cycles.txt"
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --tessera) tessera="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
if [[ ! -x "$tessera" ]]; then
  echo "vs_cycles: $tessera not found; build it first: cmake --build build --target tessera" >&2
  exit 1
fi
# Blender's own log lines (Fra:, Saved:, Time:) are dropped; the report goes to stdout and to $out.
blender -b --factory-startup --python-exit-code 1 --python "$here/vs_cycles.py" -- \
  --tessera "$tessera" --repo "$repo" --out "$out" "${args[@]}" 2>&1 |
  grep -v -E '^(Fra:|Saved:| Time:|Blender quit|Read blend:|$)' || true
test -s "$out"
