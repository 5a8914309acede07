#include "render/detail/volume_prep.h"

#include <algorithm>
#include <cmath>

namespace fulgur::render::detail {

std::uint8_t quantize_density(float rho) noexcept {
    if (!(rho > 0.0f)) return 0;  // also NaN
    if (rho >= 1.0f) return 255;
    return std::uint8_t(std::lround(double(rho) * 255.0));
}

std::vector<std::uint8_t> chebyshev_distance(const std::vector<std::uint8_t>& occupied, const core::Int3& dims) {
    const int nx = dims.x, ny = dims.y, nz = dims.z;
    FULGUR_ASSERT(occupied.size() == dims.volume(), "chebyshev_distance: mask size != dims");
    std::vector<std::uint8_t> d(occupied.size());
    for (std::size_t i = 0; i < d.size(); ++i) d[i] = occupied[i] ? 0 : 255;
    auto idx = [&](int x, int y, int z) {
        return std::size_t(x) + std::size_t(nx) * (std::size_t(y) + std::size_t(ny) * std::size_t(z));
    };
    // Forward pass: neighbours preceding (x, y, z) in raster order; backward: following.
    for (int pass = 0; pass < 2; ++pass) {
        const int s = pass == 0 ? -1 : 1;
        for (int zi = 0; zi < nz; ++zi) {
            const int z = pass == 0 ? zi : nz - 1 - zi;
            for (int yi = 0; yi < ny; ++yi) {
                const int y = pass == 0 ? yi : ny - 1 - yi;
                for (int xi = 0; xi < nx; ++xi) {
                    const int x = pass == 0 ? xi : nx - 1 - xi;
                    int best = d[idx(x, y, z)];
                    if (best == 0) continue;
                    // The 13 neighbours on the already-visited side of (x, y, z).
                    for (int dz = 0; dz <= 1; ++dz)
                        for (int dy = (dz ? -1 : 0); dy <= 1; ++dy)
                            for (int dx = (dz || dy ? -1 : 1); dx <= 1; ++dx) {
                                const int qx = x + s * dx, qy = y + s * dy, qz = z + s * dz;
                                if (qx < 0 || qy < 0 || qz < 0 || qx >= nx || qy >= ny || qz >= nz) continue;
                                best = std::min(best, int(d[idx(qx, qy, qz)]) + 1);
                            }
                    d[idx(x, y, z)] = std::uint8_t(std::min(best, 255));
                }
            }
        }
    }
    return d;
}

}  // namespace fulgur::render::detail
