#include "cloud/cloud.h"

namespace fulgur::cloud {

core::GridGeometry cumulonimbus_geometry(const CumulonimbusParams& p) {
    core::GridGeometry g;
    g.dims = p.grid;
    g.voxel_size = p.voxel_size;
    g.origin = glm::dvec3(-0.5 * p.grid.x * p.voxel_size, -0.5 * p.grid.y * p.voxel_size, 0.0);
    return g;
}

// TEMPORARY (replaced by the Dobashi 2000 automaton before issue 2 closes).
core::Grid3<float> generate_cumulonimbus(const CumulonimbusParams&) {
    throw core::Error("cloud.generator", "the cumulonimbus generator is not implemented yet");
}

}  // namespace fulgur::cloud
