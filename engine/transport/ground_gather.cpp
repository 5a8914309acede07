// The ground irradiance gathered from S (ground_gather.h): a sum over the medium's voxels
// for each of a cell's points, with exact transmittance through the voxels (optical_depth)
// and voxels near a point split into sub-voxels.
#include "transport/ground_gather.h"

#include "core/error.h"
#include "core/parallel.h"
#include "transport/directions.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace fulgur::transport {

namespace {

/// A voxel that scatters light: its centre and sigma_t V (S per direction beside).
struct Emitter {
    glm::dvec3 centre;
    double sigma_v = 0.0;
};

}  // namespace

std::vector<GroundIrradiance> gather_ground(const LightingMedium& medium,
                                            std::span<const std::vector<const SourceField*>> groups,
                                            const GroundTally& cells, const GroundGatherOptions& options) {
    validate_medium(medium);
    validate_ground_tally(cells, "gather_ground.cells");
    if (options.points_per_side < 1 || options.points_per_side > 16)
        throw core::Error("gather_ground.points_per_side",
                          "must be in [1, 16], got " + std::to_string(options.points_per_side));
    if (!std::isfinite(options.near_voxels) || options.near_voxels < 0.0 || options.near_voxels > 64.0)
        throw core::Error("gather_ground.near_voxels", "must be in [0, 64]");
    if (groups.empty()) throw core::Error("gather_ground.groups", "no group of fields");
    const core::GridGeometry& g = medium.density.geom;
    const std::size_t ng = groups.size();
    std::size_t nd = 0;
    for (std::size_t q = 0; q < ng; ++q) {
        if (groups[q].empty()) throw core::Error("gather_ground.groups[" + std::to_string(q) + "]", "no source field");
        for (std::size_t f = 0; f < groups[q].size(); ++f) {
            const SourceField* field = groups[q][f];
            const std::string name = "gather_ground.groups[" + std::to_string(q) + "][" + std::to_string(f) + "]";
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

    // The voxels that scatter, and S summed over each group's fields per voxel and direction;
    // and the box of the voxels that attenuate: outside it the medium is empty, so each
    // traversal is clipped to it first (the same optical depth, fewer empty voxels walked).
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    std::vector<Emitter> emitters;
    std::vector<double> s;  // [(emitter * ng + group) * nd + m]
    std::vector<double> here(ng * nd);
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const std::size_t c = g.index(i, j, k);
                const double st = medium.sigma_t(c);
                if (!(st > 0.0)) continue;
                lo = glm::min(lo, g.origin + g.voxel_size * glm::dvec3(i, j, k));
                hi = glm::max(hi, g.origin + g.voxel_size * glm::dvec3(i + 1, j + 1, k + 1));
                double any = 0.0;
                for (std::size_t q = 0; q < ng; ++q)
                    for (std::size_t m = 0; m < nd; ++m) {
                        double v = 0.0;
                        for (const SourceField* f : groups[q]) v += double(f->direction(m)[c]);
                        if (!std::isfinite(v))
                            throw core::Error(
                                "gather_ground.groups[" + std::to_string(q) + "]",
                                "S is not finite at voxel " + std::to_string(c) + ", direction " + std::to_string(m));
                        here[q * nd + m] = v;
                        any += std::abs(v);
                    }
                if (!(any > 0.0)) continue;
                s.insert(s.end(), here.begin(), here.end());
                emitters.push_back({g.centre(i, j, k), st * vol});
            }

    const auto through = [&](const glm::dvec3& x, const glm::dvec3& p) {
        double t0 = 0.0, t1 = 1.0;
        if (!core::clip_ray_to_box(x, p - x, lo, hi, t0, t1)) return 1.0;
        return transmittance(medium, x + t0 * (p - x), x + t1 * (p - x));
    };

    const int n = options.points_per_side;
    const double pairs = double(emitters.size()) * double(cells.cells()) * double(n) * double(n);
    if (pairs > double(std::uint64_t(1) << 32))
        throw core::Error("gather_ground", "would sum " + std::to_string(pairs) +
                                               " voxel-point pairs (at most 2^32): coarser cells or fewer points");

    std::vector<GroundIrradiance> out(ng);
    for (GroundIrradiance& o : out) {
        o.cells = cells;
        o.data.assign(cells.cells(), 0.0f);
    }
    const double h = g.voxel_size;
    core::parallel_for(0, std::int64_t(cells.cells()), [&](std::int64_t idx) {
        const int ci = int(idx % cells.nx), cj = int(idx / cells.nx);
        std::vector<double> cell_sum(ng, 0.0), sv(ng);
        for (int b = 0; b < n; ++b)
            for (int a = 0; a < n; ++a) {
                const glm::dvec3 p(cells.origin.x + (ci + (a + 0.5) / n) * cells.cell,
                                   cells.origin.y + (cj + (b + 0.5) / n) * cells.cell, cells.height);
                for (std::size_t v = 0; v < emitters.size(); ++v) {
                    const Emitter& em = emitters[v];
                    const glm::dvec3 l = em.centre - p;
                    if (!(l.z > 0.0)) continue;  // at or under the plane
                    const double r = glm::length(l);
                    const DirectionWeights w = direction_weights(-l, int(nd));
                    bool any = false;
                    for (std::size_t q = 0; q < ng; ++q) {
                        const double* sq = s.data() + (v * ng + q) * nd;
                        double x = 0.0;
                        for (int t = 0; t < w.count; ++t)
                            x += w.weight[std::size_t(t)] * sq[std::size_t(w.index[std::size_t(t)])];
                        sv[q] = x;
                        any = any || x != 0.0;
                    }
                    if (!any) continue;
                    const int split =
                        r < options.near_voxels * h ? std::min(4, int(std::ceil(options.near_voxels * h / r))) : 1;
                    double geometry = 0.0;  // transmittance x cos / r^2, over the voxel's points
                    if (split <= 1) {
                        geometry = through(em.centre, p) * (l.z / r) / (r * r);
                    } else {
                        // Sub-voxels of equal volume at their own centres, each with its own
                        // traversal (sharing the centre's outside the voxel was 3 points of L2
                        // worse on the storm for no saving at one point a cell).
                        for (int sk = 0; sk < split; ++sk)
                            for (int sj = 0; sj < split; ++sj)
                                for (int si = 0; si < split; ++si) {
                                    const glm::dvec3 x =
                                        em.centre + h * glm::dvec3((si + 0.5) / split - 0.5, (sj + 0.5) / split - 0.5,
                                                                   (sk + 0.5) / split - 0.5);
                                    const glm::dvec3 ls = x - p;
                                    if (!(ls.z > 0.0)) continue;
                                    const double rs2 = glm::dot(ls, ls);
                                    geometry += through(x, p) * (ls.z / std::sqrt(rs2)) / rs2;
                                }
                        geometry /= double(split * split * split);
                    }
                    for (std::size_t q = 0; q < ng; ++q) cell_sum[q] += em.sigma_v * sv[q] * geometry;
                }
            }
        for (std::size_t q = 0; q < ng; ++q) out[q].data[std::size_t(idx)] = float(cell_sum[q] / double(n * n));
    });
    return out;
}

GroundIrradiance gather_ground(const LightingMedium& medium, std::span<const SourceField* const> fields,
                               const GroundTally& cells, const GroundGatherOptions& options) {
    if (fields.empty()) throw core::Error("gather_ground.fields", "no source field");
    const std::vector<const SourceField*> one(fields.begin(), fields.end());
    try {
        return std::move(gather_ground(medium, std::span(&one, 1), cells, options)[0]);
    } catch (const core::Error& e) {
        // One group: name its fields as the caller passed them.
        std::string where = e.where();
        const std::string prefix = "gather_ground.groups[0][";
        if (where.rfind(prefix, 0) == 0) where = "gather_ground.fields[" + where.substr(prefix.size());
        throw core::Error(where, e.reason());
    }
}

}  // namespace fulgur::transport
