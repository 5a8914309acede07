#!/bin/sh
# The installed engine used from outside the tree: `cmake --install` of this build into a
# fresh prefix, examples/minimal configured with find_package(Fulgur) against that prefix
# only, built, and run on a tiny scene (it bakes the scene's .fgb, renders a frame before
# and one at a return stroke, and fails if the flash does not light the image).
# usage: install_example.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -eu
build=$1 src=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
# The package is found in the prefix, not in the build tree (no package registry, no hints).
cmake -S "$src/examples/minimal" -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$work/configure.log"
grep -q "$work/prefix" "$work/build/CMakeCache.txt"
cmake --build "$work/build" > "$work/build.log"
cp "$src/tests/apps/scenes/test_iso_ss_ic.json" "$work/scene.json"
cd "$work"
./build/fulgur-minimal scene.json frame | tee run.log
test -s frame_before.png
test -s frame_flash.png
grep -q "frame_flash.png: .*lit yes" run.log
# Headers of detail/ are not installed; the public ones are.
test -f prefix/include/fulgur/view/view.h
test ! -e prefix/include/fulgur/transport/detail
test -f prefix/share/fulgur/shaders/common.glsl
