#include "transport/lb_collision.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <string>

namespace fulgur::transport {

LbCollision parse_lb_collision(std::string_view s, std::string_view where) {
    if (s == "corrected") return LbCollision::Corrected;
    if (s == "published") return LbCollision::Published;
    throw core::Error(std::string(where), "expected \"corrected\" or \"published\", got \"" + std::string(s) + "\"");
}

LbAbsorption parse_lb_absorption(std::string_view s, std::string_view where) {
    if (s == "physical") return LbAbsorption::Physical;
    if (s == "conservative") return LbAbsorption::Conservative;
    throw core::Error(std::string(where), "expected \"physical\" or \"conservative\", got \"" + std::string(s) + "\"");
}

}  // namespace fulgur::transport

namespace fulgur::transport::lb {

double hg_kernel(double c, double g) noexcept {
    g = std::clamp(g, -kMaxAbsG, kMaxAbsG);
    c = std::clamp(c, -1.0, 1.0);
    const double d = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - c);
    return (1.0 - g * g) / (d * std::sqrt(d));
}

DiscretePhase published_phase(double g) {
    DiscretePhase ph;
    ph.g = g;
    ph.form = LbCollision::Published;
    for (int i = 1; i < kQ; ++i) {
        double mean = 0.0;
        for (int j = 1; j < kQ; ++j) mean += hg_kernel(cosine(i, j), g) / 18.0;
        for (int j = 1; j < kQ; ++j) ph.P[std::size_t(i)][std::size_t(j)] = weight(i) * hg_kernel(cosine(i, j), g) / mean;
    }
    return ph;
}

namespace {

// Class sums of the smooth part for one representative incoming direction per class:
// h[ci][cj] = sum_{i in class ci} w_i HG(n_i.n_j), m[ci][cj] the same times n_i.n_j.
struct ClassSums {
    double h[2][2], m[2][2];
};
ClassSums class_sums(double gf) {
    ClassSums s{};
    const int rep[2] = {1, 7};
    for (int cj = 0; cj < 2; ++cj)
        for (int i = 1; i < kQ; ++i) {
            const int ci = dir_class(i) == kAxis ? 0 : 1;
            const double c = cosine(i, rep[cj]);
            const double v = weight(i) * hg_kernel(c, gf);
            s.h[ci][cj] += v;
            s.m[ci][cj] += v * c;
        }
    return s;
}

struct CorrectedParams {
    double sA = 1, sD = 1, delta = 0, mean_axis = 0, mean_diag = 0, col_diag = 1;
};

// For a given smooth parameter gf: solve the axis column sum (s_A (s_A h_AA + s_D h_DA) = 1)
// and the delta-free combination of the diagonal column sum and mean cosine
// (s_D (s_A (h_AD - sg m_AD) + s_D (h_DD - sg m_DD)) = 1 - sg g) by a fixed point; the
// delta weight then closes the diagonal column sum.
CorrectedParams corrected_params(double gf, double g) {
    const ClassSums cs = class_sums(gf);
    const double sg = g >= 0.0 ? 1.0 : -1.0;
    CorrectedParams p;
    for (int it = 0; it < 400; ++it) {
        const double colA = p.sA * (p.sA * cs.h[0][0] + p.sD * cs.h[1][0]);
        p.sA /= std::sqrt(colA);
        const double q = p.sD * (p.sA * (cs.h[0][1] - sg * cs.m[0][1]) + p.sD * (cs.h[1][1] - sg * cs.m[1][1]));
        p.sD *= std::sqrt((1.0 - sg * g) / q);
    }
    p.mean_axis = p.sA * (p.sA * cs.m[0][0] + p.sD * cs.m[1][0]);
    p.delta = 1.0 - p.sD * (p.sA * cs.h[0][1] + p.sD * cs.h[1][1]);
    p.mean_diag = p.sD * (p.sA * cs.m[0][1] + p.sD * cs.m[1][1]) + sg * p.delta;
    return p;
}

}  // namespace

DiscretePhase corrected_phase(double g) {
    FULGUR_ASSERT(std::isfinite(g), "g must be finite");
    g = std::clamp(g, -0.999, 0.999);
    DiscretePhase ph;
    ph.g = g;
    ph.form = LbCollision::Corrected;
    // Bisection on the smooth HG parameter so that the axis class mean cosine equals g
    // (monotone in gf); the diagonal class is matched by the delta term.
    double lo = -kMaxAbsG, hi = kMaxAbsG;
    for (int it = 0; it < 80; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (corrected_params(mid, g).mean_axis < g) lo = mid;
        else hi = mid;
    }
    const double gf = 0.5 * (lo + hi);
    const CorrectedParams p = corrected_params(gf, g);
    ph.g_fit = gf;
    ph.scale_axis = p.sA;
    ph.scale_diag = p.sD;
    ph.delta_diag = p.delta;
    FULGUR_ASSERT(p.delta >= -1e-12, "corrected phase: the delta weight must be non-negative");
    for (int i = 1; i < kQ; ++i)
        for (int j = 1; j < kQ; ++j) {
            const double si = dir_class(i) == kAxis ? p.sA : p.sD;
            const double sj = dir_class(j) == kAxis ? p.sA : p.sD;
            double K = si * sj * hg_kernel(cosine(i, j), gf);
            if (dir_class(j) == kDiagonal) {
                const int target = g >= 0.0 ? j : opposite(j);
                if (i == target) K += std::max(0.0, p.delta) / weight(j);
            }
            ph.P[std::size_t(i)][std::size_t(j)] = weight(i) * K;
        }
    return ph;
}

DiscretePhase make_phase(LbCollision form, double g) {
    return form == LbCollision::Corrected ? corrected_phase(g) : published_phase(g);
}

SiteCoefficients site_coefficients(const Medium& optics, double voxel_size, double density) noexcept {
    SiteCoefficients c;
    const double rho = std::isfinite(density) ? std::max(0.0, density) : 0.0;
    c.sigma_t = optics.extinction * rho;
    c.albedo = std::clamp(optics.albedo, 0.0, 1.0);
    for (int k = 1; k <= 2; ++k) {
        const double l = voxel_size * std::sqrt(double(k));  // class 1: h, class 2: sqrt(2) h
        const double tau = c.sigma_t * l;
        c.hop[k] = l;
        c.extinction[k] = -std::expm1(-tau);  // 1 - exp(-tau), accurate for small tau
        c.track[k] = tau > 0.0 ? c.extinction[k] / c.sigma_t : l;
    }
    return c;
}

SiteCoefficients lattice_unit_coefficients(double sigma_t, double albedo) noexcept {
    SiteCoefficients c;
    c.sigma_t = std::clamp(sigma_t, 0.0, 1.0);
    c.albedo = std::clamp(albedo, 0.0, 1.0);
    for (int k = 1; k <= 2; ++k) {
        c.hop[k] = std::sqrt(double(k));
        c.extinction[k] = c.sigma_t;
        c.track[k] = c.hop[k];
    }
    return c;
}

Matrix19 collision_matrix(const DiscretePhase& phase, const SiteCoefficients& c, LbAbsorption absorption) {
    Matrix19 T{};
    const bool conservative = absorption == LbAbsorption::Conservative;
    for (int j = 1; j < kQ; ++j) {
        const double e = c.extinction[dir_class(j)];
        for (int i = 1; i < kQ; ++i)
            T[std::size_t(i)][std::size_t(j)] = (i == j ? 1.0 - e : 0.0) + c.albedo * e * phase.P[std::size_t(i)][std::size_t(j)];
        T[0][std::size_t(j)] = conservative ? (1.0 - c.albedo) * e : 0.0;
    }
    for (int i = 1; i < kQ; ++i) T[std::size_t(i)][0] = weight(i);  // rest density re-emitted isotropically
    T[0][0] = 0.0;
    return T;
}

FactoredPhase factor_phase(const DiscretePhase& phase, double a) {
    // Representative pairs (output i, input j) for each distinct value.
    auto P = [&](int i, int j) { return a * phase.P[std::size_t(i)][std::size_t(j)]; };
    // Every entry must equal its representative (cubic structure).
    auto key = [](int i, int j) { return (dir_class(i) - 1) * 2 * 5 + (dir_class(j) - 1) * 5 + (cdot(i, j) + 2); };
    double rep[20];
    bool have[20] = {};
    for (int i = 1; i < kQ; ++i)
        for (int j = 1; j < kQ; ++j) {
            const int k = key(i, j);
            if (!have[k]) {
                rep[k] = P(i, j);
                have[k] = true;
            } else {
                FULGUR_ASSERT(std::fabs(rep[k] - P(i, j)) <= 1e-12 * std::max(1.0, std::fabs(rep[k])),
                              "discrete phase must depend only on direction classes and c_i.c_j");
            }
        }
    FactoredPhase f{};
    // axis(+x)=1, -x=2, +y=3; diagonals: 7=(1,1,0), 8=(-1,-1,0), 11=(1,0,1), 9=(1,-1,0)
    double aa_same = P(1, 1), aa_opp = P(1, 2), aa_perp = P(1, 3);
    double ad_pos = P(1, 7), ad_zero = P(1, 15), ad_neg = P(1, 8);
    double da_pos = P(7, 1), da_zero = P(7, 5), da_neg = P(7, 2);
    double dd_same = P(7, 7), dd_opp = P(7, 8), dd_pos = P(7, 11), dd_zero = P(7, 9), dd_neg = P(7, 12);
    FULGUR_ASSERT(cdot(7, 11) == 1 && cdot(7, 9) == 0 && cdot(7, 12) == -1 && cdot(1, 15) == 0, "lattice table changed");
    // Column sums (double) of the exact values: axis column, diagonal column.
    const double colA = aa_same + aa_opp + 4 * aa_perp + 4 * (da_pos + da_zero + da_neg);
    const double colD = 2 * (ad_pos + ad_zero + ad_neg) + dd_same + dd_opp + 4 * dd_pos + 2 * dd_zero + 4 * dd_neg;
    f.aa_opp = float(aa_opp);
    f.aa_perp = float(aa_perp);
    f.ad_pos = float(ad_pos);
    f.ad_zero = float(ad_zero);
    f.ad_neg = float(ad_neg);
    f.da_pos = float(da_pos);
    f.da_zero = float(da_zero);
    f.da_neg = float(da_neg);
    f.dd_opp = float(dd_opp);
    f.dd_pos = float(dd_pos);
    f.dd_zero = float(dd_zero);
    f.dd_neg = float(dd_neg);
    // The "same" entries absorb the rounding of the others so that the float column sums
    // (evaluated exactly in double) match the double ones to the nearest float step.
    const double restA = double(f.aa_opp) + 4.0 * double(f.aa_perp) + 4.0 * (double(f.da_pos) + double(f.da_zero) + double(f.da_neg));
    const double restD = 2.0 * (double(f.ad_pos) + double(f.ad_zero) + double(f.ad_neg)) + double(f.dd_opp) + 4.0 * double(f.dd_pos) +
                         2.0 * double(f.dd_zero) + 4.0 * double(f.dd_neg);
    f.aa_same = float(colA - restA);
    f.dd_same = float(colD - restD);
    return f;
}

std::array<double, kQ> resolve_direction(const glm::dvec3& Lin) {
    std::array<double, kQ> f{};
    const double len = glm::length(Lin);
    FULGUR_ASSERT(std::isfinite(len) && len > 0.0, "light direction must be a finite non-zero vector");
    const glm::dvec3 L = Lin / len;
    std::array<int, kMoving> dirs;
    std::array<double, kQ> dp{};
    for (int i = 1; i < kQ; ++i) {
        const Velocity& c = kVelocity[std::size_t(i)];
        dp[std::size_t(i)] = (c.x * L.x + c.y * L.y + c.z * L.z) / hop_length(i);
        dirs[std::size_t(i - 1)] = i;
    }
    // Stable sort: ties keep table order, so the result is deterministic.
    std::stable_sort(dirs.begin(), dirs.end(), [&](int a, int b) { return dp[std::size_t(a)] > dp[std::size_t(b)]; });
    double intens = 1.0;
    for (int i : dirs) {
        if (intens < 1e-12) break;
        const double d = dp[std::size_t(i)];
        if (d <= 0.0) break;  // never reached for a unit L (positive dots sum to > 1); guards the pseudocode
        f[std::size_t(i)] = std::min(d, intens);
        intens -= d;
    }
    return f;
}

std::array<double, kQ> output_phase(const glm::dvec3& sin, double g) {
    const glm::dvec3 s = glm::normalize(sin);
    std::array<double, kQ> c{};
    for (int j = 1; j < kQ; ++j) {
        const Velocity& v = kVelocity[std::size_t(j)];
        c[std::size_t(j)] = (v.x * s.x + v.y * s.y + v.z * s.z) / hop_length(j);
    }
    const double sg = g >= 0.0 ? 1.0 : -1.0;
    // beta >= 0 tilts towards s for g >= 0 and away from it for g < 0; the exponent is <= 0.
    auto weights = [&](double gs, double beta, std::array<double, kQ>& q) {
        double Z = 0.0, m = 0.0;
        for (int j = 1; j < kQ; ++j) {
            q[std::size_t(j)] = hg_kernel(c[std::size_t(j)], gs) * std::exp(beta * (sg * c[std::size_t(j)] - 1.0));
            Z += weight(j) * q[std::size_t(j)];
            m += weight(j) * q[std::size_t(j)] * c[std::size_t(j)];
        }
        for (int j = 1; j < kQ; ++j) q[std::size_t(j)] /= 4.0 * std::numbers::pi * Z;
        return m / Z;
    };
    std::array<double, kQ> q{};
    // The discrete mean cosine is increasing in gs; bisection on gs. Between lattice
    // directions the HG family saturates (its g -> 1 limit is a power law, not a peak), so
    // if g is out of its reach an exponential tilt exp(beta s.n_j) sharpens it further
    // (up to the cosine of the nearest lattice direction, e.g. 0.816 for a cube corner).
    double lo = -kMaxAbsG, hi = kMaxAbsG;
    if (sg * weights(sg * kMaxAbsG, 0.0, q) < sg * g) {
        double blo = 0.0, bhi = 400.0;
        if (sg * weights(sg * kMaxAbsG, bhi, q) <= sg * g) return q;
        for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (blo + bhi);
            if (sg * weights(sg * kMaxAbsG, mid, q) < sg * g) blo = mid;
            else bhi = mid;
        }
        weights(sg * kMaxAbsG, 0.5 * (blo + bhi), q);
        return q;
    }
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (weights(mid, 0.0, q) < g) lo = mid;
        else hi = mid;
    }
    weights(0.5 * (lo + hi), 0.0, q);
    return q;
}

}  // namespace fulgur::transport::lb
