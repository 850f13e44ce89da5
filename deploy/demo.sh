#!/usr/bin/env bash
# One command from a fresh Debian machine to a rendered image: installs what is missing, builds Tessera (Release),
# and renders the project's Cornell box with global illumination (path tracer, rectangular ceiling light) through
# the farm (a private coordinator and 2 local worker processes) to out/cbox_gi.exr (+ a PNG preview).
# Extra arguments go to `tessera render` (for example --spp 16).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
# Each target compiled as one unity unit, as deploy/test.sh does: the fewest compiler runs for a build from scratch.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DTESSERA_UNITY_BATCH_SIZE=0 >/dev/null
cmake --build build -j "$(nproc)" --target tessera
mkdir -p out
./build/cli/tessera render scenes/cbox_gi.json -o out/cbox_gi.exr --preview out/cbox_gi.png --workers 2 "$@"
echo "demo: wrote out/cbox_gi.exr and out/cbox_gi.png"
