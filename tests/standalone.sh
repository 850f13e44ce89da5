#!/usr/bin/env bash
# The repository stands alone: no file of it names a folder beside the checkout. The course scenes the tests and
# benches use live in scenes/course/; a path that climbs out of the repository to a sibling folder for them (or the
# old names of that folder and of its compile definition) fails this check, with every offending line printed.
# Files checked: those git tracks when SOURCE_DIR is the top of a git checkout, otherwise every file under SOURCE_DIR
# except .git and build folders (build*, out).
# Usage: standalone.sh SOURCE_DIR
set -euo pipefail
SRC=${1:?usage: standalone.sh SOURCE_DIR}
SRC=$(cd "$SRC" && pwd -P)

# Built from pieces so that this file does not match its own patterns.
word=shar
word=${word}ed
patterns=("\\.\\./${word}" "compat/rdr""171" "TESSERA_${word^^}_DIR")
args=()
for p in "${patterns[@]}"; do args+=(-e "$p"); done

top=
if command -v git >/dev/null 2>&1; then
  top=$(git -C "$SRC" rev-parse --show-toplevel 2>/dev/null || true)
  [ -n "$top" ] && top=$(cd "$top" && pwd -P)
fi

status=0
if [ "$top" = "$SRC" ]; then
  how="tracked files (git grep)"
  found=$(git -C "$SRC" grep -nIE "${args[@]}") || status=$?
else
  how="files under $SRC (grep -r; not a git checkout)"
  found=$(cd "$SRC" && grep -rnIE --exclude-dir=.git --exclude-dir='build*' --exclude-dir=out "${args[@]}" .) ||
    status=$?
fi
# Both greps exit 1 when nothing matches and 2 (or more) on an error.
if [ "$status" -gt 1 ]; then
  echo "standalone: the search of $how failed (exit status $status)" >&2
  exit 2
fi
if [ -n "$found" ]; then
  echo "standalone: these lines name a folder outside the repository (the course scenes are in scenes/course/):"
  echo "$found"
  exit 1
fi
echo "standalone: no file names a folder outside the repository ($how)"
