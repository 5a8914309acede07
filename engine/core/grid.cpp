#include "core/core.h"

#include <algorithm>
#include <string>

namespace fulgur::core {

Int3 GridGeometry::unindex(std::size_t idx) const noexcept {
    const std::size_t nx = std::size_t(dims.x), ny = std::size_t(dims.y);
    return {int(idx % nx), int((idx / nx) % ny), int(idx / (nx * ny))};
}

bool GridGeometry::contains(const glm::dvec3& world) const noexcept {
    const glm::dvec3 hi = upper();
    return world.x >= origin.x && world.y >= origin.y && world.z >= origin.z && world.x < hi.x && world.y < hi.y &&
           world.z < hi.z;
}

void validate_geometry(const GridGeometry& g, std::string_view where) {
    const std::string w(where);
    constexpr int kMaxDim = 4096;  // keeps every index computation far from overflow
    auto dim_ok = [](int n) { return n >= 1 && n <= kMaxDim; };
    if (!dim_ok(g.dims.x) || !dim_ok(g.dims.y) || !dim_ok(g.dims.z))
        throw Error(w, "grid dimensions must be in [1, 4096], got " + std::to_string(g.dims.x) + "x" +
                           std::to_string(g.dims.y) + "x" + std::to_string(g.dims.z));
    if (g.cell_count() > (std::size_t(1) << 31))
        throw Error(w, "grid has " + std::to_string(g.cell_count()) + " cells; at most 2^31 are supported");
    if (!std::isfinite(g.voxel_size) || !(g.voxel_size > 0.0))
        throw Error(w, "voxel size must be a finite positive length in metres, got " + std::to_string(g.voxel_size));
    if (!std::isfinite(g.origin.x) || !std::isfinite(g.origin.y) || !std::isfinite(g.origin.z))
        throw Error(w, "grid origin must be finite");
}

Grid3<float> downsample(const Grid3<float>& src, int factor) {
    FULGUR_ASSERT(factor >= 1, "downsample factor must be >= 1");
    const Int3 s = src.dims();
    GridGeometry g;
    g.dims = {(s.x + factor - 1) / factor, (s.y + factor - 1) / factor, (s.z + factor - 1) / factor};
    g.voxel_size = src.geom.voxel_size * factor;
    g.origin = src.geom.origin;
    Grid3<float> dst(g);
    parallel_for(0, g.dims.z, [&](std::int64_t kk) {
        const int k = int(kk);
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                double sum = 0.0;
                int n = 0;
                for (int c = k * factor; c < std::min(s.z, (k + 1) * factor); ++c)
                    for (int b = j * factor; b < std::min(s.y, (j + 1) * factor); ++b)
                        for (int a = i * factor; a < std::min(s.x, (i + 1) * factor); ++a) {
                            sum += src.at(a, b, c);
                            ++n;
                        }
                dst.at(i, j, k) = float(sum / n);
            }
    });
    return dst;
}

}  // namespace fulgur::core
