#!/bin/sh
# The demo's turntable with its panels hidden, under a private Xvfb server: the camera turns on
# its own every frame (the temporal history's moving-camera frames in the window), the
# screenshot's line gives the frame rate, and the camera printed with it, started at azimuth 300
# and turned by a full turn a second, must be one a scene takes again (azimuth within
# [-360, 360]): fulgur-shot draws the same view from it.
# Usage: demo_turntable.sh FULGUR FULGUR_SHOT SCENE.json RUN_WITH_XVFB
set -eu
fulgur=$1
shot=$2
scene=$3
xvfb=$4
rm -rf demo_turn
mkdir demo_turn
cd demo_turn
cp "$scene" scene.json
sh "$xvfb" "$fulgur" scene.json --size 320x180 --screenshot-after 30 --orbit 360 --hide-panels \
    --camera '{"orbit": {"azimuth": 300, "elevation": 10}}' > demo.log
grep -q 'fps over the last second' demo.log
test -s out/screenshot_000.png
camera=$(sed -n 's/^screenshot camera: //p' demo.log)
echo "screenshot camera: $camera"
test -n "$camera"
"$shot" scene.json --seed 1 --time 0 --camera "$camera" --size 64x36 -o again.png > shot.log
test -s again.png
