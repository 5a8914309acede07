// The composite's display transform on the CPU (render.h display_levels): the twin of
// shaders/tonemap.glsl's aces_fitted and srgb_encode, in double.
#include "render/render.h"

#include <algorithm>
#include <cmath>

namespace fulgur::render {

namespace {

// Stephen Hill's ACES fit: its input and output matrices (rows), as tonemap.glsl's (whose
// column-major mat3 holds them transposed).
constexpr double kInput[3][3] = {{0.59719, 0.35458, 0.04823}, {0.07600, 0.90834, 0.01566}, {0.02840, 0.13383, 0.83777}};
constexpr double kOutput[3][3] = {
    {1.60475, -0.53108, -0.07367}, {-0.10208, 1.10813, -0.00605}, {-0.00327, -0.07276, 1.07602}};

glm::dvec3 times(const double (&m)[3][3], const glm::dvec3& v) {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}

glm::dvec3 aces_fitted(const glm::dvec3& x) {
    const glm::dvec3 v = times(kInput, glm::min(x, glm::dvec3(1e4)));
    const glm::dvec3 a = v * (v + 0.0245786) - 0.000090537;
    const glm::dvec3 b = v * (0.983729 * v + 0.4329510) + 0.238081;
    return glm::clamp(times(kOutput, a / b), 0.0, 1.0);
}

// The shader's sRGB curve: the power 1/2.4 by three square roots (Ian Taylor's fit).
double srgb_encode(double c) {
    if (c < 0.0031308) return 12.92 * c;
    const double s1 = std::sqrt(c), s2 = std::sqrt(s1), s3 = std::sqrt(s2);
    return 0.585122381 * s1 + 0.783140355 * s2 - 0.368262736 * s3;
}

}  // namespace

std::array<int, 3> display_levels(const glm::dvec3& radiance, double exposure) noexcept {
    const glm::dvec3 c = aces_fitted(radiance * exposure);
    std::array<int, 3> out{};
    for (int k = 0; k < 3; ++k) out[std::size_t(k)] = int(std::lround(std::clamp(srgb_encode(c[k]), 0.0, 1.0) * 255.0));
    return out;
}

}  // namespace fulgur::render
