// Internal numerical kernels shared by single scattering and the Monte Carlo solver:
// Gauss-Legendre rules, an inlinable Henyey-Greenstein evaluation for hot loops, and the
// chord integral of an exponential.
#pragma once

#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>

namespace fulgur::transport::detail {

/// Gauss-Legendre rule with n points on [0, 1] (nodes ascending, weights summing to 1),
/// 1 <= n <= kMaxGaussPoints. Computed once (Newton on P_n, to ~1e-15).
inline constexpr int kMaxGaussPoints = 32;
struct GaussRule {
    std::span<const double> x;
    std::span<const double> w;
};
GaussRule gauss_legendre(int n);

/// HG constants for a fixed g (already clamped), for evaluating p over many cosines.
struct HgConstants {
    double one_minus_g_sq;  // (1-g)^2
    double two_g;           // 2g
    double norm;            // (1 - g^2) / (4 pi)
    bool isotropic;         // g == 0: p = 1 / (4 pi)
    explicit HgConstants(double g) noexcept {
        g = std::isnan(g) ? 0.0 : std::clamp(g, -kMaxAbsG, kMaxAbsG);
        one_minus_g_sq = (1.0 - g) * (1.0 - g);
        two_g = 2.0 * g;
        norm = (1.0 - g * g) / (4.0 * std::numbers::pi);
        isotropic = g == 0.0;
    }
    /// p(cos): same formula as hg_phase() (stable denominator), inlinable and vectorizable.
    double operator()(double cos_theta) const noexcept {
        // std::min(1.0, std::max(-1.0, cos_theta)) written as selects, which a loop over
        // directions vectorizes (the reference-returning forms kept it scalar).
        const double lo = -1.0 < cos_theta ? cos_theta : -1.0;
        const double c = lo < 1.0 ? lo : 1.0;
        const double d = one_minus_g_sq + two_g * (1.0 - c);
        return norm / (d * std::sqrt(d));
    }
};

/// A phase function mixed with a second one by the second's share (PhaseMix): p + share (p2 - p).
/// Every solver's read-out mixes by this one rule.
inline double mixed_phase(double p, double p2, double share) noexcept { return p + share * (p2 - p); }

/// Integral of exp(-sigma t) for t in [0, len]: (1 - e^{-sigma len}) / sigma, written with
/// expm1 (no cancellation for small sigma*len) and exactly len for sigma = 0.
inline double chord_integral(double sigma, double len) noexcept {
    const double x = sigma * len;
    if (x < 1e-12) return len * (1.0 - 0.5 * x);
    return -std::expm1(-x) / sigma;
}

}  // namespace fulgur::transport::detail
