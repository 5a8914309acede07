// Small density grids and cell loops shared by the tests of several modules.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

namespace fulgur::test {

/// A grid of dims cells of voxel_size metres from origin, every cell `fill`.
inline core::Grid3<float> uniform_grid(core::Int3 dims, double voxel_size, glm::dvec3 origin = glm::dvec3(0.0),
                                       float fill = 0.0f) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = voxel_size;
    g.origin = origin;
    return core::Grid3<float>(g, fill);
}

/// An empty grid (origin 0) but for the one cell `at`, at density 1: a point-like cloud.
inline core::Grid3<float> single_voxel_cloud(core::Int3 dims, double voxel_size, core::Int3 at) {
    core::Grid3<float> d = uniform_grid(dims, voxel_size);
    d.at(at.x, at.y, at.z) = 1.0f;
    return d;
}

/// Calls fn(x, y, z) for every cell of a dims.x x dims.y x dims.z grid, x fastest (the
/// order of core::GridGeometry::index).
template <class F>
void for_each_cell(core::Int3 dims, F&& fn) {
    for (int z = 0; z < dims.z; ++z)
        for (int y = 0; y < dims.y; ++y)
            for (int x = 0; x < dims.x; ++x) fn(x, y, z);
}

}  // namespace fulgur::test
