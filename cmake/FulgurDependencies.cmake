# Every dependency comes from Debian 12 packages (scripts/setup.sh installs them).
# Nothing is downloaded or vendored at build time.
find_package(Threads REQUIRED)
find_package(OpenMP REQUIRED COMPONENTS CXX)        # libgomp: threads over the 2 cores
find_package(glm REQUIRED)                          # libglm-dev: vector math
find_package(nlohmann_json 3.10 REQUIRED)           # nlohmann-json3-dev: scene files, reports
find_package(PkgConfig REQUIRED)
pkg_check_modules(STB REQUIRED IMPORTED_TARGET stb) # libstb-dev: PNG writing (stb_image_write)
find_package(ZLIB REQUIRED)                         # zlib1g-dev: CRC-32 of .fgb files
find_package(CLI11 2.1 REQUIRED)                    # libcli11-dev: the tools' command lines
# libopenvdb-dev: OpenVDB clouds in and out (engine/cloud/vdb_child.cpp and vdb.cpp only), as OpenVDB::openvdb.
# Debian ships its FindOpenVDB.cmake beside the library, not in CMake's module directory; the
# module asks for Boost.Iostreams (libboost-iostreams-dev) and sets BUILD_SHARED_LIBS, so it
# runs inside a function: its variables stay there, its imported targets are directory-wide.
function(fulgur_find_openvdb)
  list(APPEND CMAKE_MODULE_PATH /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB)
  find_package(OpenVDB REQUIRED)
endfunction()
fulgur_find_openvdb()
find_package(OpenEXR 3 REQUIRED CONFIG)             # libopenexr-dev: linear frames out (fulgur-shot --exr)
# libopenmpi-dev + openmpi-bin: the bake and the lattice over several processes (engine/distributed,
# docs/distributed.md). Optional: on by default where MPI is found; without it every process is
# rank 0 of 1.
set(MPI_CXX_SKIP_MPICXX ON)  # the C API only (no deprecated C++ bindings)
find_package(MPI COMPONENTS CXX)
option(FULGUR_MPI "Build the distributed bake over MPI (Open MPI)" ${MPI_CXX_FOUND})
if(FULGUR_MPI AND NOT MPI_CXX_FOUND)
  message(FATAL_ERROR "FULGUR_MPI is on but no MPI was found: install libopenmpi-dev openmpi-bin "
                      "(scripts/setup.sh) or configure with -DFULGUR_MPI=OFF")
endif()

if(FULGUR_BUILD_TESTS)
  find_package(doctest REQUIRED)                    # doctest-dev
endif()

if(FULGUR_BUILD_GL)
  find_package(OpenGL REQUIRED COMPONENTS OpenGL)   # libgl-dev (glvnd)
  find_package(glfw3 3.3 REQUIRED)                  # libglfw3-dev: demo window
  pkg_check_modules(OSMESA REQUIRED IMPORTED_TARGET osmesa)   # libosmesa6-dev: headless GL
  pkg_check_modules(IMGUI REQUIRED IMPORTED_TARGET imgui)     # libimgui-dev: demo panel
endif()

# Debian's python3 first (its packages are there): glad2 (python3-glad) generates the GL 4.5
# core loader at build time from the Khronos XML it ships (the loader takes the current
# context's get-proc-address); python3-openvdb writes the VDB test files at test time.
if(FULGUR_BUILD_GL OR FULGUR_BUILD_TESTS)
  find_program(FULGUR_PYTHON3 NAMES python3 PATHS /usr/bin NO_DEFAULT_PATH)
  if(NOT FULGUR_PYTHON3)
    find_program(FULGUR_PYTHON3 NAMES python3 REQUIRED)
  endif()
endif()
