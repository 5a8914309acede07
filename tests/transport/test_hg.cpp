// Henyey-Greenstein phase function: normalization, mean cosine, extreme g, exact sampling.
#include "support/test_support.h"
#include "transport/detail/kernels.h"
#include "transport/transport.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

using namespace fulgur;
using transport::hg_phase;

namespace {

// integral over the sphere of p(mu) * f(mu) = 2 pi integral_{-1}^{1} p f dmu, computed in the
// variable s = ln(1 - mu) (the forward peak of width ~(1-g)^2 in 1 - mu becomes a smooth bump
// in s) plus s' = ln(1 + mu) for the backward peak of negative g: the interval is split at
// mu = 0 and each half uses composite Gauss-Legendre (8 points) over 200 panels in s, from
// 1 - mu = 1e-16 (the neglected sliver holds < p_max * 1e-16 < 1e-9).
template <class F>
double sphere_integral(double g, F f) {
    const auto gr = transport::detail::gauss_legendre(8);
    const double lo = std::log(1e-16), hi = 0.0;  // 1 - mu in [1e-16, 1] (mu in [0, 1))
    const int panels = 200;
    double sum = 0.0;
    for (int side = 0; side < 2; ++side) {  // side 0: mu >= 0 (v = 1 - mu); 1: mu < 0 (v = 1 + mu)
        for (int p = 0; p < panels; ++p) {
            const double a = lo + (hi - lo) * p / panels, b = lo + (hi - lo) * (p + 1) / panels;
            for (int q = 0; q < 8; ++q) {
                const double s = a + (b - a) * gr.x[std::size_t(q)];
                const double v = std::exp(s);
                const double mu = side == 0 ? 1.0 - v : v - 1.0;
                sum += (b - a) * gr.w[std::size_t(q)] * v * hg_phase(mu, g) * f(mu);
            }
        }
    }
    return 2.0 * std::numbers::pi * sum;
}

// HG cumulative distribution of mu, P(cos <= mu), from the closed form (independent of the
// sampler, which inverts it in a different, cancellation-free arrangement).
double hg_cdf(double mu, double g) {
    if (g == 0.0) return 0.5 * (mu + 1.0);
    return (1.0 - g * g) / (2.0 * g) * (1.0 / std::sqrt(1.0 + g * g - 2.0 * g * mu) - 1.0 / (1.0 + g));
}

// Upper 1% quantile of chi-square with k degrees of freedom (Wilson-Hilferty; accurate to
// ~1% for k >= 10, far below the margin any real sampling defect produces).
double chi2_critical_001(int k) {
    const double z = 2.3263478740408408;  // standard normal upper 1% point
    const double t = 2.0 / (9.0 * k);
    return k * std::pow(1.0 - t + z * std::sqrt(t), 3.0);
}

}  // namespace

TEST_CASE("HG integrates to 1 over the sphere and its mean cosine is g") {
    for (double g : {-0.9, -0.5, 0.0, 0.5, 0.9, 0.99}) {
        CAPTURE(g);
        const double norm = sphere_integral(g, [](double) { return 1.0; });
        const double mean_cos = sphere_integral(g, [](double mu) { return mu; });
        CHECK(std::fabs(norm - 1.0) < 1e-4);    // the required bound; the quadrature reaches ~1e-12
        CHECK(std::fabs(mean_cos - g) < 1e-3);  // the required bound
    }
}

TEST_CASE("HG stays finite for g = +-0.999 and +-1 (|g| clamped to kMaxAbsG)") {
    const double inf = std::numeric_limits<double>::infinity();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (double g : {0.999, -0.999, 1.0, -1.0, 1.5, -inf, inf, nan}) {
        CAPTURE(g);
        for (double mu : {-1.0, -0.999999, -0.5, 0.0, 0.5, 0.999999, 1.0, 1.0 + 1e-15, -1.0 - 1e-15}) {
            const double p = hg_phase(mu, g);
            CHECK(std::isfinite(p));
            CHECK(p > 0.0);
        }
        for (double u : {0.0, 1e-300, 0.25, 0.5, 0.75, 1.0 - 1e-16, 1.0}) {
            const double c = transport::hg_sample_cos(g, u);
            CHECK(std::isfinite(c));
            CHECK(c >= -1.0);
            CHECK(c <= 1.0);
        }
        for (const glm::dvec3 fwd :
             {glm::dvec3(0, 0, 1), glm::dvec3(0, 0, -1), glm::normalize(glm::dvec3(1, -2, 0.3))}) {
            const glm::dvec3 d = transport::hg_sample(fwd, g, 0.37, 0.81);
            CHECK(std::isfinite(d.x));
            CHECK(std::fabs(glm::length(d) - 1.0) < 1e-12);  // unit up to round-off
        }
    }
    // |g| >= 1 is clamped to kMaxAbsG: the documented behaviour (scene files reject |g| >= 1).
    // (round-off only: the call sites may be evaluated with different FMA contraction;
    // measured 2.5e-13 relative, 1e-12 bounds it)
    CHECK(hg_phase(0.3, 1.0) == test::rel(hg_phase(0.3, transport::kMaxAbsG), 1e-12));
    CHECK(hg_phase(0.3, -1.0) == test::rel(hg_phase(0.3, -transport::kMaxAbsG), 1e-12));
    // NaN g is treated as isotropic (never propagates NaN).
    CHECK(hg_phase(0.3, nan) == test::rel(1.0 / (4.0 * std::numbers::pi), 1e-15));
    // The clamped phase function is still normalized (1e-4: the required bound).
    CHECK(std::fabs(sphere_integral(1.0, [](double) { return 1.0; }) - 1.0) < 1e-4);
}

TEST_CASE("HG sampling passes a chi-square test at significance 0.01") {
    // 40 bins of equal probability under the closed-form CDF, found by bisection (not with
    // the sampler); 200000 samples per g with a fixed seed, so the test is deterministic.
    constexpr int kBins = 40;
    constexpr int kSamples = 200000;
    for (double g : {-0.9, -0.5, 0.0, 0.5, 0.9, 0.99}) {
        CAPTURE(g);
        std::vector<double> edges(kBins + 1);
        edges[0] = -1.0;
        edges[kBins] = 1.0;
        for (int b = 1; b < kBins; ++b) {
            double lo = -1.0, hi = 1.0;
            for (int it = 0; it < 200; ++it) {
                const double mid = 0.5 * (lo + hi);
                (hg_cdf(mid, g) < double(b) / kBins ? lo : hi) = mid;
            }
            edges[std::size_t(b)] = 0.5 * (lo + hi);
        }
        std::vector<int> count(kBins, 0);
        core::Rng rng(2024, 7);
        for (int s = 0; s < kSamples; ++s) {
            const double mu = transport::hg_sample_cos(g, rng.uniform());
            const auto it = std::upper_bound(edges.begin() + 1, edges.end() - 1, mu);
            ++count[std::size_t(it - (edges.begin() + 1))];
        }
        const double expected = double(kSamples) / kBins;
        double chi2 = 0.0;
        for (int c : count) chi2 += (c - expected) * (c - expected) / expected;
        CHECK(chi2 < chi2_critical_001(kBins - 1));
    }
}

TEST_CASE("HG sampling around an arbitrary axis has mean cosine g") {
    core::Rng rng(5, 1);
    for (double g : {-0.7, 0.0, 0.6, 0.95}) {
        for (const glm::dvec3 fwd :
             {glm::dvec3(0, 0, 1), glm::dvec3(0, 0, -1), glm::normalize(glm::dvec3(-0.3, 0.8, 0.1))}) {
            double sum = 0.0;
            const int n = 100000;
            for (int i = 0; i < n; ++i) {
                const double u1 = rng.uniform(), u2 = rng.uniform();
                sum += glm::dot(transport::hg_sample(fwd, g, u1, u2), fwd);
            }
            // SE of the mean cosine <= sqrt(1/n) = 0.0032; 0.015 is > 4.5 SE.
            CHECK(std::fabs(sum / n - g) < 0.015);
        }
    }
}

TEST_CASE("hg_from_above: the share of HG scattering that light from above provides") {
    using transport::hg_from_above;
    // Symmetry (the two hemispheres' shares sum to the whole phase function, 1) and its
    // centre, to 1e-8: the quadrature's error (below 1e-8 against the double sum below at
    // 8000 x 2048 cells) and rounding.
    for (const double g : {0.0, 0.3, 0.85, 0.95, -0.5})
        for (const double mu : {0.0, 0.1, 0.5, 0.9, 1.0}) {
            CHECK(hg_from_above(mu, g) + hg_from_above(-mu, g) == doctest::Approx(1.0).epsilon(1e-8));
            if (mu == 0.0 || g == 0.0) CHECK(hg_from_above(mu, g) == doctest::Approx(0.5).epsilon(1e-8));
        }
    // Straight down (mu = -1) the share is HG's forward hemisphere, P(cos > 0) = 1 - cdf(0).
    for (const double g : {0.85, 0.3, -0.5})
        CHECK(hg_from_above(-1.0, g) == doctest::Approx(1.0 - hg_cdf(0.0, g)).epsilon(1e-8));
    for (double mu = -1.0; mu < 1.0; mu += 0.125)  // the share falls as the direction turns up
        CHECK(hg_from_above(mu + 0.125, 0.85) < hg_from_above(mu, 0.85));
    // Against a brute-force double sum (no elliptic integral): the midpoint rule over the
    // incident zenith alpha (mu_i = -cos alpha, 1000 cells) and the azimuth (512 cells, exact
    // to rounding for a periodic integrand); its own error, from the same sum at 8x the
    // cells, is at most 1.2e-6 relative over these cases, so the bound is 3e-6.
    for (const double g : {0.85, 0.3, -0.5})
        for (const double mu : {-0.8, -0.3, 0.4, 0.9}) {
            const double s = std::sqrt(1.0 - mu * mu);
            constexpr int kZenith = 1000, kAzimuth = 512;
            double ref = 0.0, ref_cos = 0.0;  // the share, and weighted by the incident |cos|
            for (int i = 0; i < kZenith; ++i) {
                const double alpha = (i + 0.5) / kZenith * 0.5 * std::numbers::pi;
                for (int j = 0; j < kAzimuth; ++j) {
                    const double phi = (j + 0.5) / kAzimuth * 2.0 * std::numbers::pi;
                    const double p =
                        hg_phase(-std::cos(alpha) * mu + std::sin(alpha) * s * std::cos(phi), g) * std::sin(alpha);
                    ref += p;
                    ref_cos += p * std::cos(alpha);
                }
            }
            ref *= (0.5 * std::numbers::pi / kZenith) * (2.0 * std::numbers::pi / kAzimuth);
            ref_cos *= (0.5 * std::numbers::pi / kZenith) * (2.0 * std::numbers::pi / kAzimuth);
            CAPTURE(g);
            CAPTURE(mu);
            CHECK(hg_from_above(mu, g) == doctest::Approx(ref).epsilon(3e-6));
            CHECK(hg_from_above(mu, g, 1) == doctest::Approx(ref_cos).epsilon(3e-6));
        }
    // Out-of-range and NaN inputs: clamped, finite.
    CHECK(hg_from_above(5.0, 0.85) == hg_from_above(1.0, 0.85));
    CHECK(std::isfinite(hg_from_above(std::numeric_limits<double>::quiet_NaN(), 2.0)));
}
