// A lumpy ellipsoidal cloud for the static light's tests: density (1 - r) modulated by a sine
// (hop optical depth up to ~1.5 at the default extinction 0.015 /m over 100 m voxels), centred
// over the grid's middle `height` metres up, with an empty margin: thin and thick voxels, lit
// and shadowed ones.
#pragma once

#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <cmath>

namespace fulgur::test {

inline transport::LightingMedium lumpy_cloud(core::Int3 dims, glm::dvec3 semi_axes, double height,
                                             transport::Medium optics = {0.015, 0.95, 0.6}) {
    const core::GridGeometry g{dims, 100.0, {-50.0 * dims.x, -50.0 * dims.y, 0.0}};
    transport::LightingMedium m;
    m.density = core::Grid3<float>(g, 0.0f);
    m.optics = optics;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const glm::dvec3 p = (g.centre(i, j, k) - glm::dvec3(0.0, 0.0, height)) / semi_axes;
                const double r = glm::length(p);
                if (r < 1.0) m.density.at(i, j, k) = float((1.0 - r) * (0.8 + 0.2 * std::sin(3.0 * p.x + 2.0 * p.z)));
            }
    return m;
}

}  // namespace fulgur::test
