#!/usr/bin/env bash
# Sets up (Debian packages), builds and runs Fulgur's main job: the interactive storm demo
# `fulgur` on content/scenes/storm.json. The first run bakes the scene (progress bar in the
# terminal). Without a display it says so and renders a short headless PNG sequence into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"
exec ./build/release/app/fulgur content/scenes/storm.json "$@"
