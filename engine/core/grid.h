// fulgur::core — dense 3D voxel grids with physical geometry (voxel size in metres, origin of the
// grid's lower corner), cell-centred trilinear sampling, and the ray-box clip the traversals share.
#pragma once

#include <glm/vec3.hpp>

#include <cstddef>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace fulgur::core {

struct Int3 {
    int x = 0, y = 0, z = 0;
    constexpr std::size_t volume() const noexcept { return std::size_t(x) * std::size_t(y) * std::size_t(z); }
    constexpr bool operator==(const Int3&) const = default;
};

/// Physical placement of a voxel grid. Voxel (i,j,k) covers
/// [origin + (i,j,k)*voxel_size, origin + (i+1,j+1,k+1)*voxel_size); its sample sits at the
/// centre. z is up. Units: metres.
struct GridGeometry {
    Int3 dims;
    double voxel_size = 1.0;
    glm::dvec3 origin{0.0};

    std::size_t cell_count() const noexcept { return dims.volume(); }
    std::size_t index(int i, int j, int k) const noexcept {
        return std::size_t(i) + std::size_t(dims.x) * (std::size_t(j) + std::size_t(dims.y) * std::size_t(k));
    }
    Int3 unindex(std::size_t idx) const noexcept;
    glm::dvec3 centre(int i, int j, int k) const noexcept { return origin + (glm::dvec3(i, j, k) + 0.5) * voxel_size; }
    glm::dvec3 extent() const noexcept { return glm::dvec3(dims.x, dims.y, dims.z) * voxel_size; }
    glm::dvec3 upper() const noexcept { return origin + extent(); }
    /// Continuous voxel coordinates: the centre of voxel i maps to i + 0.5.
    glm::dvec3 to_voxel(const glm::dvec3& world) const noexcept { return (world - origin) / voxel_size; }
    /// The voxel holding `world`, clamped to the grid (a point outside maps to the nearest voxel).
    Int3 clamped_voxel(const glm::dvec3& world) const noexcept;
    bool contains(const glm::dvec3& world) const noexcept;
    bool operator==(const GridGeometry&) const = default;
};

/// Dense 3D grid, x fastest. Values are samples at voxel centres.
template <class T>
struct Grid3 {
    GridGeometry geom;
    std::vector<T> data;

    Grid3() = default;
    explicit Grid3(const GridGeometry& g, T fill = T{}) : geom(g), data(g.cell_count(), fill) {}

    const Int3& dims() const noexcept { return geom.dims; }
    std::size_t size() const noexcept { return data.size(); }
    T& at(int i, int j, int k) noexcept { return data[geom.index(i, j, k)]; }
    const T& at(int i, int j, int k) const noexcept { return data[geom.index(i, j, k)]; }

    /// Trilinear interpolation between voxel centres at a world position, clamped to the
    /// outermost centres (constant extrapolation outside the grid).
    T sample(const glm::dvec3& world) const noexcept;
};

/// Clips the parameter interval [t0, t1] of the ray o + t d (d need not be unit) against the
/// closed box [lo, hi] by slabs. Returns false (t0, t1 then unspecified) when the clipped
/// interval is empty or a coordinate is NaN; an axis-parallel ray (a component of d exactly 0)
/// is handled without 0 * inf. Used by the voxel traversal, Monte Carlo and the renderer.
inline bool clip_ray_to_box(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi,
                            double& t0, double& t1) noexcept {
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (!(o[a] >= lo[a] && o[a] <= hi[a])) return false;  // also rejects NaN
            continue;
        }
        const double inv = 1.0 / d[a];
        double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
    }
    return t0 < t1;  // false for NaN too
}

/// Voxel sizes a grid may have, in metres: below a micrometre a voxel's volume and 1/r^2 near
/// a source leave double precision's comfortable range; above 1000 km no cloud is meant.
inline constexpr double kMinVoxelSize = 1e-6, kMaxVoxelSize = 1e6;
/// Largest |origin| coordinate of a grid, in metres.
inline constexpr double kMaxOrigin = 1e9;

/// Validates a geometry (dims in [1, 4096], voxel size in [kMinVoxelSize, kMaxVoxelSize],
/// |origin| <= kMaxOrigin); throws Error naming `where`.
void validate_geometry(const GridGeometry& g, std::string_view where);

/// Box-filter downsample by an integer factor per axis (dims must divide exactly, or the
/// trailing partial block averages only the voxels it has). Voxel size grows by `factor`.
Grid3<float> downsample(const Grid3<float>& src, int factor);

/// Writes into `dst` (to.cell_count() values) Grid3::sample of the field `src` (on `from`) at
/// every voxel centre of `to`: trilinear between `from`'s centres, constant outside them.
/// Separable (one pass per axis, each source slice and row interpolated once), so an upsample
/// costs a few operations per destination cell; equal to the point-wise sample up to float
/// rounding (tests/core/test_grid.cpp).
void resample_trilinear(const GridGeometry& from, std::span<const float> src, const GridGeometry& to,
                        std::span<float> dst);

// ---------------------------------------------------------------------------------------
// Template definitions

template <class T>
T Grid3<T>::sample(const glm::dvec3& world) const noexcept {
    const glm::dvec3 u = geom.to_voxel(world) - 0.5;
    const int nx = geom.dims.x, ny = geom.dims.y, nz = geom.dims.z;
    auto split = [](double v, int n, int& i0, int& i1, double& f) {
        if (!(v > 0.0)) {
            i0 = i1 = 0;
            f = 0.0;
            return;
        }  // also catches NaN
        if (v >= double(n - 1)) {
            i0 = i1 = n - 1;
            f = 0.0;
            return;
        }
        i0 = int(v);
        i1 = i0 + 1;
        f = v - double(i0);
    };
    int x0, x1, y0, y1, z0, z1;
    double fx, fy, fz;
    split(u.x, nx, x0, x1, fx);
    split(u.y, ny, y0, y1, fy);
    split(u.z, nz, z0, z1, fz);
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    const double c00 = lerp(double(at(x0, y0, z0)), double(at(x1, y0, z0)), fx);
    const double c10 = lerp(double(at(x0, y1, z0)), double(at(x1, y1, z0)), fx);
    const double c01 = lerp(double(at(x0, y0, z1)), double(at(x1, y0, z1)), fx);
    const double c11 = lerp(double(at(x0, y1, z1)), double(at(x1, y1, z1)), fx);
    return T(lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz));
}

}  // namespace fulgur::core
