#!/usr/bin/env bash
# Sets up (Debian packages), builds and runs Fulgur's main job.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"
exec ./build/release/app/fulgur-preview content/scenes/storm.json -o out/preview "$@"
