// The headers most test files include, precompiled once and reused by every test program
// (tests/CMakeLists.txt, fulgur_add_test): parsing them was ~1 s of each file's ~3-4 s of
// compiling. A test file still includes what it uses; this only makes it cheaper.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include "core/core.h"
#include "support/test_support.h"
#include "transport/transport.h"
