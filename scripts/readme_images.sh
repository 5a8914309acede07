#!/usr/bin/env bash
# Draws again the README's and docs/render.md's pictures of the content scenes, each with the
# fulgur-shot command the README states beside it, into docs/images/. Bakes what is not baked
# yet (the scenes' .fgb and sun/sky caches land beside the scenes, as fulgur-shot does).
# Usage: scripts/readme_images.sh [BUILD_DIR]   (default build/release)
# The Cycles comparisons' pictures (blender_compare*.png, day_cumulus_cycles.png), the charts
# (scripts/plot_studies.py), the demo's and the host example's screenshots are made elsewhere.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
shot="$build/app/fulgur-shot"
[ -x "$shot" ] || { echo "readme_images.sh: no $shot (build first)" >&2; exit 1; }
out=docs/images
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

one() {  # one PICTURE SCENE [fulgur-shot options...]
    local picture=$1 scene=$2
    shift 2
    echo "$picture: fulgur-shot content/scenes/$scene $*"
    "$shot" "content/scenes/$scene" "$@" -o "$out/$picture" > /dev/null
}

# Two frames side by side, 4 white columns between them (a PNG of their width sum + 4).
pair() {  # pair PICTURE LEFT.png RIGHT.png
    /usr/bin/python3 - "$@" <<'EOF'
import sys
from PIL import Image
out, left, right = sys.argv[1:]
a, b = Image.open(left).convert("RGBA"), Image.open(right).convert("RGBA")
img = Image.new("RGBA", (a.width + 4 + b.width, max(a.height, b.height)), (255, 255, 255, 255))
img.paste(a, (0, 0))
img.paste(b, (a.width + 4, 0))
img.save(out)
EOF
}

# README, "The scenes": 640x360, automatic exposure.
one scene-storm.png storm.json --seed 1 --time +0.002 --size 640x360
one scene-storm-moonlit.png storm.json --seed 1 --time 0 --size 640x360
one scene-dusk-storm.png dusk-storm.json --seed 1 --time +0.008 --size 640x360
one scene-day-cumulus.png day-cumulus.json --seed 1 --time 0 --size 640x360
one scene-vdb-cloud.png vdb-cloud.json --seed 1 --time +0.002 --size 640x360

# README, "Sub-voxel detail and rain shafts": 1280x720, no dither.
hd=(--seed 1 --size 1280x720 --off dither)
close='{"orbit": {"target": [0, 0, 3000], "distance": 9000, "azimuth": -70, "elevation": 10}}'
shaft='{"orbit": {"target": [-3400, 0, 1400], "distance": 8000, "azimuth": -90, "elevation": 2}}'
one storm-before.png storm.json --time +0.002 "${hd[@]}"
one storm-after.png storm-full.json --time +0.002 "${hd[@]}"
one detail-before.png storm.json --time 0 --camera "$close" "${hd[@]}"
one detail-after.png storm-full.json --time 0 --camera "$close" "${hd[@]}"
one rain-closeup.png storm-full.json --time +0.002 --camera "$shaft" "${hd[@]}"
one return-stroke-peak.png storm-full.json --time +0.0005 "${hd[@]}"
one dusk-storm-before.png dusk-storm.json --time +0.008 --manual-exposure 0.12 "${hd[@]}"
one dusk-storm-after.png dusk-storm-full.json --time +0.008 --manual-exposure 0.12 "${hd[@]}"
one day-cumulus-before.png day-cumulus.json --time 0 "${hd[@]}"
one day-cumulus-after.png day-cumulus-full.json --time 0 "${hd[@]}"

# docs/render.md's glare (without | with) and the README's ground lit by the channel alone | and
# by the cloud's scattered light (+2 EV).
out=$work
one no-glare.png storm.json --seed 1 --time +0.002 --size 640x360 --off glare
one glare.png storm.json --seed 1 --time +0.002 --size 640x360
one ground-channel.png storm.json --seed 1 --time +0.002 --size 640x360 --exposure 2 --off dither,ground-scatter
one ground-scatter.png storm.json --seed 1 --time +0.002 --size 640x360 --exposure 2 --off dither
pair docs/images/glare.png "$work/no-glare.png" "$work/glare.png"
pair docs/images/ground_scatter.png "$work/ground-channel.png" "$work/ground-scatter.png"
echo "readme_images.sh: done"
