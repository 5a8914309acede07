// fulgur::basis — reconstruction of weighted sums of bases (compressed or raw) and their
// export as NRRD float32 (opens in ParaView / 3D Slicer). docs/basis.md section 5.
#pragma once

#include "basis/fgb.h"
#include "core/core.h"
#include "transport/transport.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>

namespace fulgur::basis {

struct WeightedLight {
    std::uint32_t light = 0;
    double weight = 1.0;
};

/// sum_l w_l b_l for direction m from the compressed data: the coefficients are summed
/// (Eq. 9) over the lights and over the stored components (the total S the file holds)
/// and inverse transformed once (the bake's decomposition), in double; no ambient term is
/// added.
core::Grid3<float> reconstruct(const BakedBasis& baked, std::span<const WeightedLight> lights, std::size_t direction);

/// sum_l w_l b_l for direction m from uncompressed fields: field_of(light) returns that
/// light's SourceField (all must share the geometry and direction count).
core::Grid3<float> weighted_sum(std::span<const WeightedLight> lights, std::size_t direction,
                                const std::function<const transport::SourceField&(std::uint32_t)>& field_of);

/// Writes reconstruct(...) / weighted_sum(...) as NRRD with a content line naming the
/// lights, weights and direction.
void export_compressed_nrrd(const std::filesystem::path& path, const BakedBasis& baked,
                            std::span<const WeightedLight> lights, std::size_t direction);
void export_raw_nrrd(const std::filesystem::path& path, std::span<const WeightedLight> lights, std::size_t direction,
                     const std::function<const transport::SourceField&(std::uint32_t)>& field_of);

}  // namespace fulgur::basis
