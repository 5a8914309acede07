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
    if (!(g.voxel_size >= kMinVoxelSize && g.voxel_size <= kMaxVoxelSize))
        throw Error(w, "voxel size must be in [" + format_number(kMinVoxelSize) + ", " + format_number(kMaxVoxelSize) +
                           "] m, got " + format_number(g.voxel_size, 17));
    for (int a = 0; a < 3; ++a)
        if (!(std::fabs(g.origin[a]) <= kMaxOrigin))
            throw Error(w, "grid origin must be finite and within " + format_number(kMaxOrigin) + " m of 0, got " +
                               format_number(g.origin[a], 17));
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
