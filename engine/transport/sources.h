// fulgur::transport — the light sources every module shares: the scene's lights, the point
// sources a lightning bolt becomes, the virtual lights of a bake, and every solver's input.
#pragma once

#include <glm/vec3.hpp>

namespace fulgur::transport {

/// Isotropic point source of radiant intensity I (W/sr): it emits 4 pi I W. The unit virtual
/// light has I = 1.
struct PointSource {
    glm::dvec3 position{0.0};  ///< metres, anywhere (inside or outside the grid)
    double intensity = 1.0;    ///< radiant intensity I, W/sr, finite and >= 0
};

/// Directional source (the sun): irradiance E (W/m^2) on a plane perpendicular to its
/// propagation direction; it illuminates the grid from outside.
struct DirectionalSource {
    glm::dvec3 direction{0.0, 0.0, -1.0};  ///< propagation direction (normalized on use)
    double irradiance = 1.0;               ///< E, W/m^2, finite and >= 0
};

}  // namespace fulgur::transport
