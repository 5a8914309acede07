// Orthonormal 3D Haar transform for any grid size: the non-standard or standard
// decomposition of the "unbalanced" 1D Haar (basis/haar.h and docs/basis.md), computed as inverse = U P and
// forward = P U^T where P is a diagonal scaling by powers of k = 1/sqrt(2) and U runs the
// levels with sums and differences (no per-level multiplication, hence no per-level
// accumulation of the rounding of k in float32).
//
// Derivation of the constants. The orthonormal inverse level l (l = 1 finest .. J coarsest)
// maps (a_i, d_i) to (x_2i, x_2i+1) = k (a + d, a - d) for regular pairs, (c a + s d,
// s a - c d) for the last pair when m is even (c, s from the sample counts of the two
// nodes), and passes the last approximation through when m is odd. Run it on scaled
// values: at the input of level l every approximation node but the last carries a factor
// k^l, the last node k^t_l, and details of level l are pre-scaled by k^l. A regular pair is
// then (a + d, a - d), output factor k^(l-1). The output of level 1 must carry no factor
// (t_0 = 0); a pass-through keeps its factor (t_l = t_(l-1)); the last pair of an even
// level takes t_l = l and produces x0 with factor k^(l-1), x1 with k^t_(l-1), with
//   u00 = c k^(l-1-t_l), u01 = s / k, u10 = s k^(t_(l-1)-t_l), u11 = -c k^(t_(l-1)-l).
// Coefficient 0 is pre-scaled by k^t_J. The standard decomposition applies each axis'
// levels to whole lines, so P is a product of per-axis factors; the non-standard one
// interleaves the axes level by level and a coefficient's factor is fixed when it leaves
// the recursion (see the constructor).
#include "basis/haar.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace fulgur::basis {

namespace {

// The level kernels copy short runs (tens of floats) thousands of times per transform; GCC
// turns such loops into memmove calls whose call overhead then dominates (a third of the
// inverse). Keep them as inline vector loops.
#if defined(__GNUC__) && !defined(__clang__)
#define FULGUR_INLINE_COPIES __attribute__((optimize("no-tree-loop-distribute-patterns")))
#else
#define FULGUR_INLINE_COPIES
#endif

template <class T>
using Level = detail::HaarLevel<T>;
template <class T>
using Axis = detail::HaarAxis<T>;

double powk(int e) { return std::pow(0.5, 0.5 * e); }  // k^e, exact for even e

template <class T>
Axis<T> plan_axis(int n) {
    Axis<T> ax;
    // 1. Lengths and the (c, s) of each level's last pair. All nodes of a level but the last
    //    stand for w_reg samples; the last one for w_last.
    std::vector<double> cs_c, cs_s;
    double w_reg = 1.0, w_last = 1.0;
    for (int m = n; m > 1; m = (m + 1) / 2) {
        Level<T> L;
        L.m = m;
        L.pairs = m / 2;
        L.half = (m + 1) / 2;
        double c = std::sqrt(0.5), s = std::sqrt(0.5);
        if (m % 2 == 0) {
            const double w = w_reg + w_last;
            c = std::sqrt(w_reg / w);
            s = std::sqrt(w_last / w);
            w_last = w;
        }
        w_reg *= 2.0;
        ax.levels.push_back(L);
        cs_c.push_back(c);
        cs_s.push_back(s);
    }
    const int J = int(ax.levels.size());
    // 2. Factor exponents t_l of the last node at the input of level l, bottom up: the
    //    output of level 1 carries no factor (t_0 = 0); a pass-through keeps its factor
    //    (t_l = t_(l-1)); the general step of an even level can produce any output factor
    //    and takes t_l = l on input.
    const double k = std::sqrt(0.5);
    int t_below = 0;  // t_(l-1)
    for (int l = 1; l <= J; ++l) {
        Level<T>& L = ax.levels[std::size_t(l - 1)];
        if (L.m % 2 == 0) {
            const double c = cs_c[std::size_t(l - 1)], s = cs_s[std::size_t(l - 1)];
            const int t = l;
            L.u00 = T(c * powk(l - 1 - t));
            L.u01 = T(s / k);
            L.u10 = T(s * powk(t_below - t));
            L.u11 = T(-c * powk(t_below - l));
            t_below = t;
        }
    }
    const int t_top = t_below;  // coefficient 0's factor exponent
    ax.t.assign(std::size_t(J + 1), 0);
    {
        int tb = 0;
        for (int l = 1; l <= J; ++l) {
            if (ax.levels[std::size_t(l - 1)].m % 2 == 0) tb = l;
            ax.t[std::size_t(l)] = tb;
        }
    }
    ax.detail_level.assign(std::size_t(n), std::numeric_limits<int>::max());
    for (int l = 1; l <= J; ++l) {
        const Level<T>& L = ax.levels[std::size_t(l - 1)];
        for (int i = L.half; i < L.m; ++i) ax.detail_level[std::size_t(i)] = l;
    }
    // 3. P: coefficient 0 gets k^t_J, the details of level l (positions [half_l, m_l)) k^l.
    ax.exponent.assign(std::size_t(n), 0);
    if (n > 0) ax.exponent[0] = t_top;
    for (int l = 1; l <= J; ++l) {
        const Level<T>& L = ax.levels[std::size_t(l - 1)];
        for (int i = L.half; i < L.m; ++i) ax.exponent[std::size_t(i)] = l;
    }
    for (int i = 0; i < n;) {
        int j = i + 1;
        while (j < n && ax.exponent[std::size_t(j)] == ax.exponent[std::size_t(i)]) ++j;
        ax.run_begin.push_back(i);
        ax.run_end.push_back(j);
        ax.run_exponent.push_back(ax.exponent[std::size_t(i)]);
        i = j;
    }
    return ax;
}

// ---- one level along x: scalar elements, a contiguous row --------------------------------

template <class T>
FULGUR_INLINE_COPIES void forward_row_level(T* __restrict x, T* __restrict tmp, const Level<T>& L) {
    const int m = L.m, h = L.half;
    const int regular = (m & 1) ? L.pairs : L.pairs - 1;
    for (int i = 0; i < regular; ++i) {
        const T a = x[2 * i], b = x[2 * i + 1];
        tmp[i] = a + b;
        tmp[h + i] = a - b;
    }
    if (m & 1) {
        tmp[h - 1] = x[m - 1];
    } else {
        const int i = L.pairs - 1;
        const T a = x[2 * i], b = x[2 * i + 1];
        tmp[i] = L.u00 * a + L.u10 * b;  // transposed step
        tmp[h + i] = L.u01 * a + L.u11 * b;
    }
    for (int i = 0; i < m; ++i) x[i] = tmp[i];
}

template <class T>
FULGUR_INLINE_COPIES void inverse_row_level(T* __restrict x, T* __restrict tmp, const Level<T>& L) {
    const int m = L.m, h = L.half;
    const int regular = (m & 1) ? L.pairs : L.pairs - 1;
    const T* __restrict a = x;
    const T* __restrict d = x + h;
    for (int i = 0; i < regular; ++i) {
        tmp[2 * i] = a[i] + d[i];
        tmp[2 * i + 1] = a[i] - d[i];
    }
    if (m & 1) {
        tmp[m - 1] = a[h - 1];
    } else {
        const int i = L.pairs - 1;
        tmp[2 * i] = L.u00 * a[i] + L.u01 * d[i];
        tmp[2 * i + 1] = L.u10 * a[i] + L.u11 * d[i];
    }
    for (int i = 0; i < m; ++i) x[i] = tmp[i];
}

// ---- one level along y or z: elements are runs of V contiguous values, S apart -----------
// (tmp holds the m elements packed, V apart.)

template <class T>
FULGUR_INLINE_COPIES void forward_vec_level(T* __restrict base, T* __restrict tmp, std::size_t V, std::size_t S,
                                            const Level<T>& L) {
    const int m = L.m, h = L.half;
    const int regular = (m & 1) ? L.pairs : L.pairs - 1;
    for (int i = 0; i < regular; ++i) {
        const T* __restrict a = base + std::size_t(2 * i) * S;
        const T* __restrict b = a + S;
        T* __restrict oa = tmp + std::size_t(i) * V;
        T* __restrict od = tmp + std::size_t(h + i) * V;
        for (std::size_t v = 0; v < V; ++v) {
            oa[v] = a[v] + b[v];
            od[v] = a[v] - b[v];
        }
    }
    if (m & 1) {
        std::memcpy(tmp + std::size_t(h - 1) * V, base + std::size_t(m - 1) * S, sizeof(T) * V);
    } else {
        const int i = L.pairs - 1;
        const T* __restrict a = base + std::size_t(2 * i) * S;
        const T* __restrict b = a + S;
        T* __restrict oa = tmp + std::size_t(i) * V;
        T* __restrict od = tmp + std::size_t(h + i) * V;
        const T u00 = L.u00, u01 = L.u01, u10 = L.u10, u11 = L.u11;
        for (std::size_t v = 0; v < V; ++v) {
            oa[v] = u00 * a[v] + u10 * b[v];
            od[v] = u01 * a[v] + u11 * b[v];
        }
    }
    if (S == V)
        std::memcpy(base, tmp, sizeof(T) * V * std::size_t(m));
    else
        for (int e = 0; e < m; ++e) std::memcpy(base + std::size_t(e) * S, tmp + std::size_t(e) * V, sizeof(T) * V);
}

// In place except for the approximations: they are copied out (half the elements), then
// the outputs (2i, 2i+1) are written front to back over the line. That never overwrites a
// detail still to be read: 2i + 1 < h + i' for every later pair i' > i, and the last pair
// of an even level writes its second output over its own detail after reading it.
template <class T>
FULGUR_INLINE_COPIES void inverse_vec_level(T* __restrict base, T* __restrict tmp, std::size_t V, std::size_t S,
                                            const Level<T>& L) {
    const int m = L.m, h = L.half;
    const int regular = (m & 1) ? L.pairs : L.pairs - 1;
    for (int e = 0; e < h; ++e) {  // short runs: a loop beats memcpy's call overhead here
        const T* __restrict src = base + std::size_t(e) * S;
        T* __restrict dst = tmp + std::size_t(e) * V;
        for (std::size_t v = 0; v < V; ++v) dst[v] = src[v];
    }
    for (int i = 0; i < regular; ++i) {
        const T* __restrict a = tmp + std::size_t(i) * V;
        const T* __restrict d = base + std::size_t(h + i) * S;
        T* __restrict o0 = base + std::size_t(2 * i) * S;
        T* __restrict o1 = o0 + S;
        for (std::size_t v = 0; v < V; ++v) {
            o0[v] = a[v] + d[v];
            o1[v] = a[v] - d[v];
        }
    }
    if (m & 1) {
        const T* __restrict src = tmp + std::size_t(h - 1) * V;
        T* __restrict dst = base + std::size_t(m - 1) * S;
        for (std::size_t v = 0; v < V; ++v) dst[v] = src[v];
    } else {
        const int i = L.pairs - 1;  // == h - 1: x1 lands on d's own slot
        const T* __restrict a = tmp + std::size_t(i) * V;
        T* __restrict o0 = base + std::size_t(2 * i) * S;
        T* d_then_o1 = base + std::size_t(h + i) * S;
        const T u00 = L.u00, u01 = L.u01, u10 = L.u10, u11 = L.u11;
        for (std::size_t v = 0; v < V; ++v) {
            const T av = a[v], dv = d_then_o1[v];
            o0[v] = u00 * av + u01 * dv;
            d_then_o1[v] = u10 * av + u11 * dv;
        }
    }
}

// Length of the axis' current block at level l (1-based): the m of that level, or 1 once
// the axis is exhausted.
template <class T>
int block_length(const Axis<T>& a, int l) {
    return l <= int(a.levels.size()) ? a.levels[std::size_t(l - 1)].m : 1;
}

}  // namespace

template <class T>
HaarTransform<T>::HaarTransform(core::Int3 dims, Decomposition d) : dims_(dims), decomposition_(d) {
    FULGUR_ASSERT(dims.x >= 1 && dims.y >= 1 && dims.z >= 1, "Haar transform dimensions must be >= 1");
    FULGUR_ASSERT(d == Decomposition::Standard || d == Decomposition::NonStandard, "unknown Haar decomposition");
    axes_[0] = plan_axis<T>(dims.x);
    axes_[1] = plan_axis<T>(dims.y);
    axes_[2] = plan_axis<T>(dims.z);
    const std::size_t depth = axes_[0].levels.size() + axes_[1].levels.size() + axes_[2].levels.size();
    powk_.resize(depth + 1);
    for (std::size_t e = 0; e <= depth; ++e) powk_[e] = T(powk(int(e)));
    scratch_.assign(dims.volume(), T(0));
    if (d == Decomposition::NonStandard) {
        // A coefficient leaves the recursion at level L = the first level at which one of its
        // coordinates is a detail; there each axis contributes its factor at the input of
        // level L: k^L for a detail or a regular approximation node, k^t_L for the last node,
        // k^t_J for an axis that is already exhausted (position 0).
        auto axis_exponent = [](const Axis& a, int p, int L) {
            const int J = int(a.levels.size());
            if (a.detail_level[std::size_t(p)] == L) return L;
            if (L > J) return a.t[std::size_t(J)];
            return p == a.levels[std::size_t(L - 1)].half - 1 ? a.t[std::size_t(L)] : L;
        };
        factor_.resize(dims.volume());
        std::size_t idx = 0;
        for (int k = 0; k < dims.z; ++k)
            for (int j = 0; j < dims.y; ++j)
                for (int i = 0; i < dims.x; ++i, ++idx) {
                    int L = std::min({axes_[0].detail_level[std::size_t(i)], axes_[1].detail_level[std::size_t(j)],
                                      axes_[2].detail_level[std::size_t(k)]});
                    if (L == std::numeric_limits<int>::max()) L = int(depth) + 1;  // coefficient 0
                    const int e =
                        axis_exponent(axes_[0], i, L) + axis_exponent(axes_[1], j, L) + axis_exponent(axes_[2], k, L);
                    factor_[idx] = powk_[std::size_t(e)];
                }
    }
}

// Multiplies every coefficient by P.
template <class T>
void HaarTransform<T>::scale(T* d) const noexcept {
    if (decomposition_ == Decomposition::NonStandard) {
        const std::size_t n = factor_.size();
        const T* __restrict f = factor_.data();
        for (std::size_t i = 0; i < n; ++i) d[i] *= f[i];
        return;
    }
    // Standard: P = k^(ex + ey + ez), run by run along x.
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y), nz = std::size_t(dims_.z);
    const Axis& ax = axes_[0];
    const std::size_t runs = ax.run_begin.size();
    for (std::size_t k = 0; k < nz; ++k)
        for (std::size_t j = 0; j < ny; ++j) {
            T* __restrict row = d + nx * (j + ny * k);
            const int base = axes_[1].exponent[j] + axes_[2].exponent[k];
            for (std::size_t r = 0; r < runs; ++r) {
                const T f = powk_[std::size_t(base + ax.run_exponent[r])];
                if (f == T(1)) continue;
                for (int i = ax.run_begin[r]; i < ax.run_end[r]; ++i) row[i] *= f;
            }
        }
}

template <class T>
void HaarTransform<T>::forward(std::span<T> data) {
    FULGUR_ASSERT(data.size() == size(), "Haar transform: data size does not match the plan");
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y);
    T* d = data.data();
    T* tmp = scratch_.data();
    const Axis &ax = axes_[0], &ay = axes_[1], &az = axes_[2];
    const int Jx = int(ax.levels.size()), Jy = int(ay.levels.size()), Jz = int(az.levels.size());
    if (decomposition_ == Decomposition::Standard) {
        // Row by row, slice by slice: each piece stays in cache through all its levels.
        for (std::size_t r = 0; r < ny * std::size_t(dims_.z); ++r)
            for (int l = 1; l <= Jx; ++l) forward_row_level<T>(d + r * nx, tmp, ax.levels[std::size_t(l - 1)]);
        for (int k = 0; k < dims_.z; ++k)
            for (int l = 1; l <= Jy; ++l)
                forward_vec_level<T>(d + std::size_t(k) * nx * ny, tmp, nx, nx, ay.levels[std::size_t(l - 1)]);
        for (int l = 1; l <= Jz; ++l) forward_vec_level<T>(d, tmp, nx * ny, nx * ny, az.levels[std::size_t(l - 1)]);
    } else {
        const int J = std::max({Jx, Jy, Jz});
        for (int l = 1; l <= J; ++l) {
            const int mx = block_length<T>(ax, l), my = block_length<T>(ay, l), mz = block_length<T>(az, l);
            if (l <= Jx)
                for (int k = 0; k < mz; ++k)
                    for (int j = 0; j < my; ++j)
                        forward_row_level<T>(d + nx * (std::size_t(j) + ny * std::size_t(k)), tmp,
                                             ax.levels[std::size_t(l - 1)]);
            if (l <= Jy)
                for (int k = 0; k < mz; ++k)
                    forward_vec_level<T>(d + std::size_t(k) * nx * ny, tmp, std::size_t(mx), nx,
                                         ay.levels[std::size_t(l - 1)]);
            if (l <= Jz)
                for (int j = 0; j < my; ++j)
                    forward_vec_level<T>(d + std::size_t(j) * nx, tmp, std::size_t(mx), nx * ny,
                                         az.levels[std::size_t(l - 1)]);
        }
    }
    scale(d);
}

template <class T>
void HaarTransform<T>::inverse(std::span<T> data) {
    FULGUR_ASSERT(data.size() == size(), "Haar transform: data size does not match the plan");
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y);
    T* d = data.data();
    T* tmp = scratch_.data();
    const Axis &ax = axes_[0], &ay = axes_[1], &az = axes_[2];
    const int Jx = int(ax.levels.size()), Jy = int(ay.levels.size()), Jz = int(az.levels.size());
    scale(d);
    if (decomposition_ == Decomposition::Standard) {
        for (int l = Jz; l >= 1; --l) inverse_vec_level<T>(d, tmp, nx * ny, nx * ny, az.levels[std::size_t(l - 1)]);
        for (int k = 0; k < dims_.z; ++k)
            for (int l = Jy; l >= 1; --l)
                inverse_vec_level<T>(d + std::size_t(k) * nx * ny, tmp, nx, nx, ay.levels[std::size_t(l - 1)]);
        for (std::size_t r = 0; r < ny * std::size_t(dims_.z); ++r)
            for (int l = Jx; l >= 1; --l) inverse_row_level<T>(d + r * nx, tmp, ax.levels[std::size_t(l - 1)]);
    } else {
        const int J = std::max({Jx, Jy, Jz});
        for (int l = J; l >= 1; --l) {
            const int mx = block_length<T>(ax, l), my = block_length<T>(ay, l), mz = block_length<T>(az, l);
            if (l <= Jz)
                for (int j = 0; j < my; ++j)
                    inverse_vec_level<T>(d + std::size_t(j) * nx, tmp, std::size_t(mx), nx * ny,
                                         az.levels[std::size_t(l - 1)]);
            if (l <= Jy)
                for (int k = 0; k < mz; ++k)
                    inverse_vec_level<T>(d + std::size_t(k) * nx * ny, tmp, std::size_t(mx), nx,
                                         ay.levels[std::size_t(l - 1)]);
            if (l <= Jx)
                for (int k = 0; k < mz; ++k)
                    for (int j = 0; j < my; ++j)
                        inverse_row_level<T>(d + nx * (std::size_t(j) + ny * std::size_t(k)), tmp,
                                             ax.levels[std::size_t(l - 1)]);
        }
    }
}

template class HaarTransform<float>;
template class HaarTransform<double>;

}  // namespace fulgur::basis
