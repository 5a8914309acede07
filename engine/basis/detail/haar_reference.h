// Internal to fulgur::basis: a slow, literal double-precision reference of the orthonormal
// 3D Haar schemes, written straight from the definitions in docs/basis.md (rotations with
// 1/sqrt 2 at every level, no factoring). The tests check the production transform against
// it and the haar_schemes benchmark uses it to compare schemes, including the "plain"
// pass-through variant that production does not offer.
#pragma once

#include "core/core.h"

#include <cmath>
#include <vector>

namespace fulgur::basis::reference {

/// One 1D level on the line base[0], base[stride], ..., m elements; w_reg / w_last are the
/// sample counts of the regular nodes and of the last node. unbalanced = false uses
/// 1/sqrt 2 for every pair (the plain pass-through scheme).
inline void haar_level(double* base, std::size_t stride, int m, bool unbalanced, double w_reg, double w_last,
                       std::vector<double>& tmp) {
    const int p = m / 2, h = (m + 1) / 2;
    const double k = std::sqrt(0.5);
    tmp.assign(std::size_t(m), 0.0);
    for (int i = 0; i < p; ++i) {
        double c = k, s = k;
        if (unbalanced && i == p - 1 && m % 2 == 0) {
            c = std::sqrt(w_reg / (w_reg + w_last));
            s = std::sqrt(w_last / (w_reg + w_last));
        }
        const double a = base[std::size_t(2 * i) * stride], b = base[std::size_t(2 * i + 1) * stride];
        tmp[std::size_t(i)] = c * a + s * b;
        tmp[std::size_t(h + i)] = s * a - c * b;
    }
    if (m % 2) tmp[std::size_t(h - 1)] = base[std::size_t(m - 1) * stride];
    for (int i = 0; i < m; ++i) base[std::size_t(i) * stride] = tmp[std::size_t(i)];
}

struct AxisState {
    int m;
    double w_reg = 1, w_last = 1;
    void advance() {
        if (m % 2 == 0) w_last += w_reg;
        w_reg *= 2;
        m = (m + 1) / 2;
    }
};

/// Forward transform in place. standard: full 1D transform per axis (x, then y, then z);
/// otherwise non-standard: one level on every axis of the current low block, then recurse.
inline void haar_forward(std::vector<double>& f, core::Int3 n, bool standard, bool unbalanced = true) {
    const std::size_t nx = std::size_t(n.x), ny = std::size_t(n.y);
    std::vector<double> tmp;
    const std::size_t strides[3] = {1, nx, nx * ny};
    AxisState st[3] = {{n.x}, {n.y}, {n.z}};
    auto level_on_axis = [&](int a, const int lim[3]) {
        const int o1 = a == 0 ? 1 : 0, o2 = a == 2 ? 1 : 2;
        for (int u = 0; u < lim[o1]; ++u)
            for (int v = 0; v < lim[o2]; ++v)
                haar_level(f.data() + std::size_t(u) * strides[o1] + std::size_t(v) * strides[o2], strides[a], st[a].m,
                           unbalanced, st[a].w_reg, st[a].w_last, tmp);
    };
    if (standard) {
        for (int a = 0; a < 3; ++a)
            while (st[a].m > 1) {
                int lim[3] = {n.x, n.y, n.z};
                lim[a] = st[a].m;
                level_on_axis(a, lim);
                st[a].advance();
            }
    } else {
        while (st[0].m > 1 || st[1].m > 1 || st[2].m > 1) {
            const int lim[3] = {st[0].m, st[1].m, st[2].m};  // the current low block
            for (int a = 0; a < 3; ++a)
                if (st[a].m > 1) level_on_axis(a, lim);
            for (int a = 0; a < 3; ++a)
                if (st[a].m > 1) st[a].advance();
        }
    }
}

}  // namespace fulgur::basis::reference
