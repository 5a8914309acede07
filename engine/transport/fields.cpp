// Operations on S fields.
#include "transport/transport.h"

#include <algorithm>

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

}  // namespace fulgur::transport
