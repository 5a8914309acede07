#include "core/core.h"

#include <numbers>

namespace fulgur::core {

Rng::Rng(std::uint64_t seed, std::uint64_t stream) noexcept {
    // PCG32 initialisation (pcg32_srandom_r): the stream selects the odd increment.
    inc_ = (stream << 1u) | 1u;
    state_ = 0;
    next_u32();
    state_ += seed;
    next_u32();
}

std::uint32_t Rng::next_u32() noexcept {
    const std::uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const auto xorshifted = std::uint32_t(((old >> 18u) ^ old) >> 27u);
    const auto rot = std::uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31u));
}

double Rng::uniform() noexcept {
    const std::uint64_t hi = next_u32() >> 5;  // 27 bits
    const std::uint64_t lo = next_u32() >> 6;  // 26 bits
    return double((hi << 26) | lo) * 0x1p-53;
}

std::uint32_t Rng::uniform_below(std::uint32_t bound) noexcept {
    FULGUR_ASSERT(bound > 0, "uniform_below needs a positive bound");
    const std::uint32_t threshold = (-bound) % bound;  // 2^32 mod bound
    for (;;) {
        const std::uint32_t r = next_u32();
        if (r >= threshold) return r % bound;
    }
}

double Rng::normal() noexcept {
    // Box-Muller; 1 - u keeps the logarithm's argument in (0, 1].
    const double u1 = 1.0 - uniform();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

std::uint64_t hash_seed(std::uint64_t a, std::uint64_t b, std::uint64_t c) noexcept {
    auto mix = [](std::uint64_t z) {
        z += 0x9e3779b97f4a7c15ULL;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return z ^ (z >> 31);
    };
    return mix(mix(mix(a) ^ b) ^ c);
}

}  // namespace fulgur::core
