// What the bake's plan believes a light's exact single scattering costs against what it costs
// (transport::single_scattering_cost, a measured sample of voxels, against the full solve on
// one thread), across the tolerance and g on the default storm's transport grid: a virtual
// light in the cloud (the costliest kind) and one at the lattice's corner. The full solve is
// run only when the estimate is under a minute; beyond, the estimate is what the plan has.
#include "bench/bench.h"

#include "basis/virtual_lights.h"
#include "core/core.h"
#include "solve/solve.h"

#include <filesystem>

using namespace fulgur;

FULGUR_BENCH(ss_cost, "single scattering's estimated cost (the plan's probe) against its time, by tolerance and g") {
    scene::Scene s = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    const core::Grid3<float> density = scene::make_density(s);
    const basis::VirtualLightGrid lights = basis::build_virtual_light_grid(density, s.virtual_lights);
    const std::size_t inside =
        lights.index(lights.x.size() / 2, lights.y.size() / 2, std::min(lights.z.size() - 1, lights.base_layer + 1));
    struct Case {
        double tolerance, g;
    };
    std::vector<Case> cases = {{1e-3, 0.6},  {1e-5, 0.6},  {1e-3, 0.9}, {1e-6, 0.9},
                               {1e-4, 0.99}, {1e-6, 0.99}, {1e-9, 0.0}, {1e-9, 0.9}};
    if (ctx.quick) cases = {{1e-3, 0.6}, {1e-9, 0.9}};
    const core::ScopedThreadCount one(1);  // as a bake worker solves a light
    for (const Case& c : cases) {
        s.medium.g = c.g;
        s.transport.ss_tolerance = c.tolerance;
        const solve::Media media = solve::make_media(s, density);
        const auto dirs = transport::output_directions(s.effective_directions());
        const transport::SingleScatteringOptions o = solve::single_scattering_options(s);
        for (const std::size_t light : {inside, std::size_t(0)}) {
            const transport::PointSource src{lights.position(std::uint32_t(light)), 1.0};
            core::Stopwatch probe;
            const transport::SingleScatteringCost est =
                transport::single_scattering_cost(media.transport, src, dirs, o, 2.0);
            const double probe_s = probe.seconds();
            nlohmann::json j = {{"scene", "content/scenes/storm.json"},
                                {"tolerance", c.tolerance},
                                {"g", c.g},
                                {"light", light == inside ? "in the cloud" : "corner"},
                                {"voxels", est.voxels},
                                {"measured_voxels", est.measured},
                                {"complete", est.complete},
                                {"probe_s", probe_s},
                                {"estimate_s", est.seconds}};
            if (est.seconds < 60.0) {
                core::Stopwatch sw;
                transport::SourceField f = transport::single_scattering(media.transport, src, dirs, o);
                const double t = sw.seconds();
                j["solve_s"] = t;
                j["estimate_over_solve"] = est.seconds / t;
            }
            ctx.emit("ss_cost", j);
        }
    }
}
