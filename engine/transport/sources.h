// fulgur::transport — the light sources every module shares: the scene's lights, the point
// sources and lines a lightning bolt becomes, the virtual lights of a bake, and every solver's input.
#pragma once

#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace fulgur::transport {

/// Isotropic point source of radiant intensity I (W/sr): it emits 4 pi I W. The unit virtual
/// light has I = 1.
struct PointSource {
    glm::dvec3 position{0.0};  ///< metres, anywhere (inside or outside the grid)
    double intensity = 1.0;    ///< radiant intensity I, W/sr, finite and >= 0
};

/// An isotropic line source (a lit stretch of a lightning channel): every metre of the
/// segment a-b emits `intensity` W/sr (power 4 pi I |b - a|).
struct LineSource {
    glm::dvec3 a{0.0}, b{0.0};  ///< metres
    double intensity = 0.0;     ///< W/sr per metre, finite and >= 0
    std::uint32_t group = 0;    ///< tally group (MonteCarloOptions::groups), e.g. main channel / branches
};

/// Directional source (the sun): irradiance E (W/m^2) on a plane perpendicular to its
/// propagation direction; it illuminates the grid from outside.
struct DirectionalSource {
    glm::dvec3 direction{0.0, 0.0, -1.0};  ///< propagation direction (normalized on use)
    double irradiance = 1.0;               ///< E, W/m^2, finite and >= 0
};

/// A sky dome: radiance from every direction above the horizon, uniform in azimuth, a
/// function of the elevation only, lighting the grid from outside (the sky's truth,
/// transport::monte_carlo). Tabulated at u = sin(elevation) = k / (n - 1), k = 0 .. n - 1, and
/// linear between; no light from below the horizon.
struct DomeSource {
    std::vector<double> radiance;  ///< W m^-2 sr^-1, 2 <= n <= 2^20 values, finite and >= 0
};

}  // namespace fulgur::transport
