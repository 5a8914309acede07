// The ground's irradiance from its dome (ground_dome.h): cosine-weighted rays from each cell's
// centre, walked voxel by voxel through the medium, each gathering the scattered radiance of
// every group and the transmittance its skies are seen through.
#include "transport/ground_dome.h"

#include "core/error.h"
#include "core/parallel.h"
#include "transport/detail/traversal.h"
#include "transport/directions.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace fulgur::transport {

namespace {

/// Checks groups of fields: at least one group, each non-empty, every field
/// non-null, on the medium's grid, with one common set of 1, 6, 18 or 26 directions and cells
/// x directions values, and S finite wherever the medium scatters (its sum over each group's
/// fields). Returns the number of directions.
std::size_t check_field_groups(const LightingMedium& medium, std::span<const std::vector<const SourceField*>> groups) {
    const std::string who = "ground_dome";
    if (groups.empty()) throw core::Error(who + ".groups", "no group of fields");
    const core::GridGeometry& g = medium.density.geom;
    std::size_t nd = 0;
    for (std::size_t q = 0; q < groups.size(); ++q) {
        if (groups[q].empty()) throw core::Error(who + ".groups[" + std::to_string(q) + "]", "no source field");
        for (std::size_t f = 0; f < groups[q].size(); ++f) {
            const SourceField* field = groups[q][f];
            const std::string name = who + ".groups[" + std::to_string(q) + "][" + std::to_string(f) + "]";
            if (!field) throw core::Error(name, "null");
            if (nd == 0) nd = field->directions.size();
            if (field->geom != g) throw core::Error(name, "is not on the medium's grid");
            if (field->directions.size() != nd || (nd != 1 && nd != 6 && nd != 18 && nd != 26))
                throw core::Error(name, "has " + std::to_string(field->directions.size()) +
                                            " directions; every field needs the same 1, 6, 18 or 26");
            if (field->data.size() != g.cell_count() * nd)
                throw core::Error(name,
                                  "holds " + std::to_string(field->data.size()) + " values, not cells x directions");
        }
    }
    for (std::size_t c = 0; c < g.cell_count(); ++c) {
        if (!(medium.sigma_t(c) > 0.0)) continue;
        for (std::size_t q = 0; q < groups.size(); ++q)
            for (std::size_t m = 0; m < nd; ++m) {
                double v = 0.0;
                for (const SourceField* f : groups[q]) v += double(f->direction(m)[c]);
                if (!std::isfinite(v))
                    throw core::Error(
                        who + ".groups[" + std::to_string(q) + "]",
                        "S is not finite at voxel " + std::to_string(c) + ", direction " + std::to_string(m));
            }
    }
    return nd;
}

/// Below this transmittance a ray stops: what lies behind can add at most this fraction of
/// the largest radiance on the ray.
constexpr double kMinTransmittance = 1e-7;

/// `n` directions over the upper hemisphere with density cos(theta) / pi: the points of a
/// Fibonacci spiral in the unit disc (equal areas) lifted onto the hemisphere (Malley's
/// method), so an irradiance is pi times the mean radiance over them.
std::vector<glm::dvec3> cosine_dome(int n) {
    std::vector<glm::dvec3> out(static_cast<std::size_t>(n));
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (int k = 0; k < n; ++k) {
        const double r2 = (k + 0.5) / n, r = std::sqrt(r2), phi = golden_angle * k;
        out[std::size_t(k)] = {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1.0 - r2))};
    }
    return out;
}

/// `n` directions over the upper hemisphere with uniform density 1 / (2 pi): a Fibonacci
/// spiral with z at the midpoints of n equal steps in [0, 1] (equal solid angles), so an
/// integral of f over the hemisphere is 2 pi times the mean of f over them.
std::vector<glm::dvec3> uniform_dome(int n) {
    std::vector<glm::dvec3> out(static_cast<std::size_t>(n));
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (int k = 0; k < n; ++k) {
        const double z = (k + 0.5) / n, r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = golden_angle * k;
        out[std::size_t(k)] = {r * std::cos(phi), r * std::sin(phi), z};
    }
    return out;
}

}  // namespace

DomeGround ground_dome(const LightingMedium& medium, std::span<const std::vector<const SourceField*>> groups,
                       std::span<const DomeProfile> skies, const GroundTally& cells, const DomeGroundOptions& options) {
    validate_medium(medium);
    validate_ground_tally(cells, "ground_dome.cells");
    if (options.rays < 16 || options.rays > 65536)
        throw core::Error("ground_dome.rays", "must be in [16, 65536], got " + std::to_string(options.rays));
    if (options.points_per_side < 1 || options.points_per_side > 16)
        throw core::Error("ground_dome.points_per_side",
                          "must be in [1, 16], got " + std::to_string(options.points_per_side));
    const int n = options.points_per_side;
    const std::size_t ng = groups.size();
    const std::size_t nd = ng > 0 ? check_field_groups(medium, groups) : 1;
    const std::size_t nk = skies.size();
    if (ng == 0 && nk == 0) throw core::Error("ground_dome", "neither a group of fields nor a sky to gather");
    // Cosine-weighted rays for the irradiance; with a lobe, rays of equal solid angle (a lobe
    // toward a horizontal viewer peaks at the horizon, where cosine-weighted rays are sparse).
    const std::vector<glm::dvec3> dome = options.lobe ? uniform_dome(options.rays) : cosine_dome(options.rays);
    // Each sky's radiance per ray, checked once.
    std::vector<double> sky(nk * dome.size());
    for (std::size_t k = 0; k < nk; ++k) {
        if (!skies[k]) throw core::Error("ground_dome.skies[" + std::to_string(k) + "]", "empty");
        for (std::size_t r = 0; r < dome.size(); ++r) {
            const double v = skies[k](dome[r].z);
            if (!std::isfinite(v) || v < 0.0)
                throw core::Error("ground_dome.skies[" + std::to_string(k) + "]",
                                  "radiance " + std::to_string(v) + " at sin(elevation) " + std::to_string(dome[r].z) +
                                      ": must be finite and >= 0");
            sky[k * dome.size() + r] = v;
        }
    }
    // Each ray's weight over the common pi / rays: 1 for the irradiance (cosine-weighted
    // rays), 2 lobe(w) with a lobe (rays of equal solid angle, 2 pi / rays each).
    std::vector<double> ray_weight(dome.size(), 1.0);
    if (options.lobe)
        for (std::size_t r = 0; r < dome.size(); ++r) {
            const double v = options.lobe(dome[r]);
            if (!std::isfinite(v) || v < 0.0)
                throw core::Error("ground_dome.lobe", "value " + std::to_string(v) + " at sin(elevation) " +
                                                          std::to_string(dome[r].z) + ": must be finite and >= 0");
            ray_weight[r] = 2.0 * v;
        }
    // The box of the voxels that attenuate: outside it the medium is empty.
    const core::GridGeometry& g = medium.density.geom;
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i)
                if (medium.sigma_t(g.index(i, j, k)) > 0.0) {
                    lo = glm::min(lo, g.origin + g.voxel_size * glm::dvec3(i, j, k));
                    hi = glm::max(hi, g.origin + g.voxel_size * glm::dvec3(i + 1, j + 1, k + 1));
                }
    // Work bound: a ray crosses at most the sum of the cloud box's sides in voxels (~1e8 visits
    // a second on one core).
    const glm::dvec3 box = lo.x <= hi.x ? (hi - lo) / g.voxel_size : glm::dvec3(0.0);
    const double visits = double(cells.cells()) * double(n * n) * double(dome.size()) * (box.x + box.y + box.z + 3.0);
    if (visits > double(std::uint64_t(1) << 33))
        throw core::Error("ground_dome", "could visit " + std::to_string(visits) +
                                             " voxels (at most 2^33): coarser cells or fewer rays");
    // Each ray's direction weights (S toward the ground is S along -direction).
    std::vector<DirectionWeights> weights;
    weights.reserve(dome.size());
    for (const glm::dvec3& w : dome) weights.push_back(direction_weights(-w, int(nd)));

    DomeGround out;
    out.groups.resize(ng);
    out.skies.resize(nk);
    for (std::vector<GroundIrradiance>* o : {&out.groups, &out.skies})
        for (GroundIrradiance& e : *o) {
            e.cells = cells;
            e.data.assign(cells.cells(), 0.0f);
        }
    // Each group's fields summed once (a group of one field is read in place): a ray then
    // reads one value per direction at each voxel it crosses where it read one per field.
    std::vector<SourceField> sums;
    sums.reserve(ng);  // no reallocation: field_of points into it
    std::vector<const SourceField*> field_of(ng);
    for (std::size_t q = 0; q < ng; ++q) {
        if (groups[q].size() == 1) {
            field_of[q] = groups[q][0];
            continue;
        }
        SourceField& sum = sums.emplace_back(*groups[q][0]);
        for (std::size_t f = 1; f < groups[q].size(); ++f) {
            const std::vector<float>& d = groups[q][f]->data;
            for (std::size_t i = 0; i < d.size(); ++i) sum.data[i] += d[i];
        }
        field_of[q] = &sum;
    }
    const bool any_cloud = lo.x <= hi.x;
    const bool centre = options.within == DomeGroundOptions::Within::Centre;
    const double weight = std::numbers::pi / double(dome.size() * std::size_t(n * n));
    core::parallel_for(0, std::int64_t(cells.cells()), [&](std::int64_t idx) {
        const int ci = int(idx % cells.nx), cj = int(idx / cells.nx);
        std::vector<double> e_group(ng, 0.0), e_sky(nk, 0.0), l(ng);
        for (int pr = 0; pr < n * n; ++pr) {
            const glm::dvec3 p(cells.origin.x + (ci + (pr % n + 0.5) / n) * cells.cell,
                               cells.origin.y + (cj + (pr / n + 0.5) / n) * cells.cell, cells.height);
            for (std::size_t r = 0; r < dome.size(); ++r) {
                const glm::dvec3& w = dome[r];
                std::fill(l.begin(), l.end(), 0.0);
                double T = 1.0;
                double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
                if (any_cloud && core::clip_ray_to_box(p, w, lo, hi, t0, t1)) {
                    const DirectionWeights& dw = weights[r];
                    detail::traverse(g, p, w, t0, t1, [&](std::size_t c, double a, double b) {
                        const double st = medium.sigma_t(c);
                        if (!(st > 0.0)) return true;
                        const double absorbed = -std::expm1(-st * (b - a));  // 1 - exp(-sigma l)
                        const double emitted = centre ? st * (b - a) * std::exp(-0.5 * st * (b - a)) : absorbed;
                        for (std::size_t q = 0; q < ng; ++q) {
                            double s = 0.0;
                            for (int t = 0; t < dw.count; ++t)
                                s += dw.weight[std::size_t(t)] *
                                     double(field_of[q]->direction(std::size_t(dw.index[std::size_t(t)]))[c]);
                            l[q] += T * emitted * s;
                        }
                        T *= 1.0 - absorbed;
                        return T > kMinTransmittance;
                    });
                }
                for (std::size_t q = 0; q < ng; ++q) e_group[q] += ray_weight[r] * l[q];
                for (std::size_t k = 0; k < nk; ++k) e_sky[k] += ray_weight[r] * T * sky[k * dome.size() + r];
            }
        }
        for (std::size_t q = 0; q < ng; ++q) out.groups[q].data[std::size_t(idx)] = float(weight * e_group[q]);
        for (std::size_t k = 0; k < nk; ++k) out.skies[k].data[std::size_t(idx)] = float(weight * e_sky[k]);
    });
    return out;
}

}  // namespace fulgur::transport
