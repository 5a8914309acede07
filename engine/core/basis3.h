// fulgur::core — an orthonormal basis around a unit vector, shared by direction sampling
// (the phase function), the bolt generator's turns and every other construction that needs
// two directions perpendicular to a given one.
#pragma once

#include <glm/vec3.hpp>

#include <cmath>

namespace fulgur::core {

/// Unit vectors (t, b) with (t, b, n) right-handed and orthonormal, for unit n; continuous
/// except across n.z = 0's sign flip and free of the cancellation near n = -z that the
/// classic Frisvad construction has (Duff et al. 2017, branchless).
inline void orthonormal_basis(const glm::dvec3& n, glm::dvec3& t, glm::dvec3& b) noexcept {
    const double sign = std::copysign(1.0, n.z);
    const double a = -1.0 / (sign + n.z);
    const double c = n.x * n.y * a;
    t = glm::dvec3(1.0 + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = glm::dvec3(c, sign + n.y * n.y * a, -n.y);
}

}  // namespace fulgur::core
