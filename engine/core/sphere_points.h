// fulgur::core — directions of equal solid angle on the unit sphere (a Fibonacci sphere), for
// the deterministic ray casts from point sources and the near-field models' quadratures.
#pragma once

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

namespace fulgur::core {

/// Direction r of n (0 <= r < n) about the pole +z: z = 1 - (2r + 1)/n (equal bands of solid
/// angle, Archimedes), azimuth r times the golden angle plus `turn` radians. The n directions
/// each stand for 4 pi / n sr.
inline glm::dvec3 fibonacci_direction(int r, int n, double turn = 0.0) noexcept {
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    const double z = 1.0 - (r + 0.5) * 2.0 / n, s = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double az = r * golden_angle + turn;
    return {s * std::cos(az), s * std::sin(az), z};
}

/// The n >= 1 directions of fibonacci_direction with no turn.
inline std::vector<glm::dvec3> fibonacci_sphere(int n) {
    std::vector<glm::dvec3> d(static_cast<std::size_t>(std::max(n, 0)));
    for (int r = 0; r < n; ++r) d[std::size_t(r)] = fibonacci_direction(r, n);
    return d;
}

}  // namespace fulgur::core
