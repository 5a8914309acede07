// fulgur::basis — IEEE 754 binary16 conversions, the float16 storage precision of bases.
#pragma once

#include <cstdint>

namespace fulgur::basis {

/// IEEE 754 binary16 from binary32, round to nearest, ties to even; subnormal halves are
/// produced (gradual underflow), magnitudes below half the smallest subnormal become +-0,
/// overflow gives +-infinity, NaN gives a quiet NaN with the sign kept.
std::uint16_t float_to_half(float f) noexcept;
/// Exact binary16 -> binary32 (every half is representable).
float half_to_float(std::uint16_t h) noexcept;

}  // namespace fulgur::basis
