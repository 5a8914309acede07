// Helpers shared by the cloud tests: measurements of a density grid.
#pragma once

#include "cloud/cloud.h"

#include <cstddef>

namespace fulgur::cloud::test {

/// Index of the voxel layer containing height z (metres).
inline int layer_at(const core::Grid3<float>& d, double z) { return int((z - d.geom.origin.z) / d.geom.voxel_size); }

/// Horizontal area (m^2) of layer k where the density exceeds `threshold`.
inline double layer_area(const core::Grid3<float>& d, int k, float threshold) {
    std::size_t n = 0;
    for (int j = 0; j < d.dims().y; ++j)
        for (int i = 0; i < d.dims().x; ++i) n += d.at(i, j, k) > threshold ? 1 : 0;
    return double(n) * d.geom.voxel_size * d.geom.voxel_size;
}

/// Largest layer_area over layers [k0, k1].
inline double max_layer_area(const core::Grid3<float>& d, int k0, int k1, float threshold) {
    double m = 0.0;
    for (int k = k0; k <= k1; ++k) m = std::max(m, layer_area(d, k, threshold));
    return m;
}

/// Number of voxels whose density exceeds `threshold`.
inline std::size_t cloudy_voxels(const core::Grid3<float>& d, float threshold) {
    std::size_t n = 0;
    for (float v : d.data) n += v > threshold ? 1 : 0;
    return n;
}

}  // namespace fulgur::cloud::test
