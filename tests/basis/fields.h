// Test fields for the basis tests: smooth point-light-like fields (what a basis looks
// like: a 1/r^2 peak, a smooth falloff) with a little deterministic noise.
#pragma once

#include "core/core.h"

#include <cmath>
#include <vector>

namespace fulgur::test {

/// 1/(r^2 + a^2) around a point inside the grid, a smooth gradient and noise of relative
/// size `noise`, all positive like a source function.
inline std::vector<double> light_field(core::Int3 n, std::uint64_t seed, double noise = 1e-3) {
    core::Rng rng(seed, 17);
    const double px = rng.uniform() * n.x, py = rng.uniform() * n.y, pz = rng.uniform() * n.z;
    std::vector<double> f(n.volume());
    for (int k = 0; k < n.z; ++k)
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i) {
                const double dx = i + 0.5 - px, dy = j + 0.5 - py, dz = k + 0.5 - pz;
                const double v = 1.0 / (dx * dx + dy * dy + dz * dz + 0.7) + 0.01 * (1.0 + 0.1 * i - 0.05 * k);
                f[std::size_t(i) + std::size_t(n.x) * (std::size_t(j) + std::size_t(n.y) * std::size_t(k))] =
                    v * (1.0 + noise * (rng.uniform() - 0.5));
            }
    return f;
}

inline double l2(const std::vector<double>& v) {
    core::CompensatedSum s;
    for (double x : v) s.add(x * x);
    return std::sqrt(s.value());
}

inline double l2_diff(const std::vector<double>& a, const std::vector<double>& b) {
    core::CompensatedSum s;
    for (std::size_t i = 0; i < a.size(); ++i) s.add((a[i] - b[i]) * (a[i] - b[i]));
    return std::sqrt(s.value());
}

}  // namespace fulgur::test
