// BakedBases' storage (runtime.h, docs/runtime.md "Data layout"). Internal to engine/runtime
// and its tests.
#pragma once

#include "runtime/runtime.h"

#if defined(__F16C__)
#include <immintrin.h>
#endif

#include <cstdint>
#include <vector>

namespace fulgur::runtime {

/// Exact binary16 -> binary32: the F16C instruction where the build targets it, else the
/// portable bit-level conversion (same result).
inline float half_to_float_fast(std::uint16_t h) noexcept {
#if defined(__F16C__)
    return _cvtsh_ss(h);
#else
    return basis::half_to_float(h);
#endif
}

struct BakedBases::Impl {
    basis::FgbMetadata meta;
    std::size_t bases_per_light = 0;  ///< meta.bases()
    /// Run of basis (l, b) in the pool: [offset[r], offset[r + 1]) with r = l * bases_per_light + b.
    std::vector<std::uint64_t> offset;
    bool narrow = true;  ///< indices in index16 (cells <= 65536), else index32
    std::vector<std::uint16_t> index16;
    std::vector<std::uint32_t> index32;
    /// Values as the file stores them: float32 files in `value`; float16 files stay float16
    /// in `value16` (a third less memory and accumulation traffic than expanding them),
    /// each run's value being half * 2^scale_exp[r] (exactly the file's value).
    bool half = false;
    std::vector<float> value;
    std::vector<std::uint16_t> value16;
    std::vector<std::int32_t> scale_exp;  ///< per run, float16 only
    std::vector<double> gamma;            ///< per run: sqrt of the dropped coefficients' energy

    std::size_t values() const noexcept { return half ? value16.size() : value.size(); }
    /// Stored value k of run r as a float (the file's value, exactly).
    float value_at(std::size_t r, std::size_t k) const noexcept;

    std::size_t run(std::size_t light, std::size_t basis) const noexcept { return light * bases_per_light + basis; }
};

/// The storage of `b` (for the reconstruction and the module's tests).
inline const BakedBases::Impl& bases_impl(const BakedBases& b) noexcept { return *b.impl_; }

}  // namespace fulgur::runtime
