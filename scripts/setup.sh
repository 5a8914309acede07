#!/usr/bin/env bash
# Installs every system dependency Fulgur needs, from Debian 12 packages only.
# Safe to run repeatedly; skips apt when everything is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config   # toolchain
  libglm-dev                                     # vector math
  nlohmann-json3-dev                             # scene files, JSON reports
  libstb-dev                                     # stb_image_write (PNG)
  zlib1g-dev                                     # CRC-32 (crc32) for the .fgb baked file
  doctest-dev                                    # unit/property tests
  libcli11-dev                                   # command lines of every tool (CLI11, header-only)
  libomp-dev                                     # (OpenMP headers for clang tooling; g++ uses libgomp)
  libgl-dev libosmesa6-dev libgl1-mesa-dri       # OpenGL through Mesa, OSMesa for headless
  libglfw3-dev                                   # demo window
  libimgui-dev                                   # demo panel (Dear ImGui)
  python3-glad                                   # GL loader generator (glad2), run at build time
  xvfb xauth                                     # virtual display for the demo screenshot
  python3-matplotlib                             # charts of the studies' CSV (scripts/plot_studies.py)
  libopenvdb-dev                                 # OpenVDB clouds in (scene "cloud": {"vdb": ...}) and out (--vdb)
  libboost-iostreams-dev                         # (asked for by libopenvdb-dev's FindOpenVDB.cmake)
  python3-openvdb                                # writes the VDB test files and content/clouds (scripts/make_vdb_cloud.py)
  clang libclang-rt-14-dev                       # libFuzzer harnesses (fuzz preset, fuzz/)
  clang-format                                   # the formatting check (scripts/check_format.sh)
  libopenmpi-dev openmpi-bin                     # the bake over several processes (MPI; docs/distributed.md)
  libopenexr-dev                                 # linear frames out (fulgur-shot --exr)
  blender                                        # Cycles, the outside renderer of the image (docs/blender.md)
  python3-openimageio                            # reads the EXRs of the Cycles comparison (scripts/)
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]})); then
  SUDO=""
  if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
  echo "setup: installing ${missing[*]}"
  $SUDO apt-get update
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
else
  echo "setup: all system packages present"
fi
