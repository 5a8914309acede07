#include "core/core.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace fulgur::core {

Int3 GridGeometry::unindex(std::size_t idx) const noexcept {
    const std::size_t nx = std::size_t(dims.x), ny = std::size_t(dims.y);
    return {int(idx % nx), int((idx / nx) % ny), int(idx / (nx * ny))};
}

Int3 GridGeometry::clamped_voxel(const glm::dvec3& world) const noexcept {
    const glm::dvec3 v = to_voxel(world);
    return {std::clamp(int(std::floor(v.x)), 0, dims.x - 1), std::clamp(int(std::floor(v.y)), 0, dims.y - 1),
            std::clamp(int(std::floor(v.z)), 0, dims.z - 1)};
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

namespace {

// One axis of Grid3::sample: the two source indices and the weight of the second for each
// destination centre along that axis.
struct AxisTaps {
    std::vector<int> i0, i1;
    std::vector<double> f;
};

AxisTaps axis_taps(double from_origin, double from_voxel, int n, double to_origin, double to_voxel, int m) {
    AxisTaps t;
    t.i0.resize(std::size_t(m));
    t.i1.resize(std::size_t(m));
    t.f.resize(std::size_t(m));
    for (int d = 0; d < m; ++d) {
        const double world = to_origin + (double(d) + 0.5) * to_voxel;
        const double v = (world - from_origin) / from_voxel - 0.5;
        int a = 0, b = 0;
        double w = 0.0;
        if (!(v > 0.0)) {
            a = b = 0;
        } else if (v >= double(n - 1)) {
            a = b = n - 1;
        } else {
            a = int(v);
            b = a + 1;
            w = v - double(a);
        }
        t.i0[std::size_t(d)] = a;
        t.i1[std::size_t(d)] = b;
        t.f[std::size_t(d)] = w;
    }
    return t;
}

}  // namespace

void resample_trilinear(const GridGeometry& from, std::span<const float> src, const GridGeometry& to,
                        std::span<float> dst) {
    FULGUR_ASSERT(src.size() == from.cell_count() && dst.size() == to.cell_count(),
                  "resample_trilinear: field sizes must match their geometries");
    const Int3 n = from.dims, m = to.dims;
    const AxisTaps tx = axis_taps(from.origin.x, from.voxel_size, n.x, to.origin.x, to.voxel_size, m.x);
    const AxisTaps ty = axis_taps(from.origin.y, from.voxel_size, n.y, to.origin.y, to.voxel_size, m.y);
    const AxisTaps tz = axis_taps(from.origin.z, from.voxel_size, n.z, to.origin.z, to.voxel_size, m.z);
    const std::size_t sx = std::size_t(n.x), sxy = sx * std::size_t(n.y);
    parallel_for(0, m.z, [&](std::int64_t kk) {
        const std::size_t k = std::size_t(kk);
        // z: the destination slice's two source slices, mixed once (n.x x n.y, double).
        std::vector<double> slice(sxy), row(sx);
        const float* z0 = src.data() + std::size_t(tz.i0[k]) * sxy;
        const float* z1 = src.data() + std::size_t(tz.i1[k]) * sxy;
        const double fz = tz.f[k];
        for (std::size_t i = 0; i < sxy; ++i) slice[i] = double(z0[i]) + (double(z1[i]) - double(z0[i])) * fz;
        for (int j = 0; j < m.y; ++j) {
            // y: the destination row's two source rows.
            const double* y0 = slice.data() + std::size_t(ty.i0[std::size_t(j)]) * sx;
            const double* y1 = slice.data() + std::size_t(ty.i1[std::size_t(j)]) * sx;
            const double fy = ty.f[std::size_t(j)];
            for (std::size_t i = 0; i < sx; ++i) row[i] = y0[i] + (y1[i] - y0[i]) * fy;
            // x: each destination cell.
            float* out = dst.data() + to.index(0, j, int(k));
            for (int i = 0; i < m.x; ++i) {
                const double a = row[std::size_t(tx.i0[std::size_t(i)])], b = row[std::size_t(tx.i1[std::size_t(i)])];
                out[i] = float(a + (b - a) * tx.f[std::size_t(i)]);
            }
        }
    });
}

}  // namespace fulgur::core
