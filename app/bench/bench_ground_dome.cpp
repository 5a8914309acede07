// The ground from S by rays up from each cell (transport::ground_dome) on the default storm:
// the per_strike configuration (a strike's two groups, the storm's lighting grid and ground
// cells, 1024 rays a cell) with the groups sharing each ray's walk, against the baseline of
// one call per group, on 1 and 2 threads; and the static light's configuration (three groups
// and two skies on the static light's grid and cells).
#include "bench/bench.h"

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"
#include "sky/ground.h"
#include "transport/ground_dome.h"
#include "transport/transport.h"

#include <filesystem>
#include <vector>

using namespace fulgur;

FULGUR_BENCH(ground_dome,
             "the ground from S by rays up on the default storm: groups sharing each ray vs one call per "
             "group, 1 and 2 threads; the static light's ground") {
    const scene::Scene sc = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    const transport::LightingMedium m = scene::make_lighting_medium(sc, scene::make_density(sc));
    const std::optional<transport::GroundTally> cells = runtime::strike_ground(sc, m.density.geom);
    if (!cells) return;
    // S of every cloud voxel in every direction: the cost depends on which voxels scatter,
    // not on the values. Two groups (the main channel and the branches) as in per_strike.
    const std::vector<glm::dvec3> dirs = transport::output_directions(sc.effective_directions());
    transport::SourceField a(m.density.geom, dirs), b(m.density.geom, dirs), c(m.density.geom, dirs);
    for (std::size_t i = 0; i < a.data.size(); ++i) {
        a.data[i] = 1.0f;
        b.data[i] = 0.5f;
        c.data[i] = 0.25f;
    }
    std::size_t scattering = 0;
    for (const float d : m.density.data) scattering += d > 0.0f;
    const std::vector<std::vector<const transport::SourceField*>> groups = {{&a}, {&b}};
    const int repeats = ctx.quick ? 1 : 5;
    const int rays = transport::DomeGroundOptions{}.rays;
    for (int threads = 1; threads <= ctx.max_threads; ++threads) {
        core::set_thread_count(threads);
        const double shared = bench::time_median(repeats, [&] { (void)transport::ground_dome(m, groups, {}, *cells); });
        const double apart = bench::time_median(repeats, [&] {
            for (const auto& g : groups) (void)transport::ground_dome(m, std::span(&g, 1), {}, *cells);
        });
        ctx.emit("ground_dome", {{"case", "strike"},
                                 {"threads", threads},
                                 {"lighting_voxels", m.density.geom.cell_count()},
                                 {"scattering_voxels", scattering},
                                 {"cells", cells->cells()},
                                 {"rays_per_cell", rays},
                                 {"seconds_two_groups_shared", shared},
                                 {"seconds_one_call_per_group", apart},
                                 {"ratio_apart_over_shared", apart / shared},
                                 {"rays_per_second", double(cells->cells()) * rays / shared}});
    }
    // The static light's ground: the sun and the two ends of the sky as groups, the two ends
    // seen past the cloud as skies, on the static light's cells.
    const std::optional<transport::GroundTally> statics = sky::static_ground_cells(sc, m.density.geom);
    if (!statics) return;
    const std::vector<std::vector<const transport::SourceField*>> three = {{&a}, {&b}, {&c}};
    const transport::DomeProfile ends[] = {[](double s) { return scene::SkyDome::zenith_weight(s); },
                                           [](double s) { return 1.0 - scene::SkyDome::zenith_weight(s); }};
    for (int threads = 1; threads <= ctx.max_threads; ++threads) {
        core::set_thread_count(threads);
        const double t = bench::time_median(repeats, [&] { (void)transport::ground_dome(m, three, ends, *statics); });
        ctx.emit("ground_dome", {{"case", "static"},
                                 {"threads", threads},
                                 {"cells", statics->cells()},
                                 {"rays_per_cell", rays},
                                 {"seconds", t},
                                 {"rays_per_second", double(statics->cells()) * rays / t}});
    }
}
