#!/usr/bin/env bash
# The Dockerfile's runtime stage, checked without a Docker engine: its base is the Debian release this machine runs
# (so package names match), and it installs the Debian package of every shared library the built `tessera` links
# (found with ldd and dpkg -S). A library added to the build without its runtime package fails here, not in a
# container at start-up. Arguments: TESSERA SOURCE_DIR.
set -euo pipefail
TESSERA=$1
DOCKERFILE=$2/Dockerfile
fail() { echo "FAIL: $*" >&2; exit 1; }
for tool in ldd dpkg-query; do command -v "$tool" >/dev/null || fail "'$tool' not found (this check needs a Debian system)"; done
[ -f "$DOCKERFILE" ] || fail "no Dockerfile at $DOCKERFILE"

codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
[ -n "$codename" ] || fail "cannot tell this machine's Debian release from /etc/os-release"
grep -Eq "^FROM debian:$codename AS build" "$DOCKERFILE" || fail "the build stage is not FROM debian:$codename"
grep -Eq "^FROM debian:$codename-slim AS runtime" "$DOCKERFILE" || fail "the runtime stage is not FROM debian:$codename-slim"

# Package names on the runtime stage's `apt-get install` lines (from its FROM to the end of the file).
runtime_pkgs=$(sed -n '/^FROM .* AS runtime/,$p' "$DOCKERFILE" | tr '\\' '\n' |
  sed -n '/apt-get install/,/&&/p' | tr ' ' '\n' | grep -E '^[a-z0-9][a-z0-9.+-]+$' |
  grep -vE '^(apt-get|install|rm)$' | sort -u)
[ -n "$runtime_pkgs" ] || fail "found no apt-get install list in the runtime stage"

missing=()
checked=0
while read -r lib path; do
  [ -n "$path" ] || continue
  pkg=""
  for candidate in "$path" "$(readlink -f "$path")" "/usr$path"; do
    pkg=$(dpkg-query -S "$candidate" 2>/dev/null | head -n1 | cut -d: -f1) && [ -n "$pkg" ] && break
  done
  [ -n "$pkg" ] || fail "$lib ($path) belongs to no Debian package: the runtime image could not provide it"
  checked=$((checked + 1))
  grep -qx -- "$pkg" <<<"$runtime_pkgs" || missing+=("$pkg ($lib)")
done < <(ldd "$TESSERA" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}')
[ "$checked" -gt 0 ] || fail "ldd listed no shared libraries for $TESSERA"
[ ${#missing[@]} = 0 ] || fail "the runtime stage does not install: ${missing[*]}"
echo "PASS: the runtime stage installs the packages of all $checked shared libraries of tessera"
