// fulgur::core — random numbers: PCG32 (O'Neill 2014), deterministic per (seed, stream), and seed mixing.
#pragma once

#include <cstdint>

namespace fulgur::core {

/// PCG32 (XSH-RR, 64-bit state). Deterministic for a given (seed, stream); different
/// streams are independent sequences, so per-path or per-batch streams give results that
/// do not depend on the thread count.
class Rng {
public:
    explicit Rng(std::uint64_t seed = 0x853c49e6748fea9bULL, std::uint64_t stream = 0xda3e39cb94b95bdbULL) noexcept;
    std::uint32_t next_u32() noexcept;
    /// Uniform in [0, 1) with 24 random bits.
    float uniform_float() noexcept { return float(next_u32() >> 8) * 0x1p-24f; }
    /// Uniform in [0, 1) with 53 random bits.
    double uniform() noexcept;
    /// Uniform integer in [0, bound) without modulo bias.
    std::uint32_t uniform_below(std::uint32_t bound) noexcept;
    /// Standard normal (Box-Muller, both draws consumed).
    double normal() noexcept;

private:
    std::uint64_t state_ = 0;
    std::uint64_t inc_ = 0;
};

/// Mixes several 64-bit values into one seed (SplitMix64 finalizer chain).
std::uint64_t hash_seed(std::uint64_t a, std::uint64_t b = 0, std::uint64_t c = 0) noexcept;

}  // namespace fulgur::core
