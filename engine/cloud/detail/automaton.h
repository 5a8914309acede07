// Internal to fulgur::cloud (tests include it): the pieces of the cumulonimbus generator.
//
//  * Ellipsoid / cumulonimbus_layout: where the seed ellipsoids go.
//  * seed_field: the per-cell seed weight W in [0, 1] (max over ellipsoids), 8-bit.
//  * Automaton: Dobashi et al. 2000's cellular automaton driven by W.
//  * smooth_density: space-time average to a continuous density.
#pragma once

#include "cloud/cloud.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace fulgur::cloud::detail {

/// A seed ellipsoid: axis-aligned; at normalized distance d from the centre its weight is
/// strength * (1 - t^2)^2 with t = clamp((d - (1 - softness)) / softness, 0, 1): a plateau
/// of full strength inside d < 1 - softness, falling smoothly to 0 at d = 1. Nothing above
/// z_max (used for the anvil's flat top).
struct Ellipsoid {
    glm::dvec3 centre{0.0};  ///< metres
    glm::dvec3 radii{1.0};   ///< semi-axes, metres
    double strength = 1.0;   ///< peak weight in (0, 1]
    double softness = 1.0;   ///< in (0, 1]: fraction of the radius over which the weight falls
    double z_max = std::numeric_limits<double>::infinity();
};

/// The ellipsoid's weight at squared normalized distance d2 (0 outside).
double ellipsoid_weight(const Ellipsoid& e, double d2) noexcept;

/// The seed ellipsoids of the cumulonimbus `p` describes (p must be valid). Deterministic:
/// a function of p only (its own RNG stream of p.seed).
std::vector<Ellipsoid> cumulonimbus_layout(const CumulonimbusParams& p);

/// Seed weight per cell (x fastest), W = max over ellipsoids, quantized to 0..255
/// (255 = 1). Cells whose centre lies below floor_z get 0.
std::vector<std::uint8_t> seed_field(const core::GridGeometry& g, std::span<const Ellipsoid> ellipsoids,
                                     double floor_z);

/// Dobashi et al. 2000's cellular automaton. Each cell holds three bits (hum, act, cld).
/// One step applies, in this order,
///   growth:     hum' = hum & !act,  cld' = cld | act,  act' = !act & hum & f_act,
///               f_act = act at (i±1,j,k), (i,j±1,k), (i,j,k±1), (i±2,j,k), (i,j±2,k), (i,j,k-2)
///   extinction: cld' &= rnd >= p_ext(W)
///   supply:     hum' |= rnd < p_hum(W),  act' |= rnd < p_act(W)
/// with p_ext(W) = p_ext (1 - W), p_hum(W) = p_hum W, p_act(W) = p_act W and W the cell's
/// seed weight. Outside the grid every state is false. A cell with W = 0 never receives
/// vapour or activation, so it stays empty for ever: the automaton skips such cells (and
/// their state must be, and stays, 0). Random numbers come from one core::Rng per
/// (seed, step, row), so the result is the same for any thread count.
class Automaton {
public:
    static constexpr std::uint8_t kHum = 1, kAct = 2, kCld = 4;

    struct Probabilities {
        double p_ext = 0.0, p_hum = 0.0, p_act = 0.0;
    };

    Automaton(core::Int3 dims, std::vector<std::uint8_t> weights, Probabilities p, std::uint64_t seed);

    const core::Int3& dims() const noexcept { return dims_; }
    std::uint8_t get(int i, int j, int k) const noexcept { return cur_[padded(i, j, k)]; }
    /// Sets a cell's bits (kHum | kAct | kCld); a cell with W = 0 only accepts 0.
    void set(int i, int j, int k, std::uint8_t bits) noexcept;
    /// Initial state: vapour with probability W (a head start towards the steady state),
    /// no activation, no cloud. Uses its own random stream.
    void init_vapour();
    /// One step. If cld_counts is given (one byte per cell, x fastest), adds the new cld
    /// bit of every cell to it.
    void step(std::uint8_t* cld_counts = nullptr);
    int steps_done() const noexcept { return steps_; }
    /// Number of cells whose cld bit is set.
    std::size_t cloud_cells() const;

private:
    std::size_t padded(int i, int j, int k) const noexcept {
        return std::size_t(i + kPad) + sy_ * std::size_t(j + kPad) + sz_ * std::size_t(k + kPad);
    }
    static constexpr int kPad = 2;  // the neighbourhood reaches two cells out
    core::Int3 dims_;
    std::size_t sy_ = 0, sz_ = 0;
    std::vector<std::uint8_t> weights_;            // unpadded, x fastest
    std::vector<std::uint8_t> cur_, next_;         // padded states
    std::vector<std::int32_t> span_lo_, span_hi_;  // per row (j + ny k): cells [lo, hi) with W > 0
    // 16-bit thresholds per weight level: event if (16 random bits) < threshold.
    std::array<std::uint32_t, 256> thr_ext_{}, thr_hum_{}, thr_act_{};
    std::uint64_t seed_;
    int steps_ = 0;
};

/// Space-time average to density: counts (cld over the averaging window, x fastest) /
/// window, smoothed by a separable (1 - (d/(r+1))^2)^3 kernel of radius r (voxels) — a
/// normalized convolution that only uses layers k >= first_layer, so the cloud base stays
/// flat and sharp — then density = min(1, gain * value). Layers below first_layer are 0.
std::vector<float> smooth_density(core::Int3 dims, std::span<const std::uint8_t> counts, int window, int radius,
                                  int first_layer, double gain);

}  // namespace fulgur::cloud::detail
