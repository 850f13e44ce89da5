#!/usr/bin/env bash
# Installs what is missing, builds Tessera and runs it. (Rendering arrives with the renderer; until then this
# builds the binary and prints its version.)
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$(nproc)" --target tessera
./build/cli/tessera --version
