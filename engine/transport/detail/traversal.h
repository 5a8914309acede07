// Internal: exact voxel traversal (3D DDA, Amanatides & Woo 1987) through a voxel grid.
//
// Used by the transmittance, single-scattering and Monte Carlo code. A ray x(t) = o + t*d
// (d unit, t in metres) is clipped to the grid's box and walked voxel by voxel; each visit
// reports the voxel and the parameter interval [t_in, t_out] the ray spends in it. The
// intervals tile the clipped segment exactly (their lengths telescope), so a line integral
// of a piecewise-constant field is exact up to round-off.
//
// Conventions for degenerate rays (all documented behaviour, all tested):
//  * zero-length segments and rays that miss the box visit nothing;
//  * a ray starting exactly on a voxel face and leaving it in -axis direction starts in the
//    voxel on the - side (the one it actually enters);
//  * a ray running exactly *along* a face between two voxels (direction component 0 on a
//    face coordinate) samples the voxel on the + side of that face, except on the grid's
//    upper boundary face, where it samples the last (inside) voxel. The set of such rays has
//    measure zero; the convention only has to be deterministic;
//  * the box is closed: a ray grazing the box boundary visits the boundary voxels.
// Iterations are capped at nx + ny + nz + 3, which the walk can never legitimately exceed,
// so a NaN or pathological input can never loop forever.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace fulgur::transport::detail {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// Incremental DDA walker. After a successful start(), the current voxel is (i, j, k) /
/// `cell`, occupied for t in [t, t_next()]; advance() moves to the next voxel.
class DdaWalker {
public:
    int i = 0, j = 0, k = 0;
    std::ptrdiff_t cell = 0;
    double t = 0.0;      ///< entry parameter of the current voxel
    double t_end = 0.0;  ///< end of the clipped segment

    /// Starts a walk over o + t d, t in [t0, t1], d unit (or at least non-zero and finite).
    /// Returns false when the clipped segment is empty.
    bool start(const core::GridGeometry& g, const glm::dvec3& o, const glm::dvec3& d, double t0, double t1) noexcept {
        if (!(t1 > t0)) return false;
        if (!core::clip_ray_to_box(o, d, g.origin, g.upper(), t0, t1)) return false;
        return start_clipped(g, o, d, t0, t1);
    }

    /// start() for a segment the caller has clipped already to a box inside the grid's (a
    /// coarser grid over the same medium: delta tracking's majorant cells), t0 < t1: the
    /// second clip would return the same interval.
    bool start_clipped(const core::GridGeometry& g, const glm::dvec3& o, const glm::dvec3& d, double t0,
                       double t1) noexcept {
        n_[0] = g.dims.x;
        n_[1] = g.dims.y;
        n_[2] = g.dims.z;
        stride_[0] = 1;
        stride_[1] = g.dims.x;
        stride_[2] = std::ptrdiff_t(g.dims.x) * g.dims.y;
        const glm::dvec3 p = o + t0 * d;
        int idx[3];
        for (int a = 0; a < 3; ++a) {
            const double u = (p[a] - g.origin[a]) / g.voxel_size;
            double fl = std::floor(u);
            if (d[a] < 0.0 && u == fl) fl -= 1.0;  // on a face, moving down: the lower voxel
            idx[a] = int(std::clamp(fl, 0.0, double(n_[a] - 1)));
            if (d[a] > 0.0) {
                step_[a] = 1;
                inv_[a] = 1.0 / d[a];
                bound_[a] = g.origin[a] + double(idx[a] + 1) * g.voxel_size;
            } else if (d[a] < 0.0) {
                step_[a] = -1;
                inv_[a] = 1.0 / d[a];
                bound_[a] = g.origin[a] + double(idx[a]) * g.voxel_size;
            } else {
                step_[a] = 0;
                inv_[a] = 0.0;
                bound_[a] = 0.0;
            }
            o_[a] = o[a];
            h_step_[a] = double(step_[a]) * g.voxel_size;
            tmax_[a] = step_[a] == 0 ? kInf : (bound_[a] - o_[a]) * inv_[a];
        }
        i = idx[0];
        j = idx[1];
        k = idx[2];
        cell = std::ptrdiff_t(i) + stride_[1] * j + stride_[2] * k;
        t = t0;
        t_end = t1;
        left_ = n_[0] + n_[1] + n_[2] + 3;
        return true;
    }

    /// Exit parameter of the current voxel (clamped to the segment end, never below t).
    double t_next() const noexcept {
        const double m = std::min(std::min(tmax_[0], tmax_[1]), std::min(tmax_[2], t_end));
        return m > t ? m : t;
    }

    /// Moves to the next voxel. Returns false when the segment or the grid is exhausted.
    bool advance() noexcept {
        const double tn = t_next();
        if (tn >= t_end || --left_ <= 0) return false;
        const int a = (tmax_[0] <= tmax_[1]) ? (tmax_[0] <= tmax_[2] ? 0 : 2) : (tmax_[1] <= tmax_[2] ? 1 : 2);
        int* ip = a == 0 ? &i : (a == 1 ? &j : &k);
        *ip += step_[a];
        if (*ip < 0 || *ip >= n_[a]) return false;
        cell += step_[a] * stride_[a];
        bound_[a] += h_step_[a];
        tmax_[a] = (bound_[a] - o_[a]) * inv_[a];
        t = tn;
        return true;
    }

private:
    int n_[3] = {0, 0, 0};
    int step_[3] = {0, 0, 0};
    std::ptrdiff_t stride_[3] = {0, 0, 0};
    double inv_[3] = {0, 0, 0};
    double bound_[3] = {0, 0, 0};
    double h_step_[3] = {0, 0, 0};
    double o_[3] = {0, 0, 0};
    double tmax_[3] = {kInf, kInf, kInf};
    int left_ = 0;
};

/// Calls fn(cell, t_in, t_out) for every voxel the segment o + t d, t in [t0, t1] crosses,
/// in order. fn returns false to stop early.
template <class F>
inline void traverse(const core::GridGeometry& g, const glm::dvec3& o, const glm::dvec3& d, double t0, double t1,
                     F&& fn) {
    DdaWalker w;
    if (!w.start(g, o, d, t0, t1)) return;
    do {
        if (!fn(std::size_t(w.cell), w.t, w.t_next())) return;
    } while (w.advance());
}

/// Optical depth kappa * sum(rho_i * length_i) along o + t d, t in [t0, t1], clipped to the
/// box [lo, hi] (the grid's box, or a tighter box outside which the density is 0); stops
/// early (returning a value > cutoff) once the depth exceeds `cutoff`. Same traversal and
/// conventions as DdaWalker, written as one tight loop (the hot path of single scattering):
/// the stepping axis is selected without unpredictable branches.
inline double optical_depth_along(const core::GridGeometry& g, const float* density, double kappa, const glm::dvec3& o,
                                  const glm::dvec3& d, double t0, double t1, double cutoff, const glm::dvec3& lo,
                                  const glm::dvec3& hi) noexcept {
    if (!(t1 > t0) || !core::clip_ray_to_box(o, d, lo, hi, t0, t1)) return 0.0;
    const double h = g.voxel_size;
    const int n[3] = {g.dims.x, g.dims.y, g.dims.z};
    const std::ptrdiff_t stride[3] = {1, g.dims.x, std::ptrdiff_t(g.dims.x) * g.dims.y};
    int idx[3];
    double tmax[3], tdel[3];
    std::ptrdiff_t sstep[3];
    int step[3];
    for (int a = 0; a < 3; ++a) {
        const double u = (o[a] + t0 * d[a] - g.origin[a]) / h;
        double fl = std::floor(u);
        if (d[a] < 0.0 && u == fl) fl -= 1.0;
        idx[a] = int(std::clamp(fl, 0.0, double(n[a] - 1)));
        if (d[a] > 0.0) {
            step[a] = 1;
            tdel[a] = h / d[a];
            tmax[a] = (g.origin[a] + double(idx[a] + 1) * h - o[a]) / d[a];
        } else if (d[a] < 0.0) {
            step[a] = -1;
            tdel[a] = -h / d[a];
            tmax[a] = (g.origin[a] + double(idx[a]) * h - o[a]) / d[a];
        } else {
            step[a] = 0;
            tdel[a] = 0.0;
            tmax[a] = kInf;
        }
        sstep[a] = step[a] * stride[a];
    }
    std::ptrdiff_t cell = idx[0] + stride[1] * idx[1] + stride[2] * idx[2];
    const double rho_cutoff = kappa > 0.0 ? cutoff / kappa : kInf;
    double acc = 0.0, t = t0;
    double tx = tmax[0], ty = tmax[1], tz = tmax[2];
    int ix = idx[0], iy = idx[1], iz = idx[2];
    for (int left = n[0] + n[1] + n[2] + 3; left > 0; --left) {
        const bool bx = (tx <= ty) & (tx <= tz);
        const bool by = !bx & (ty <= tz);
        const bool bz = !bx & !by;
        double tn = bx ? tx : (by ? ty : tz);
        if (tn >= t1) {
            acc += double(density[cell]) * (t1 - t);
            break;
        }
        if (tn > t) {
            acc += double(density[cell]) * (tn - t);
            t = tn;
        }
        if (acc > rho_cutoff) break;
        tx = bx ? tx + tdel[0] : tx;
        ty = by ? ty + tdel[1] : ty;
        tz = bz ? tz + tdel[2] : tz;
        ix += bx ? step[0] : 0;
        iy += by ? step[1] : 0;
        iz += bz ? step[2] : 0;
        if ((unsigned(ix) >= unsigned(n[0])) | (unsigned(iy) >= unsigned(n[1])) | (unsigned(iz) >= unsigned(n[2])))
            break;
        cell += bx ? sstep[0] : (by ? sstep[1] : sstep[2]);
    }
    return kappa * acc;
}

/// Same over the whole grid box.
inline double optical_depth_along(const core::GridGeometry& g, const float* density, double kappa, const glm::dvec3& o,
                                  const glm::dvec3& d, double t0, double t1, double cutoff = kInf) noexcept {
    return optical_depth_along(g, density, kappa, o, d, t0, t1, cutoff, g.origin, g.upper());
}

}  // namespace fulgur::transport::detail
