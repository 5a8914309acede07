// A brute-force reference for the voxel-averaged single scattering of a point source
// (transport.h, single_scattering_reference): no error model, no choice of rules, nothing
// shared with quadrature.cpp but the phase function and the DDA transmittance (which
// test_traversal checks against sorted plane crossings). The voxel is cut into equal cells;
// every cell gets the same 3-point Gauss-Legendre tensor rule, and cells close to the light
// (where 1/r^2 and the phase function's peak vary across a cell) are halved until they are
// far for their size. Shadow edges (kinks of the transmittance along planes through the
// light and an upstream voxel edge) are integrated by the cells' sheer number: the error of
// the cells a plane crosses falls as the cube of the cell size.
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace fulgur::transport {

namespace {

// 3-point Gauss-Legendre on [0, 1]: nodes (1 -+ sqrt(3/5)) / 2 and 1/2, weights 5/18, 8/18.
constexpr double kRoot = 0.7745966692414834;  // sqrt(3 / 5)
constexpr std::array<double, 3> kNode{0.5 * (1.0 - kRoot), 0.5, 0.5 * (1.0 + kRoot)};
constexpr std::array<double, 3> kWeight{5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};

struct ReferenceCtx {
    const LightingMedium& medium;
    glm::dvec3 light;
    std::span<const glm::dvec3> directions;
    double g = 0.0;
    double near = 0.0;  // a cell closer to the light than near x its size is halved
    int max_depth = 0;
};

double box_distance(const glm::dvec3& lo, const glm::dvec3& hi, const glm::dvec3& p) {
    const glm::dvec3 q = glm::max(lo - p, glm::max(glm::dvec3(0.0), p - hi));
    return glm::length(q);
}

// Adds the integral over the cube [lo, lo + s] of p(s . rhat) T / r^2 to acc (per direction).
void integrate_cell(const ReferenceCtx& c, const glm::dvec3& lo, double s, int depth, std::vector<double>& acc) {
    if (depth < c.max_depth && box_distance(lo, lo + s, c.light) < c.near * s) {
        const double h = 0.5 * s;
        for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 2; ++j)
                for (int i = 0; i < 2; ++i) integrate_cell(c, lo + h * glm::dvec3(i, j, k), h, depth + 1, acc);
        return;
    }
    const double volume = s * s * s;
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
                const glm::dvec3 x = lo + s * glm::dvec3(kNode[i], kNode[j], kNode[k]);
                const glm::dvec3 r = x - c.light;
                const double r2 = glm::dot(r, r);
                if (!(r2 > 0.0)) continue;  // a node on the light: a set of measure zero
                const double w =
                    volume * kWeight[i] * kWeight[j] * kWeight[k] * transmittance(c.medium, c.light, x) / r2;
                if (w == 0.0) continue;
                const glm::dvec3 rhat = r / std::sqrt(r2);
                for (std::size_t d = 0; d < c.directions.size(); ++d)
                    acc[d] += w * hg_phase(glm::dot(c.directions[d], rhat), c.g);
            }
}

// Throws unless the medium is valid and has no second phase function, the voxel lies in its
// grid and cells is in [1, 256].
void check_arguments(const LightingMedium& medium, core::Int3 voxel, int cells) {
    validate_medium(medium);
    const core::GridGeometry& g = medium.density.geom;
    if (medium.phase_mix)
        throw core::Error("single_scattering_reference", "takes a medium without a second phase function");
    if (!(voxel.x >= 0 && voxel.y >= 0 && voxel.z >= 0 && voxel.x < g.dims.x && voxel.y < g.dims.y &&
          voxel.z < g.dims.z))
        throw core::Error("single_scattering_reference.voxel", "is outside the grid");
    if (cells < 1 || cells > 256)
        throw core::Error("single_scattering_reference.cells", "must be in [1, 256], got " + std::to_string(cells));
}

}  // namespace

std::vector<double> single_scattering_reference(const LightingMedium& medium, const PointSource& light,
                                                std::span<const glm::dvec3> directions, core::Int3 voxel, int cells) {
    check_arguments(medium, voxel, cells);
    const core::GridGeometry& g = medium.density.geom;
    // A 3-point rule on a cell of size s at distance d from the light errs by about
    // (s (1 + k_g) / d)^6 / 400 (the a-priori model of quadrature.cpp, k_g = 1.5 |g| / (1 - |g|)
    // the phase function's log-slope): d >= 2 (1 + k_g) s keeps a cell's error under 1e-4 of
    // its part. The cells left within that at the depth limit (1 / 2^14 of a cell) hold a share
    // of the voxel's integral about their size over the voxel's: under 1e-5 for cells >= 1/16.
    const double absg = std::min(std::abs(medium.optics.g), kMaxAbsG);
    const ReferenceCtx c{medium, light.position, directions, medium.optics.g, 2.0 * (1.0 + 1.5 * absg / (1.0 - absg)),
                         14};
    std::vector<double> acc(directions.size(), 0.0);
    const double s = g.voxel_size / cells;
    const glm::dvec3 lo = g.origin + glm::dvec3(voxel.x, voxel.y, voxel.z) * g.voxel_size;
    for (int k = 0; k < cells; ++k)
        for (int j = 0; j < cells; ++j)
            for (int i = 0; i < cells; ++i) integrate_cell(c, lo + s * glm::dvec3(i, j, k), s, 0, acc);
    const double volume = g.voxel_size * g.voxel_size * g.voxel_size;
    for (double& v : acc) v *= medium.optics.albedo * light.intensity / volume;
    return acc;
}

std::vector<double> single_scattering_reference(const LightingMedium& medium, const DirectionalSource& sun,
                                                std::span<const glm::dvec3> directions, core::Int3 voxel, int cells) {
    check_arguments(medium, voxel, cells);
    const core::GridGeometry& g = medium.density.geom;
    const double len = glm::length(sun.direction);
    if (!std::isfinite(len) || !(len > 0.0)) throw core::Error("sun.direction", "must be a finite non-zero vector");
    const glm::dvec3 d = sun.direction / len;
    // The phase function is one value per output direction: only the transmittance is averaged.
    const double s = g.voxel_size / cells;
    const glm::dvec3 lo = g.origin + glm::dvec3(voxel.x, voxel.y, voxel.z) * g.voxel_size;
    double mean_t = 0.0;
    for (int k = 0; k < cells; ++k)
        for (int j = 0; j < cells; ++j)
            for (int i = 0; i < cells; ++i)
                for (int c = 0; c < 3; ++c)
                    for (int b = 0; b < 3; ++b)
                        for (int a = 0; a < 3; ++a) {
                            const glm::dvec3 x =
                                lo + s * (glm::dvec3(i, j, k) + glm::dvec3(kNode[a], kNode[b], kNode[c]));
                            mean_t +=
                                kWeight[a] * kWeight[b] * kWeight[c] * std::exp(-optical_depth_to_sun(medium, x, d));
                        }
    mean_t /= double(cells) * cells * cells;
    std::vector<double> out(directions.size());
    for (std::size_t m = 0; m < directions.size(); ++m)
        out[m] = medium.optics.albedo * sun.irradiance * hg_phase(glm::dot(directions[m], d), medium.optics.g) * mean_t;
    return out;
}

}  // namespace fulgur::transport
