#!/usr/bin/env bash
# Checks that every tracked C++ source (*.h, *.cpp) under app, engine, tests, fuzz and
# examples is formatted as .clang-format says (clang-format 14, Debian package clang-format).
# Changes nothing: prints each deviation and exits non-zero if there is any. To fix a file:
# clang-format -i FILE.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v clang-format >/dev/null; then
  echo "check_format: clang-format not found (scripts/setup.sh installs it)" >&2
  exit 1
fi

mapfile -t files < <(git ls-files -- 'app/*.h' 'app/*.cpp' 'engine/*.h' 'engine/*.cpp' 'tests/*.h' 'tests/*.cpp' \
  'fuzz/*.h' 'fuzz/*.cpp' 'examples/*.h' 'examples/*.cpp')
if ((${#files[@]} == 0)); then
  echo "check_format: no tracked sources found" >&2
  exit 1
fi

if clang-format --dry-run -Werror "${files[@]}"; then
  echo "check_format: ${#files[@]} files formatted as .clang-format says"
else
  echo "check_format: the files above differ from .clang-format (fix with clang-format -i FILE)" >&2
  exit 1
fi
