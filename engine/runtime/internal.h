// BakedBases' storage (runtime.h, docs/runtime.md "Data layout"). Internal to engine/runtime
// and its tests.
#pragma once

#include "runtime/runtime.h"

#include <cstdint>
#include <vector>

namespace fulgur::runtime {

struct BakedBases::Impl {
    basis::FgbMetadata meta;
    std::size_t bases_per_light = 0;  ///< meta.bases()
    /// Run of basis (l, b) in the pool: [offset[r], offset[r + 1]) with r = l * bases_per_light + b.
    std::vector<std::uint64_t> offset;
    bool narrow = true;                  ///< indices in index16 (cells <= 65536), else index32
    std::vector<std::uint16_t> index16;
    std::vector<std::uint32_t> index32;
    std::vector<float> value;            ///< float32 (float16 files expanded exactly)
    std::vector<double> gamma;           ///< per run: sqrt of the dropped coefficients' energy

    std::size_t run(std::size_t light, std::size_t basis) const noexcept { return light * bases_per_light + basis; }
};

}  // namespace fulgur::runtime
