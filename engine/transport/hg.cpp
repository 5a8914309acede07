#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace fulgur::transport {

namespace {
double clamp_g(double g) noexcept {
    if (std::isnan(g)) return 0.0;
    return std::clamp(g, -kMaxAbsG, kMaxAbsG);
}
}  // namespace

double hg_phase(double cos_theta, double g) noexcept {
    g = clamp_g(g);
    const double c = std::clamp(cos_theta, -1.0, 1.0);
    const double d = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - c);  // >= min((1-g)^2, (1+g)^2) > 0
    return (1.0 - g * g) / (4.0 * std::numbers::pi * d * std::sqrt(d));
}

double hg_from_above(double mu, double g, int cos_power) {
    FULGUR_ASSERT(cos_power >= 0 && cos_power <= 8, "hg_from_above: cos_power must be in [0, 8]");
    g = clamp_g(g);
    if (std::isnan(mu)) mu = 0.0;
    mu = std::clamp(mu, -1.0, 1.0);
    const double s = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    // Over the azimuth between w_i and w_s, hg's denominator is (a - b cos phi)^{3/2} with
    // a = 1 + g^2 - 2 g mu_i mu, b = 2 |g| sin_i sin: the integral over phi of its inverse is
    // 4 E(k) / ((a - b) sqrt(a + b)), k^2 = 2b / (a + b) (E: complete, second kind), so with
    // hg's (1 - g^2) / (4 pi) it is (1 - g^2) E(k) / (pi (a - b) sqrt(a + b)). a - b is at
    // least (1 - |g|)^2 > 0; a written as (1 - g)^2 + 2 g (1 - mu_i mu), no cancellation.
    const auto azimuthal = [&](double mu_i, double si) {
        const double a = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu_i * mu);
        const double b = 2.0 * std::abs(g) * si * s;
        const double k = std::sqrt(std::clamp(2.0 * b / (a + b), 0.0, 1.0));
        return (1.0 - g * g) / std::numbers::pi * std::comp_ellint_2(k) / ((a - b) * std::sqrt(a + b));
    };
    // mu_i = -cos(alpha), alpha in [0, pi/2] (incident light travelling downward): d mu_i =
    // sin(alpha) d alpha, smooth where sin_i = sqrt(1 - mu_i^2) is not. Composite Simpson.
    constexpr int kIntervals = 2048;
    const double h = 0.5 * std::numbers::pi / kIntervals;
    const auto f = [&](int i) {
        const double alpha = i * h;
        const double c = std::cos(alpha);
        return azimuthal(-c, std::sin(alpha)) * std::sin(alpha) * (cos_power == 0 ? 1.0 : std::pow(c, cos_power));
    };
    double sum = f(0) + f(kIntervals);
    for (int i = 1; i < kIntervals; ++i) sum += (i % 2 ? 4.0 : 2.0) * f(i);
    return std::clamp(sum * h / 3.0, 0.0, 1.0);
}

double hg_sample_cos(double g, double u) noexcept {
    g = clamp_g(g);
    u = std::clamp(u, 0.0, 1.0);
    // Inverse CDF written for 1 - cos directly, which has no division by g and no
    // cancellation near the forward peak:
    //   den = 1 - g + 2 g u,  s = (1 - g^2) / den,  1 - cos = (1-g)(1-u)(s + 1 - g) / den.
    const double den = 1.0 - g + 2.0 * g * u;  // in [min(1-g, 1+g), max(...)], > 0
    const double s = (1.0 - g * g) / den;
    const double one_minus_cos = (1.0 - g) * (1.0 - u) * (s + 1.0 - g) / den;
    return std::clamp(1.0 - one_minus_cos, -1.0, 1.0);
}

glm::dvec3 hg_sample(const glm::dvec3& forward, double g, double u1, double u2) noexcept {
    const double cos_t = hg_sample_cos(g, u1);
    const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
    const double phi = 2.0 * std::numbers::pi * u2;
    glm::dvec3 t, b;
    core::orthonormal_basis(forward, t, b);
    return glm::normalize(sin_t * std::cos(phi) * t + sin_t * std::sin(phi) * b + cos_t * forward);
}

std::vector<glm::dvec3> output_directions(int count) {
    if (count == 1) return {glm::dvec3(0, 0, 1)};
    if (count != 6 && count != 18 && count != 26)
        throw core::Error("directions", "output direction count must be 1, 6, 18 or 26, got " + std::to_string(count));
    std::vector<glm::dvec3> dirs;
    auto add_with_nonzeros = [&](int nonzeros) {
        for (int z = -1; z <= 1; ++z)
            for (int y = -1; y <= 1; ++y)
                for (int x = -1; x <= 1; ++x)
                    if (std::abs(x) + std::abs(y) + std::abs(z) == nonzeros)
                        dirs.push_back(glm::normalize(glm::dvec3(x, y, z)));
    };
    // Faces in the documented order (+x,-x,+y,-y,+z,-z), then edges, then corners.
    dirs = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    if (count >= 18) add_with_nonzeros(2);
    if (count == 26) add_with_nonzeros(3);
    return dirs;
}

}  // namespace fulgur::transport
