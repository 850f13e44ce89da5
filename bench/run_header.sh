# shellcheck shell=bash
# Sourced by benchmarks: run_header NAME ROOT BUILD_DIR prints the first lines of a results file (the bench's name and
# the time, the commit with -dirty for a modified tree, the machine, the build's flags and the binary's version).
run_header() {
  local name=$1 root=$2 build=$3 commit flags
  commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
  git -C "$root" diff --quiet HEAD 2>/dev/null || commit="$commit-dirty"
  flags=$(sed -nE 's/^(CMAKE_BUILD_TYPE|TESSERA_NATIVE|CMAKE_CXX_FLAGS_RELEASE):[A-Z]+=(.*)/\1=\2/p' "$build/CMakeCache.txt" | tr '\n' ' ')
  echo "$name: $(date -u +%FT%TZ), commit $commit"
  echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), nproc $(nproc); build: $flags"
  echo "binary: $("$build/cli/tessera" --version)"
}
