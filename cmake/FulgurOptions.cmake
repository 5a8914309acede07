# Build options shared by every Fulgur target. Targets opt in by linking fulgur_options.
option(FULGUR_WERROR "Treat compiler warnings as errors" ON)
option(FULGUR_NATIVE "Optimize for the build machine (-march=native); the binaries run where they are built" ON)
option(FULGUR_SANITIZE "Build with AddressSanitizer and UndefinedBehaviorSanitizer" OFF)
option(FULGUR_BUILD_TESTS "Build the test suite" ON)
option(FULGUR_BUILD_GL "Build the OpenGL renderer and the executables that need it" ON)
option(FULGUR_FUZZ "Build the libFuzzer harnesses (clang; fuzz/): the engine is instrumented for them" OFF)

if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
  set(CMAKE_BUILD_TYPE Release CACHE STRING "Build type" FORCE)
endif()

add_library(fulgur_options INTERFACE)
add_library(fulgur::options ALIAS fulgur_options)
target_compile_features(fulgur_options INTERFACE cxx_std_20)
target_compile_options(fulgur_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align
  $<$<BOOL:${FULGUR_WERROR}>:-Werror>
  # GCC 12 reports false -Wrestrict positives inside libstdc++ for "literal" + std::string
  # (GCC bug 105329); the warning is not actionable in our code.
  $<$<CXX_COMPILER_ID:GNU>:-Wno-restrict>
  # Never -ffast-math: tests rely on IEEE semantics (NaN checks, exact sums, determinism).
  -fno-fast-math
  $<$<BOOL:${FULGUR_NATIVE}>:-march=native>)
if(FULGUR_SANITIZE)
  target_compile_options(fulgur_options INTERFACE
    -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all)
  target_link_options(fulgur_options INTERFACE -fsanitize=address,undefined)
endif()

if(FULGUR_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "FULGUR_FUZZ needs clang (libFuzzer): use the fuzz preset")
  endif()
  target_compile_options(fulgur_options INTERFACE
    -fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all)
  target_link_options(fulgur_options INTERFACE -fsanitize=address,undefined)
endif()

# Where executables find shaders/ and content/ when run from the build tree.
set(FULGUR_SOURCE_ROOT "${PROJECT_SOURCE_DIR}")
