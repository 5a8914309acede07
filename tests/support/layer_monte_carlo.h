// An independent estimate of the sun's light in an infinite homogeneous layer: the layer's own
// Monte Carlo in depth alone (no grid, no voxels across, no tally box, no code shared with the
// engine's tracer). Photons enter the top along the sun, fly exponential steps, keep albedo x
// their weight at each collision (Russian roulette below 0.1), scatter by Henyey-Greenstein.
// Optionally the density falls linearly to 0 over `ramp` metres centred on the top (what a
// trilinear read of voxels gives where the layer meets empty voxels above it: the same optical
// depth, spread over one voxel), sampled by delta tracking.
// Two estimates, order 1 and orders >= 2 apart, with standard errors from batches:
//  - S per layer and output direction: every flight adds its length in each layer times
//    p(s_m . d) (track-length estimate of integral p L dw), S = albedo x that / volume;
//  - the radiance leaving the top toward each view direction v (v.z > 0): every collision adds
//    the next-event estimate w albedo p(d . v) exp(-tau to the top / v.z) / v.z.
// Both per unit irradiance across the sun's beam.
#pragma once

#include "core/rng.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>
#include <glm/glm.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <span>
#include <vector>

namespace fulgur::test {

struct LayerEstimate {
    // [order 0: single, 1: multiple][layer from the bottom][direction]: mean and standard error
    std::array<std::vector<std::vector<double>>, 2> mean, se;
    // [order][view]: radiance leaving the top toward each view direction, and its standard error
    std::array<std::vector<double>, 2> radiance, radiance_se;
};

struct LayerSpec {
    double sigma = 0.01, albedo = 0.99, g = 0.0;  // extinction per metre, albedo, HG g
    double layer = 100.0;                         // thickness of one tally layer (m)
    int layers = 10;
    glm::dvec3 sun{0.0, 0.0, -1.0};  // the direction sunlight travels (unit, z < 0)
    double ramp = 0.0;               // width of the top's linear fall of density (m), 0: sharp
};

/// Density at height z of the layer [0, top] whose top falls linearly over `ramp`.
inline double layer_density(const LayerSpec& L, double z) {
    const double top = L.layer * L.layers, a = top - 0.5 * L.ramp, b = top + 0.5 * L.ramp;
    if (z < 0.0 || z > b) return 0.0;
    return z <= a ? 1.0 : (b - z) / L.ramp;
}

/// Optical depth per unit extinction from height z (inside) up through the top.
inline double layer_depth_above(const LayerSpec& L, double z) {
    const double top = L.layer * L.layers, a = top - 0.5 * L.ramp, b = top + 0.5 * L.ramp;
    if (z >= b) return 0.0;
    if (z >= a) return 0.5 * (b - z) * (b - z) / L.ramp;
    return (a - z) + 0.5 * L.ramp;
}

inline double layer_hg(double g, double mu) {
    return (1.0 - g * g) / (4.0 * std::numbers::pi * std::pow(1.0 + g * g - 2.0 * g * mu, 1.5));
}

inline glm::dvec3 layer_scatter(const glm::dvec3& d, double g, core::Rng& rng) {
    const double u = rng.uniform(), v = rng.uniform();
    double mu;
    if (std::fabs(g) < 1e-6) {
        mu = 1.0 - 2.0 * u;
    } else {
        const double q = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        mu = std::clamp((1.0 + g * g - q * q) / (2.0 * g), -1.0, 1.0);
    }
    const double st = std::sqrt(std::max(0.0, 1.0 - mu * mu)), phi = 2.0 * std::numbers::pi * v;
    const glm::dvec3 a = std::fabs(d.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
    const glm::dvec3 t = glm::normalize(glm::cross(a, d)), b = glm::cross(d, t);
    return glm::normalize(mu * d + st * (std::cos(phi) * t + std::sin(phi) * b));
}

/// The mean of a field's direction `m` over columns [lo, hi) x [lo, hi) of layer `k`: an
/// engine field read where the layer is the same in every column (far from its edges).
inline double middle_columns_mean(const transport::SourceField& f, std::size_t m, int k, int lo, int hi) {
    const core::GridGeometry& g = f.geom;
    double sum = 0.0;
    for (int j = lo; j < hi; ++j)
        for (int i = lo; i < hi; ++i) sum += f.data[m * g.cell_count() + g.index(i, j, k)];
    return sum / double((hi - lo) * (hi - lo));
}

/// `dirs`: output directions of S; `views`: directions toward a camera above the layer.
inline LayerEstimate layer_monte_carlo(const LayerSpec& L, std::span<const glm::dvec3> dirs,
                                       std::span<const glm::dvec3> views, int photons, int batches) {
    const std::size_t M = dirs.size(), V = views.size();
    const double top = L.layer * L.layers + 0.5 * L.ramp, mu0 = -L.sun.z;  // top: where density starts
    const std::size_t layers = std::size_t(L.layers);
    std::array<std::vector<double>, 2> sum, sum2, rsum, rsum2;  // [order][layer * M + m], [order][v]
    for (int o = 0; o < 2; ++o) {
        sum[o].assign(layers * M, 0.0);
        sum2[o] = sum[o];
        rsum[o].assign(V, 0.0);
        rsum2[o] = rsum[o];
    }
    core::Rng rng(20261201, 7);
    for (int b = 0; b < batches; ++b) {
        std::array<std::vector<double>, 2> acc, racc;
        for (int o = 0; o < 2; ++o) {
            acc[o].assign(layers * M, 0.0);
            racc[o].assign(V, 0.0);
        }
        for (int n = 0; n < photons; ++n) {
            double z = top, w = 1.0;
            glm::dvec3 d = L.sun;
            for (int k = 0;; ++k) {
                const double s = -std::log1p(-rng.uniform()) / L.sigma;
                double z1 = z + s * d.z;
                const bool leaves = z1 > top || z1 < 0.0;
                z1 = std::clamp(z1, 0.0, top);
                // Delta tracking through the ramp: a tentative collision is real with
                // probability density / 1 (drawn only where the density is below 1).
                const double rho = leaves ? 1.0 : layer_density(L, z1);
                const bool null_collision = rho < 1.0 && rng.uniform() >= rho;
                // The flight's length in each layer it crosses.
                const double lo = std::min(z, z1), hi = std::max(z, z1);
                std::vector<double>& a = acc[k == 0 ? 0 : 1];
                if (std::fabs(d.z) > 1e-12)
                    for (std::size_t l = std::size_t(std::max(0.0, std::floor(lo / L.layer)));
                         l < layers && double(l) * L.layer < hi; ++l) {
                        const double len = (std::min(hi, double(l + 1) * L.layer) - std::max(lo, double(l) * L.layer)) /
                                           std::fabs(d.z);
                        if (len <= 0.0) continue;
                        for (std::size_t m = 0; m < M; ++m)
                            a[l * M + m] += w * len * layer_hg(L.g, glm::dot(dirs[m], d));
                    }
                if (leaves) break;
                z = z1;
                if (null_collision) {  // same direction, same order
                    --k;
                    continue;
                }
                // The collision seen from above (order k + 1).
                for (std::size_t v = 0; v < V; ++v)
                    racc[k == 0 ? 0 : 1][v] += w * L.albedo * layer_hg(L.g, glm::dot(d, views[v])) *
                                               std::exp(-L.sigma * layer_depth_above(L, z) / views[v].z) / views[v].z;
                w *= L.albedo;
                if (w < 0.1) {
                    if (rng.uniform() < 0.5) break;
                    w *= 2.0;
                }
                d = layer_scatter(d, L.g, rng);
            }
        }
        // Per unit irradiance across the beam, E mu0 crosses the top per unit area.
        const double ks = L.albedo * mu0 / (double(photons) * L.layer), kr = mu0 / double(photons);
        for (int o = 0; o < 2; ++o) {
            for (std::size_t i = 0; i < acc[o].size(); ++i) {
                sum[o][i] += acc[o][i] * ks;
                sum2[o][i] += std::pow(acc[o][i] * ks, 2);
            }
            for (std::size_t v = 0; v < V; ++v) {
                rsum[o][v] += racc[o][v] * kr;
                rsum2[o][v] += std::pow(racc[o][v] * kr, 2);
            }
        }
    }
    const auto stats = [&](double s, double s2, double& mean, double& se) {
        mean = s / batches;
        se = std::sqrt(std::max(0.0, s2 / batches - mean * mean) / (batches - 1));
    };
    LayerEstimate out;
    for (int o = 0; o < 2; ++o) {
        out.mean[o].assign(layers, std::vector<double>(M, 0.0));
        out.se[o] = out.mean[o];
        for (std::size_t l = 0; l < layers; ++l)
            for (std::size_t m = 0; m < M; ++m)
                stats(sum[o][l * M + m], sum2[o][l * M + m], out.mean[o][l][m], out.se[o][l][m]);
        out.radiance[o].assign(V, 0.0);
        out.radiance_se[o] = out.radiance[o];
        for (std::size_t v = 0; v < V; ++v) stats(rsum[o][v], rsum2[o][v], out.radiance[o][v], out.radiance_se[o][v]);
    }
    return out;
}

}  // namespace fulgur::test
