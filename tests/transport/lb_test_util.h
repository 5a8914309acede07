// Helpers shared by the lattice-Boltzmann tests.
#pragma once

#include "transport/detail/lb_collision.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace fulgur::test::lb {

using transport::lb::kQ;
using transport::lb::Matrix19;

/// Eigenvalues of a real symmetric matrix (cyclic Jacobi), ascending.
inline std::vector<double> symmetric_eigenvalues(std::vector<std::vector<double>> a) {
    const std::size_t n = a.size();
    for (int sweep = 0; sweep < 100; ++sweep) {
        double off = 0.0;
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = i + 1; j < n; ++j) off += a[i][j] * a[i][j];
        if (off < 1e-30) break;
        for (std::size_t p = 0; p < n; ++p)
            for (std::size_t q = p + 1; q < n; ++q) {
                if (std::fabs(a[p][q]) < 1e-300) continue;
                const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                const double t = (theta >= 0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1.0));
                const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
                for (std::size_t k = 0; k < n; ++k) {  // columns p, q
                    const double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (std::size_t k = 0; k < n; ++k) {  // rows p, q
                    const double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
            }
    }
    std::vector<double> ev(n);
    for (std::size_t i = 0; i < n; ++i) ev[i] = a[i][i];
    std::sort(ev.begin(), ev.end());
    return ev;
}

/// Dominant eigenvalue (spectral radius, the Perron root of a non-negative matrix) by power
/// iteration.
inline double perron_root(const Matrix19& T, int iterations = 20000) {
    std::vector<double> v(kQ, 1.0), u(kQ);
    double lambda = 0.0;
    for (int it = 0; it < iterations; ++it) {
        double norm = 0.0;
        for (int i = 0; i < kQ; ++i) {
            u[std::size_t(i)] = 0.0;
            for (int j = 0; j < kQ; ++j) u[std::size_t(i)] += T[std::size_t(i)][std::size_t(j)] * v[std::size_t(j)];
            norm = std::max(norm, std::fabs(u[std::size_t(i)]));
        }
        lambda = norm;
        for (int i = 0; i < kQ; ++i) v[std::size_t(i)] = u[std::size_t(i)] / norm;
    }
    return lambda;
}

}  // namespace fulgur::test::lb
