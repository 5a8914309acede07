// Cumulonimbus generation (engine/cloud) at the default scene's size: total time and the
// stages (seed field, automaton, smoothing), on 1..max threads, against the machine's
// memory bandwidth measured in the same run.
#include "bench/bench.h"

#include "cloud/detail/automaton.h"

#include <cmath>
#include <vector>

FULGUR_BENCH(cloud, "cumulonimbus generator at the default size: total and per-stage seconds, 1 and 2 threads") {
    using namespace fulgur;
    const cloud::CumulonimbusParams p;  // the default storm's cloud
    const int repeats = ctx.quick ? 2 : 7;
    const core::GridGeometry g = cloud::cumulonimbus_geometry(p);
    const auto ellipsoids = cloud::detail::cumulonimbus_layout(p);
    const int first_layer = int(std::ceil(p.base_height / p.voxel_size - 0.5));
    const int saved = core::thread_count();
    for (int t = 1; t <= ctx.max_threads; ++t) {
        core::set_thread_count(t);
        std::vector<std::uint8_t> weights;
        const double seed_s =
            bench::time_median(repeats, [&] { weights = cloud::detail::seed_field(g, ellipsoids, p.base_height); });
        std::size_t active = 0;
        for (auto w : weights) active += w > 0 ? 1 : 0;
        std::vector<std::uint8_t> counts;
        const double ca_s = bench::time_median(repeats, [&] {
            cloud::detail::Automaton ca(p.grid, weights, {p.p_ext, p.p_hum, p.p_act}, 1);
            ca.init_vapour();
            counts.assign(g.cell_count(), 0);
            for (int s = 0; s < p.steps; ++s) ca.step(s >= p.steps - p.average_steps ? counts.data() : nullptr);
        });
        const double smooth_s = bench::time_median(repeats, [&] {
            (void)cloud::detail::smooth_density(p.grid, counts, p.average_steps, p.smoothing_radius, first_layer,
                                                p.density_gain);
        });
        const double total_s = bench::time_median(repeats, [&] { (void)cloud::generate_cumulonimbus(p); });
        ctx.emit("cloud", {{"threads", t},
                           {"grid", {p.grid.x, p.grid.y, p.grid.z}},
                           {"cells", g.cell_count()},
                           {"seeded_cells", active},
                           {"steps", p.steps},
                           {"total_s", total_s},
                           {"seed_field_s", seed_s},
                           {"automaton_s", ca_s},
                           {"smoothing_s", smooth_s},
                           {"automaton_cell_updates_per_s", double(active) * p.steps / ca_s},
                           {"baseline_triad_GBps", bench::measure_bandwidth(t)}});
    }
    core::set_thread_count(saved);
}
