#!/usr/bin/env bash
# One command from a fresh Debian machine to a rendered image: installs what is missing, builds Tessera (Release),
# and renders the project's Cornell box with its rectangular area light through the farm (a private coordinator
# and 2 local worker processes) to out/cbox_area_light.exr (+ a PNG preview).
# Extra arguments go to `tessera render` (for example --spp 16).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$(nproc)" --target tessera
mkdir -p out
./build/cli/tessera render scenes/cbox_area_light.json -o out/cbox_area_light.exr --preview out/cbox_area_light.png --workers 2 "$@"
echo "demo: wrote out/cbox_area_light.exr and out/cbox_area_light.png"
