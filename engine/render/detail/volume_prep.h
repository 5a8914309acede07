// Internal: CPU preparation of the density texture (quantization and the empty-space
// distance field used by the ray marcher to skip empty space).
#pragma once

#include "core/core.h"

#include <cstdint>
#include <vector>

namespace fulgur::render::detail {

/// Chebyshev (L-infinity) distance in voxels from each voxel centre to the nearest voxel
/// with occupied != 0, capped at 255 (also the value when nothing is occupied). Exact:
/// a forward and a backward chamfer pass over the 26-neighbourhood with unit weights.
std::vector<std::uint8_t> chebyshev_distance(const std::vector<std::uint8_t>& occupied, const core::Int3& dims);

/// Density quantized to 8 bits as the GPU stores it (round to nearest, clamped to [0, 1];
/// NaN -> 0).
std::uint8_t quantize_density(float rho) noexcept;

}  // namespace fulgur::render::detail
