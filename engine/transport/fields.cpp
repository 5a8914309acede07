// Operations on S fields, and the ground tally's cells.
#include "transport/transport.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace fulgur::transport {

SourceField block_average(const SourceField& fine, int factor) {
    FULGUR_ASSERT(factor >= 1, "block_average: factor must be >= 1");
    if (factor == 1) return fine;
    core::Grid3<float> one(fine.geom);
    SourceField out;
    for (std::size_t m = 0; m < fine.directions.size(); ++m) {
        const std::span<const float> d = fine.direction(m);
        std::copy(d.begin(), d.end(), one.data.begin());
        const core::Grid3<float> c = core::downsample(one, factor);
        if (m == 0) out = SourceField(c.geom, fine.directions);
        std::copy(c.data.begin(), c.data.end(), out.direction(m).begin());
    }
    return out;
}

SourceField in_every_direction(const SourceField& one, std::span<const glm::dvec3> directions) {
    FULGUR_ASSERT(one.directions.size() == 1, "in_every_direction: a one-direction field");
    SourceField out(one.geom, std::vector<glm::dvec3>(directions.begin(), directions.end()));
    for (std::size_t m = 0; m < directions.size(); ++m)
        std::copy(one.data.begin(), one.data.end(), out.direction(m).begin());
    return out;
}

GroundTally ground_cells_around(const core::GridGeometry& lighting, double height, double margin, int max_side) {
    FULGUR_ASSERT(max_side >= 1 && max_side <= 4096 && margin >= 0.0, "ground_cells_around: bad max_side or margin");
    FULGUR_ASSERT(std::isfinite(lighting.voxel_size) && lighting.voxel_size > 0.0,
                  "ground_cells_around: the lighting grid has no voxel size");
    const glm::dvec3 span = lighting.extent() + 2.0 * margin;
    GroundTally g;
    g.height = height;
    g.cell = std::max(2.0 * lighting.voxel_size, std::max(span.x, span.y) / max_side);
    g.origin = glm::dvec2(lighting.origin.x, lighting.origin.y) - margin;
    g.nx = std::clamp(int(std::ceil(span.x / g.cell)), 1, max_side);
    g.ny = std::clamp(int(std::ceil(span.y / g.cell)), 1, max_side);
    return g;
}

void validate_ground_tally(const GroundTally& g, const std::string& where) {
    if (!std::isfinite(g.height) || std::abs(g.height) > 1e7)
        throw core::Error(where + ".height", "must be finite and within 1e7 m, got " + std::to_string(g.height));
    if (!std::isfinite(g.origin.x) || !std::isfinite(g.origin.y) || std::abs(g.origin.x) > 1e9 ||
        std::abs(g.origin.y) > 1e9)
        throw core::Error(where + ".origin", "must be finite and within 1e9 m");
    if (!std::isfinite(g.cell) || !(g.cell >= 1e-3) || g.cell > 1e6)
        throw core::Error(where + ".cell", "must be in [1e-3, 1e6] m, got " + std::to_string(g.cell));
    if (g.nx < 1 || g.nx > 4096) throw core::Error(where + ".nx", "must be in [1, 4096], got " + std::to_string(g.nx));
    if (g.ny < 1 || g.ny > 4096) throw core::Error(where + ".ny", "must be in [1, 4096], got " + std::to_string(g.ny));
    if (g.cells() > (std::size_t(1) << 22))
        throw core::Error(where, "at most 2^22 cells, got " + std::to_string(g.cells()));
}

double GroundIrradiance::power() const noexcept {
    core::CompensatedSum s;
    for (const float v : data) s.add(double(v));
    return s.value() * cells.cell * cells.cell;
}

}  // namespace fulgur::transport
