// Dobashi et al. 2007's benchmark configuration, shared by the benchmarks (mc, bake, frame):
// a flat cloud layer on a 32x32x4 lighting grid (synthetic smooth layer, 400 m voxels; the
// paper's cloud data is not available) and its 20x20x7 virtual-light grid whose vertical
// spacing grows away from the layer (2800 lights), 26 output directions, g = 0.6.
#pragma once

#include "bake/bake.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <vector>

namespace fulgur::bench {

/// The layer's medium on an nxy x nxy x nz grid covering the same 12.8 km box.
transport::LightingMedium dobashi_layer(int nxy, int nz);

/// The paper's 20 x 20 x 7 virtual-light positions (x fastest, then y, then z).
std::vector<glm::dvec3> dobashi_lights();

/// A bakeable paper configuration: a scene whose lighting grid is the layer at full
/// resolution (downsample 1), and a bake plan whose virtual-light grid is dobashi_lights()
/// (not the scene's Eq. 4 grid). `xi` is the energy threshold, `multiple` switches the
/// lattice-Boltzmann part, components are combined (one basis per direction, as the paper).
struct PaperConfig {
    scene::Scene scene;
    core::Grid3<float> density;
    bake::Plan plan;
};
PaperConfig paper_config(int nxy, int nz, double xi, bool multiple = true);

}  // namespace fulgur::bench
