// IEEE 754 binary16 <-> binary32 conversion, bit-exact and portable (no F16C needed; the
// tests compare against F16C where the build machine has it).
#include "basis/half.h"

#include "basis/detail/internal.h"

#include <bit>

namespace fulgur::basis {

std::uint16_t double_to_half(double v) noexcept {
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(v);
    const std::uint16_t sign = std::uint16_t((bits >> 48) & 0x8000u);
    const std::uint64_t x = bits & 0x7fffffffffffffffull;
    constexpr std::uint64_t kExpMask = 0x7ff0000000000000ull;
    if (x >= kExpMask) {  // Inf or NaN
        if (x == kExpMask) return std::uint16_t(sign | 0x7c00u);
        // Quiet NaN; keep the top payload bits so a NaN stays a NaN.
        return std::uint16_t(sign | 0x7e00u | std::uint16_t((x >> 42) & 0x1ffu));
    }
    const int e = int(x >> 52);  // biased double exponent
    const std::uint64_t mant = (x & 0x000fffffffffffffull) | (e ? 0x0010000000000000ull : 0);
    // |v| = mant * 2^(e - 1075) (e >= 1); a half is q * 2^(E - 25) with a 11-bit q.
    if (e == 0) return sign;  // double subnormals are far below half's range
    const int unbiased = e - 1023;
    if (unbiased >= 16) return std::uint16_t(sign | 0x7c00u);  // >= 65536: overflow
    int shift;                                                 // right shift applied to the 53-bit mantissa
    std::uint32_t exp_field;
    if (unbiased >= -14) {  // normal half: keep 11 significant bits
        shift = 42;
        exp_field = std::uint32_t(unbiased + 15);
    } else {  // subnormal half: value / 2^-24, rounded
        shift = 42 + (-14 - unbiased);
        exp_field = 0;
        if (shift > 53) return sign;  // < 2^-25 (at most half the smallest subnormal, tie -> even 0)
    }
    std::uint64_t q = mant >> shift;
    const std::uint64_t rem = mant & ((std::uint64_t(1) << shift) - 1);
    const std::uint64_t halfway = std::uint64_t(1) << (shift - 1);
    if (rem > halfway || (rem == halfway && (q & 1))) ++q;
    std::uint32_t h;
    if (exp_field == 0) {
        h = std::uint32_t(q);  // q == 0x400 is the smallest normal: the bit pattern is right
    } else {
        // q has the implicit bit at 2^10; rounding may carry into 2^11 (next binade).
        h = (exp_field << 10) + std::uint32_t(q - 0x400);
        if (h >= 0x7c00u) return std::uint16_t(sign | 0x7c00u);  // rounded up to infinity
    }
    return std::uint16_t(sign | h);
}

std::uint16_t float_to_half(float f) noexcept { return double_to_half(double(f)); }

float half_to_float(std::uint16_t h) noexcept {
    const std::uint32_t sign = std::uint32_t(h & 0x8000u) << 16;
    const std::uint32_t e = (h >> 10) & 0x1fu;
    const std::uint32_t m = h & 0x3ffu;
    if (e == 0) {
        // +-0 or subnormal m * 2^-24: exact in float.
        const float v = float(m) * 0x1p-24f;
        return sign ? -v : v;
    }
    if (e == 31) return std::bit_cast<float>(sign | 0x7f800000u | (m << 13));
    return std::bit_cast<float>(sign | ((e + 112u) << 23) | (m << 13));
}

}  // namespace fulgur::basis
