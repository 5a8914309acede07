// Orthonormal 3D Haar transform for any grid size: the standard decomposition of the
// "unbalanced" 1D Haar (basis.h and docs/basis.md), computed as inverse = U P and
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
// Coefficient 0 is pre-scaled by k^t_J.
#include "basis/basis.h"

#include <cmath>
#include <cstring>

namespace fulgur::basis {

namespace {

template <class T>
using Level = typename HaarTransform<T>::Level;
template <class T>
using Axis = typename HaarTransform<T>::Axis;

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

// ---- x axis: scalar elements, one contiguous row -----------------------------------------

template <class T>
void forward_row(T* __restrict x, T* __restrict tmp, const std::vector<Level<T>>& levels) {
    for (const Level<T>& L : levels) {
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
        std::memcpy(x, tmp, sizeof(T) * std::size_t(m));
    }
}

template <class T>
void inverse_row(T* __restrict x, T* __restrict tmp, const std::vector<Level<T>>& levels) {
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
        const Level<T>& L = *it;
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
        std::memcpy(x, tmp, sizeof(T) * std::size_t(m));
    }
}

// ---- y and z axes: elements are contiguous vectors of V values ---------------------------

template <class T>
void forward_vec(T* __restrict base, T* __restrict tmp, std::size_t V, const std::vector<Level<T>>& levels) {
    for (const Level<T>& L : levels) {
        const int m = L.m, h = L.half;
        const int regular = (m & 1) ? L.pairs : L.pairs - 1;
        for (int i = 0; i < regular; ++i) {
            const T* __restrict a = base + std::size_t(2 * i) * V;
            const T* __restrict b = a + V;
            T* __restrict oa = tmp + std::size_t(i) * V;
            T* __restrict od = tmp + std::size_t(h + i) * V;
            for (std::size_t v = 0; v < V; ++v) {
                oa[v] = a[v] + b[v];
                od[v] = a[v] - b[v];
            }
        }
        if (m & 1) {
            std::memcpy(tmp + std::size_t(h - 1) * V, base + std::size_t(m - 1) * V, sizeof(T) * V);
        } else {
            const int i = L.pairs - 1;
            const T* __restrict a = base + std::size_t(2 * i) * V;
            const T* __restrict b = a + V;
            T* __restrict oa = tmp + std::size_t(i) * V;
            T* __restrict od = tmp + std::size_t(h + i) * V;
            const T u00 = L.u00, u01 = L.u01, u10 = L.u10, u11 = L.u11;
            for (std::size_t v = 0; v < V; ++v) {
                oa[v] = u00 * a[v] + u10 * b[v];
                od[v] = u01 * a[v] + u11 * b[v];
            }
        }
        std::memcpy(base, tmp, sizeof(T) * V * std::size_t(m));
    }
}

template <class T>
void inverse_vec(T* __restrict base, T* __restrict tmp, std::size_t V, const std::vector<Level<T>>& levels) {
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
        const Level<T>& L = *it;
        const int m = L.m, h = L.half;
        const int regular = (m & 1) ? L.pairs : L.pairs - 1;
        for (int i = 0; i < regular; ++i) {
            const T* __restrict a = base + std::size_t(i) * V;
            const T* __restrict d = base + std::size_t(h + i) * V;
            T* __restrict o0 = tmp + std::size_t(2 * i) * V;
            T* __restrict o1 = o0 + V;
            for (std::size_t v = 0; v < V; ++v) {
                o0[v] = a[v] + d[v];
                o1[v] = a[v] - d[v];
            }
        }
        if (m & 1) {
            std::memcpy(tmp + std::size_t(m - 1) * V, base + std::size_t(h - 1) * V, sizeof(T) * V);
        } else {
            const int i = L.pairs - 1;
            const T* __restrict a = base + std::size_t(i) * V;
            const T* __restrict d = base + std::size_t(h + i) * V;
            T* __restrict o0 = tmp + std::size_t(2 * i) * V;
            T* __restrict o1 = o0 + V;
            const T u00 = L.u00, u01 = L.u01, u10 = L.u10, u11 = L.u11;
            for (std::size_t v = 0; v < V; ++v) {
                o0[v] = u00 * a[v] + u01 * d[v];
                o1[v] = u10 * a[v] + u11 * d[v];
            }
        }
        std::memcpy(base, tmp, sizeof(T) * V * std::size_t(m));
    }
}

}  // namespace

template <class T>
HaarTransform<T>::HaarTransform(core::Int3 dims) : dims_(dims) {
    FULGUR_ASSERT(dims.x >= 1 && dims.y >= 1 && dims.z >= 1, "Haar transform dimensions must be >= 1");
    axes_[0] = plan_axis<T>(dims.x);
    axes_[1] = plan_axis<T>(dims.y);
    axes_[2] = plan_axis<T>(dims.z);
    const std::size_t depth = axes_[0].levels.size() + axes_[1].levels.size() + axes_[2].levels.size();
    powk_.resize(depth + 1);
    for (std::size_t e = 0; e <= depth; ++e) powk_[e] = T(powk(int(e)));
    scratch_.assign(dims.volume(), T(0));
}

// Multiplies every coefficient by P = k^(ex + ey + ez), run by run along x.
template <class T>
void HaarTransform<T>::scale(T* d) const noexcept {
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
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y), nz = std::size_t(dims_.z);
    T* d = data.data();
    T* tmp = scratch_.data();
    if (!axes_[0].levels.empty())
        for (std::size_t r = 0; r < ny * nz; ++r) forward_row<T>(d + r * nx, tmp, axes_[0].levels);
    if (!axes_[1].levels.empty())
        for (std::size_t k = 0; k < nz; ++k) forward_vec<T>(d + k * nx * ny, tmp, nx, axes_[1].levels);
    if (!axes_[2].levels.empty()) forward_vec<T>(d, tmp, nx * ny, axes_[2].levels);
    scale(d);
}

template <class T>
void HaarTransform<T>::inverse(std::span<T> data) {
    FULGUR_ASSERT(data.size() == size(), "Haar transform: data size does not match the plan");
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y), nz = std::size_t(dims_.z);
    T* d = data.data();
    T* tmp = scratch_.data();
    scale(d);
    if (!axes_[2].levels.empty()) inverse_vec<T>(d, tmp, nx * ny, axes_[2].levels);
    if (!axes_[1].levels.empty())
        for (std::size_t k = 0; k < nz; ++k) inverse_vec<T>(d + k * nx * ny, tmp, nx, axes_[1].levels);
    if (!axes_[0].levels.empty())
        for (std::size_t r = 0; r < ny * nz; ++r) inverse_row<T>(d + r * nx, tmp, axes_[0].levels);
}

template class HaarTransform<float>;
template class HaarTransform<double>;

}  // namespace fulgur::basis
