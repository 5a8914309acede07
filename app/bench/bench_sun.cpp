// The sun solved again when it moves (the demo's time-of-day slider): on the default storm
// (content/scenes/storm.json: its moon moved along its course to three elevations), the wall
// time of one re-solve (sky::solve_sun: exact single scattering + the lattice for orders >= 2
// on the transport grid, and the full-resolution transmittance), split into its parts, on 1
// and max_threads threads. One solve per case: each takes seconds, and it is what the user
// waits for.
#include "bench/bench.h"

#include "core/core.h"
#include "sky/sky.h"

#include <algorithm>
#include <filesystem>

using namespace fulgur;

FULGUR_BENCH(sun, "sun re-solve on the default storm at three elevations (time of day), 1 and N threads") {
    const scene::Scene s = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    FULGUR_ASSERT(s.sun.has_value(), "the default storm has a moon");
    const core::Grid3<float> density = scene::make_density(s);
    const solve::Media media = sky::static_media(s, density);
    const sky::SolveSettings settings = sky::solve_settings(s, density);
    const sky::SunCourse course = sky::sun_course(*s.sun);
    std::vector<double> hours = {course.last_hour - 0.25, course.scene_hour, 12.0};  // ~4, 40, 50 degrees
    if (ctx.quick) hours = {course.scene_hour};
    std::vector<int> threads = {1};
    if (ctx.max_threads > 1 && !ctx.quick) threads.push_back(ctx.max_threads);
    for (int t : threads) {
        const core::ScopedThreadCount share(t);
        for (double hour : hours) {
            const scene::Sun sun = course.at(hour);
            double el = 0.0, az = 0.0;
            course.angles(hour, el, az);
            const sky::SunSolve r = sky::solve_sun(s, density, media, settings, sun.direction);
            const double rest = r.seconds - r.field.seconds_single - r.field.seconds_multiple;
            // The time-of-day's preview (order 2 by the lattice, sky::SunResolver's first answer)
            // and how far the refined solve moves the light from it (relative L2 of S over the
            // cloud, single + multiple, every direction): the step the view shows when it lands.
            sky::SolveSettings quick = settings;
            quick.exact_orders = 1;
            const transport::DirectionalSource unit{sun.direction, 1.0};  // as solve_sun
            core::Stopwatch sw;
            const sky::LightField p = sky::solve_directional(
                media, std::span(&unit, 1), transport::output_directions(s.effective_directions()), quick);
            const double preview_s = sw.seconds();
            core::RelativeL2 step;
            const std::vector<float>& rho = media.lighting.density.data;
            for (std::size_t i = 0; i < p.multiple.data.size(); ++i)
                if (rho[i % rho.size()] > 0.0f)
                    step.add(double(p.single.data[i]) + p.multiple.data[i],
                             double(r.field.single.data[i]) + r.field.multiple.data[i]);
            ctx.emit("sun", {{"scene", "content/scenes/storm.json"},
                             {"threads", t},
                             {"hour", hour},
                             {"elevation_deg", el},
                             {"azimuth_deg", az},
                             {"transport_grid",
                              {media.transport.density.dims().x, media.transport.density.dims().y,
                               media.transport.density.dims().z}},
                             {"directions", s.effective_directions()},
                             {"lattice_steps", r.field.iterations},
                             {"converged", r.field.converged},
                             {"seconds", r.seconds},
                             {"seconds_single", r.field.seconds_single},
                             {"seconds_lattice", r.field.seconds_multiple},
                             {"seconds_transmittance_and_rest", rest},
                             {"exact_orders", settings.exact_orders},
                             {"preview_seconds", preview_s},
                             {"preview_to_refined_change", step.value()}});
        }
    }
}

// The static light's truth (test_sky_storm, fulgur-study static-frontier): Monte Carlo of the
// sun from the grid's boundary through the full-resolution density, S tallied on the lighting
// grid at the scene's output directions, and in the same run toward the scene's camera. Its cost is the expected-value walks through the fine grid (a memory-bound loop: the
// density and the per-direction tally rows are read per voxel), so the memory bandwidth of the
// same run is its baseline.
FULGUR_BENCH(sun_truth, "Monte Carlo of the sun through the default storm's full-resolution density, paths/s") {
    const scene::Scene s = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    const core::Grid3<float> density = scene::make_density(s);
    const solve::Media lighting = sky::static_media(s, density);
    const solve::Media full = solve::make_media(s, density, 1, true);
    const auto dirs = transport::output_directions(s.effective_directions());
    const transport::DirectionalSource sun{scene::sun_direction(25.0, 30.0), 1.0};
    const std::uint64_t paths = ctx.quick ? 50'000 : 400'000;
    for (int t = 1; t <= std::min(2, ctx.max_threads); ++t) {
        const core::ScopedThreadCount share(t);
        ctx.emit("sun_truth", {{"baseline", "memory"}, {"threads", t}, {"triad_GBps", bench::measure_bandwidth(t)}});
        transport::MonteCarloOptions mo;
        mo.paths = paths;
        mo.seed = 17;
        mo.halves = true;
        const double sec = bench::time_median(ctx.quick ? 1 : 3, [&] {
            transport::monte_carlo(full.full, sun, lighting.lighting.density.geom, dirs, mo);
        });
        // The same paths tallied toward the scene's camera (transport.static_light.directions
        // "camera"): one phase evaluation per deposit instead of one per baked direction.
        transport::MonteCarloOptions toward = mo;
        toward.toward = scene::camera_position(s.camera, density.geom);
        const auto one = transport::output_directions(1);
        const double sec_toward = bench::time_median(ctx.quick ? 1 : 3, [&] {
            transport::monte_carlo(full.full, sun, lighting.lighting.density.geom, one, toward);
        });
        const core::GridGeometry& fg = full.full.density.geom;
        const core::GridGeometry& lg = lighting.lighting.density.geom;
        ctx.emit("sun_truth", {{"scene", "content/scenes/storm.json"},
                               {"threads", t},
                               {"density_grid", {fg.dims.x, fg.dims.y, fg.dims.z}},
                               {"tally_grid", {lg.dims.x, lg.dims.y, lg.dims.z}},
                               {"directions", dirs.size()},
                               {"paths", paths},
                               {"seconds", sec},
                               {"paths_per_s", double(paths) / sec},
                               {"toward_camera_seconds", sec_toward},
                               {"baked_over_toward_camera", sec / sec_toward}});
    }
}
