#!/usr/bin/env bash
# Installs every Debian package Tessera's build, tests and benchmarks need.
# Idempotent: packages already present are skipped, so a second run costs only a dpkg query.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git curl ca-certificates python3
  clang libclang-rt-14-dev
  libboost1.81-dev nlohmann-json3-dev libopenexr-dev libimath-dev libglm-dev
  libspdlog-dev libfmt-dev libtinyobjloader-dev libtbb-dev libcli11-dev
  libsqlite3-dev libpng-dev zlib1g-dev libdeflate-dev libssl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libembree-dev gnuplot-nox
  slurm-wlm munge python3-yaml python3-kubernetes systemd
  openssl iproute2
  chromium chromium-driver python3-selenium
  python3-openimageio python3-numpy openexr
  ffmpeg
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "install-deps: need root (or sudo) to install: ${missing[*]}" >&2; exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
