// The ground gathered from S (transport::gather_ground) on the default storm: the per_strike
// configuration (a strike's two groups, the storm's lighting grid and ground cells) with the
// groups sharing each pair's transmittance, against the baseline of one gather per group, on 1
// and 2 threads.
#include "bench/bench.h"

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"
#include "transport/ground_gather.h"
#include "transport/transport.h"

#include <filesystem>
#include <vector>

using namespace fulgur;

FULGUR_BENCH(ground_gather,
             "the ground gathered from S on the default storm: groups sharing transmittances vs one "
             "gather per group, 1 and 2 threads") {
    const scene::Scene sc = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    const transport::LightingMedium m = scene::make_lighting_medium(sc, scene::make_density(sc));
    const std::optional<transport::GroundTally> cells = runtime::strike_ground(sc, m.density.geom);
    if (!cells) return;
    // S of every cloud voxel in every direction: the cost depends on which voxels scatter,
    // not on the values. Two groups (the main channel and the branches) as in per_strike.
    const std::vector<glm::dvec3> dirs = transport::output_directions(sc.effective_directions());
    transport::SourceField a(m.density.geom, dirs), b(m.density.geom, dirs);
    for (std::size_t i = 0; i < a.data.size(); ++i) {
        a.data[i] = 1.0f;
        b.data[i] = 0.5f;
    }
    std::size_t emitters = 0;
    for (const float d : m.density.data) emitters += d > 0.0f;
    const std::vector<std::vector<const transport::SourceField*>> groups = {{&a}, {&b}};
    const int repeats = ctx.quick ? 1 : 3;
    for (int threads = 1; threads <= ctx.max_threads; ++threads) {
        core::set_thread_count(threads);
        const double shared = bench::time_median(repeats, [&] { (void)transport::gather_ground(m, groups, *cells); });
        const double apart = bench::time_median(repeats, [&] {
            for (const auto& g : groups) (void)transport::gather_ground(m, std::span(g), *cells);
        });
        const double points = double(transport::GroundGatherOptions{}.points_per_side);
        const double pairs = double(emitters) * double(cells->cells()) * points * points;
        ctx.emit("ground_gather", {{"threads", threads},
                                   {"lighting_voxels", m.density.geom.cell_count()},
                                   {"scattering_voxels", emitters},
                                   {"cells", cells->cells()},
                                   {"seconds_two_groups_shared", shared},
                                   {"seconds_one_gather_per_group", apart},
                                   {"ratio_apart_over_shared", apart / shared},
                                   {"voxel_point_pairs_per_second", pairs / shared}});
    }
}
