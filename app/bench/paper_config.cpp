#include "bench/paper_config.h"

#include <cmath>

namespace fulgur::bench {

transport::LightingMedium dobashi_layer(int nxy, int nz) {
    core::GridGeometry g;
    g.dims = {nxy, nxy, nz};
    g.voxel_size = 12800.0 / nxy;
    g.origin = {-6400.0, -6400.0, 1200.0};
    transport::LightingMedium m;
    m.density = core::Grid3<float>(g, 0.0f);
    m.optics = {0.004, 0.99, 0.6};
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < nxy; ++j)
            for (int i = 0; i < nxy; ++i) {
                const double x = (i + 0.5) / nxy - 0.5, y = (j + 0.5) / nxy - 0.5, z = (k + 0.5) / nz;
                const double r = std::sqrt(x * x + y * y) / 0.45 + 0.3 * std::fabs(z - 0.5);
                if (r < 1.0)
                    m.density.at(i, j, k) =
                        float((1.0 - r) * (0.7 + 0.3 * std::sin(11.0 * x + 2.0 * z) * std::cos(9.0 * y)));
            }
    return m;
}

namespace {
constexpr double kLightZ[7] = {0.0, 600.0, 1100.0, 2000.0, 2900.0, 3600.0, 5000.0};
double light_xy(int i) { return -7600.0 + 800.0 * i; }
}  // namespace

std::vector<glm::dvec3> dobashi_lights() {
    std::vector<glm::dvec3> l;
    for (double z : kLightZ)
        for (int j = 0; j < 20; ++j)
            for (int i = 0; i < 20; ++i) l.push_back({light_xy(i), light_xy(j), z});
    return l;
}

PaperConfig paper_config(int nxy, int nz, double xi, bool multiple) {
    PaperConfig c;
    const transport::LightingMedium m = dobashi_layer(nxy, nz);
    c.density = m.density;
    scene::Scene& s = c.scene;
    s.name = "Dobashi 2007 configuration";
    s.medium = m.optics;
    s.lighting_downsample = 1;
    s.directions = 26;
    s.effects.multiple_scattering = multiple;
    // Quadrature tolerance 1e-2: L1 error 1e-3 (docs/transport.md), 10x below the 1%
    // compression error, at half the cost of the 1e-3 default.
    s.transport.ss_tolerance = 1e-2;
    s.separate_components = false;
    s.compression.mode = basis::ThresholdMode::Energy;
    s.compression.xi = xi;
    s.virtual_lights.ground_height = 0.0;
    s.virtual_lights.h_usr = 800.0;
    bake::PlanOptions po;
    po.estimate = false;
    c.plan = bake::make_plan(s, c.density, po);
    basis::VirtualLightGrid& g = c.plan.lights;
    g.x.clear();
    g.y.clear();
    for (int i = 0; i < 20; ++i) {
        g.x.push_back(light_xy(i));
        g.y.push_back(light_xy(i));
    }
    g.z.assign(std::begin(kLightZ), std::end(kLightZ));
    g.cloud_base = 1200.0;
    g.cloud_top = 2800.0;
    g.base_layer = 3;  // z = 2000 is the first layer inside the layer [1200, 2800]
    c.plan.metadata.lights = g;
    c.plan.raw_bytes =
        std::uint64_t(g.count()) * c.plan.metadata.bases() * c.plan.lighting.cell_count() * sizeof(float);
    c.plan.reasons.push_back("paper configuration: the virtual-light grid is Dobashi's 20 x 20 x 7, not Eq. 4's");
    return c;
}

}  // namespace fulgur::bench
