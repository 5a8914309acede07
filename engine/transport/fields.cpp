// Operations on S fields.
#include "transport/transport.h"

#include <algorithm>
#include <cmath>

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

SourceField block_spread(const SourceField& coarse, const core::GridGeometry& fine) {
    const int f = int(std::lround(coarse.geom.voxel_size / fine.voxel_size));
    FULGUR_ASSERT(f >= 1 && coarse.geom.origin == fine.origin, "block_spread: `coarse` must coarsen `fine`");
    SourceField out(fine, coarse.directions);
    for (std::size_t m = 0; m < coarse.directions.size(); ++m) {
        const std::span<const float> c = coarse.direction(m);
        const std::span<float> o = out.direction(m);
        for (int k = 0; k < fine.dims.z; ++k)
            for (int j = 0; j < fine.dims.y; ++j)
                for (int i = 0; i < fine.dims.x; ++i)
                    o[fine.index(i, j, k)] = c[coarse.geom.index(i / f, j / f, k / f)];
    }
    return out;
}

}  // namespace fulgur::transport
