// Orthonormal 3D Haar transform for any grid size (standard decomposition of the
// "unbalanced" 1D Haar; see basis.h and docs/basis.md).
//
// Memory layout during a level: the m current approximations of a line are transformed
// into scratch (approximations first, then details) and copied back. The y and z passes
// treat whole x-lines / xy-planes as the "elements" of the 1D transform, so their inner
// loops run over contiguous memory and vectorize; the x pass works row by row.
#include "basis/basis.h"

#include <cmath>
#include <cstring>

namespace fulgur::basis {

namespace {

template <class T>
using Level = typename HaarTransform<T>::Level;

template <class T>
std::vector<Level<T>> plan_axis(int n) {
    std::vector<Level<T>> levels;
    // All nodes of a level but the last stand for w_reg samples; the last one for w_last.
    double w_reg = 1.0, w_last = 1.0;
    const double k = std::sqrt(0.5);
    int m = n;
    while (m > 1) {
        Level<T> L;
        L.m = m;
        L.pairs = m / 2;
        L.half = (m + 1) / 2;
        if (m % 2 == 0) {
            // The last pair joins a regular node and the last node.
            const double w = w_reg + w_last;
            L.c_last = T(std::sqrt(w_reg / w));
            L.s_last = T(std::sqrt(w_last / w));
            w_last = w;
        } else {
            // The last node passes through with its weight; every pair is regular.
            L.c_last = T(k);
            L.s_last = T(k);
        }
        w_reg *= 2.0;
        m = L.half;
        levels.push_back(L);
    }
    return levels;
}

// ---- x axis: scalar elements, one contiguous row of length n ----------------------------

template <class T>
void forward_row(T* __restrict x, T* __restrict tmp, const std::vector<Level<T>>& levels) {
    const T k = T(std::sqrt(0.5));
    for (const Level<T>& L : levels) {
        const int p = L.pairs, h = L.half;
        for (int i = 0; i < p - 1; ++i) {
            const T a = x[2 * i], b = x[2 * i + 1];
            tmp[i] = k * (a + b);
            tmp[h + i] = k * (a - b);
        }
        {
            const int i = p - 1;
            const T a = x[2 * i], b = x[2 * i + 1];
            tmp[i] = L.c_last * a + L.s_last * b;
            tmp[h + i] = L.s_last * a - L.c_last * b;
        }
        if (L.m & 1) tmp[h - 1] = x[L.m - 1];
        std::memcpy(x, tmp, sizeof(T) * std::size_t(L.m));
    }
}

template <class T>
void inverse_row(T* __restrict x, T* __restrict tmp, const std::vector<Level<T>>& levels) {
    const T k = T(std::sqrt(0.5));
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
        const Level<T>& L = *it;
        const int p = L.pairs, h = L.half;
        const T* __restrict a = x;
        const T* __restrict d = x + h;
        for (int i = 0; i < p - 1; ++i) {
            tmp[2 * i] = k * (a[i] + d[i]);
            tmp[2 * i + 1] = k * (a[i] - d[i]);
        }
        {
            const int i = p - 1;
            tmp[2 * i] = L.c_last * a[i] + L.s_last * d[i];
            tmp[2 * i + 1] = L.s_last * a[i] - L.c_last * d[i];
        }
        if (L.m & 1) tmp[L.m - 1] = a[h - 1];
        std::memcpy(x, tmp, sizeof(T) * std::size_t(L.m));
    }
}

// ---- y and z axes: elements are contiguous vectors of V values ---------------------------

template <class T>
void forward_vec(T* __restrict base, T* __restrict tmp, std::size_t V, const std::vector<Level<T>>& levels) {
    const T k = T(std::sqrt(0.5));
    for (const Level<T>& L : levels) {
        const int p = L.pairs, h = L.half;
        for (int i = 0; i < p; ++i) {
            const T c = i == p - 1 ? L.c_last : k;
            const T s = i == p - 1 ? L.s_last : k;
            const T* __restrict a = base + std::size_t(2 * i) * V;
            const T* __restrict b = a + V;
            T* __restrict oa = tmp + std::size_t(i) * V;
            T* __restrict od = tmp + std::size_t(h + i) * V;
            for (std::size_t v = 0; v < V; ++v) {
                oa[v] = c * a[v] + s * b[v];
                od[v] = s * a[v] - c * b[v];
            }
        }
        if (L.m & 1) std::memcpy(tmp + std::size_t(h - 1) * V, base + std::size_t(L.m - 1) * V, sizeof(T) * V);
        std::memcpy(base, tmp, sizeof(T) * V * std::size_t(L.m));
    }
}

template <class T>
void inverse_vec(T* __restrict base, T* __restrict tmp, std::size_t V, const std::vector<Level<T>>& levels) {
    const T k = T(std::sqrt(0.5));
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
        const Level<T>& L = *it;
        const int p = L.pairs, h = L.half;
        for (int i = 0; i < p; ++i) {
            const T c = i == p - 1 ? L.c_last : k;
            const T s = i == p - 1 ? L.s_last : k;
            const T* __restrict a = base + std::size_t(i) * V;
            const T* __restrict d = base + std::size_t(h + i) * V;
            T* __restrict o0 = tmp + std::size_t(2 * i) * V;
            T* __restrict o1 = o0 + V;
            for (std::size_t v = 0; v < V; ++v) {
                o0[v] = c * a[v] + s * d[v];
                o1[v] = s * a[v] - c * d[v];
            }
        }
        if (L.m & 1) std::memcpy(tmp + std::size_t(L.m - 1) * V, base + std::size_t(h - 1) * V, sizeof(T) * V);
        std::memcpy(base, tmp, sizeof(T) * V * std::size_t(L.m));
    }
}

}  // namespace

template <class T>
HaarTransform<T>::HaarTransform(core::Int3 dims) : dims_(dims) {
    FULGUR_ASSERT(dims.x >= 1 && dims.y >= 1 && dims.z >= 1, "Haar transform dimensions must be >= 1");
    levels_[0] = plan_axis<T>(dims.x);
    levels_[1] = plan_axis<T>(dims.y);
    levels_[2] = plan_axis<T>(dims.z);
    scratch_.assign(dims.volume(), T(0));
}

template <class T>
void HaarTransform<T>::forward(std::span<T> data) {
    FULGUR_ASSERT(data.size() == size(), "Haar transform: data size does not match the plan");
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y), nz = std::size_t(dims_.z);
    T* d = data.data();
    T* tmp = scratch_.data();
    if (!levels_[0].empty())
        for (std::size_t r = 0; r < ny * nz; ++r) forward_row<T>(d + r * nx, tmp, levels_[0]);
    if (!levels_[1].empty())
        for (std::size_t k = 0; k < nz; ++k) forward_vec<T>(d + k * nx * ny, tmp, nx, levels_[1]);
    if (!levels_[2].empty()) forward_vec<T>(d, tmp, nx * ny, levels_[2]);
}

template <class T>
void HaarTransform<T>::inverse(std::span<T> data) {
    FULGUR_ASSERT(data.size() == size(), "Haar transform: data size does not match the plan");
    const std::size_t nx = std::size_t(dims_.x), ny = std::size_t(dims_.y), nz = std::size_t(dims_.z);
    T* d = data.data();
    T* tmp = scratch_.data();
    if (!levels_[2].empty()) inverse_vec<T>(d, tmp, nx * ny, levels_[2]);
    if (!levels_[1].empty())
        for (std::size_t k = 0; k < nz; ++k) inverse_vec<T>(d + k * nx * ny, tmp, nx, levels_[1]);
    if (!levels_[0].empty())
        for (std::size_t r = 0; r < ny * nz; ++r) inverse_row<T>(d + r * nx, tmp, levels_[0]);
}

template class HaarTransform<float>;
template class HaarTransform<double>;

}  // namespace fulgur::basis
