// What the static light's accuracy costs: the sun's solve against its truth.
//   static-frontier: the default storm and the day cumulus, the sun at 60, 25 and 5 degrees,
//   each static-light configuration (transport.static_light: refine, exact orders) solved as
//   the renderer's cache would be (sky::solve_directional on sky::static_media), against the
//   truth: Monte Carlo of the sun from the grid's boundary through the full-resolution density,
//   tallied on the lighting grid (transport::monte_carlo with a tally grid), cached in the
//   output folder. Relative L2 of S over the cloud (lighting cells holding density), all
//   directions, single and multiple apart, the whole-cloud totals' ratio, the solve's time.
//   Outputs: static_frontier.csv. --quick: the storm, one elevation, two configurations.
#include "study/study.h"

#include "core/core.h"
#include "scene/scene.h"
#include "sky/sky.h"

#include <cstdio>

using namespace fulgur;

namespace {

// The truth of one sun, kept in `file` keyed by its direction and paths.
transport::MonteCarloResult cached_sun_truth(const solve::Media& full_media, const transport::DirectionalSource& sun,
                                             const core::GridGeometry& lighting, std::span<const glm::dvec3> dirs,
                                             std::uint64_t paths, const std::filesystem::path& file) {
    const std::uint64_t key =
        core::hash_seed(core::hash_seed(paths, std::uint64_t(std::llround(sun.direction.x * 1e9))),
                        core::hash_seed(std::uint64_t(std::llround(sun.direction.y * 1e9)),
                                        std::uint64_t(std::llround(sun.direction.z * 1e9))));
    transport::MonteCarloResult r;
    const std::vector<glm::dvec3> d(dirs.begin(), dirs.end());
    r.single = r.multiple = transport::SourceField(lighting, d);
    if (study::read_fields(file, key, r.noise, r.single, r.multiple)) return r;
    transport::MonteCarloOptions mo;
    mo.paths = paths;
    mo.seed = 23;
    mo.halves = true;
    r = transport::monte_carlo(full_media.full, sun, lighting, dirs, mo);
    study::write_fields(file, key, r.noise, r.single, r.multiple);
    return r;
}

double total(const transport::SourceField& f, const std::vector<float>& rho) {
    core::CompensatedSum s;
    const std::size_t cells = rho.size();
    for (std::size_t i = 0; i < f.data.size(); ++i)
        if (rho[i % cells] > 0.0f) s.add(f.data[i]);
    return s.value();
}

}  // namespace

FULGUR_STUDY(static_frontier, "static-frontier",
             "the sun's light against its truth (Monte Carlo through the full-resolution density) for static-light "
             "configurations (refine, exact orders): error and solve time; default storm and day cumulus, the sun "
             "at 60, 25 and 5 degrees") {
    const std::filesystem::path scenes = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes";
    struct Config {
        std::string name;
        int refine, exact_orders;
        std::uint64_t order2_paths = 400'000;
    };
    struct Case {
        std::string file;
        std::vector<Config> configs;
        std::uint64_t truth_paths;  // the truth's noise well below the best configuration's error
    };
    std::vector<Case> cases = {
        {"storm.json",
         {{"r1", 1, 1},
          {"r2", 2, 1},
          {"r3", 3, 1},
          {"r1o2", 1, 2},
          {"r2o2", 2, 2},
          {"r3o2 100k", 3, 2, 100'000},
          {"r3o2", 3, 2}},
         4'000'000},
        {"day-cumulus.json",
         {{"r1", 1, 1}, {"r2", 2, 1}, {"r1o2", 1, 2}, {"r2o2 100k", 2, 2, 100'000}, {"r2o2", 2, 2}},
         16'000'000}};
    std::vector<double> elevations = {60.0, 25.0, 5.0};
    const std::vector<double> azimuths = {-60.0, 30.0, 150.0};
    if (ctx.quick) {
        cases = {{"storm.json", {{"r1", 1, 1}, {"r1o2", 1, 2}}, 500'000}};
        elevations = {25.0};
    }
    if (!ctx.only.empty())
        for (Case& c : cases)
            std::erase_if(c.configs, [&](const Config& k) { return ctx.only.find(k.name) == std::string::npos; });
    study::Csv rows(
        ctx.file("static_frontier.csv"),
        {"scene", "config", "refine", "exact_orders", "order2_paths", "elevation", "single_error", "multiple_error",
         "total_error", "single_ratio", "multiple_ratio", "seconds", "truth_noise_single", "truth_noise_multiple"});
    nlohmann::json out = nlohmann::json::array();
    for (const Case& c : cases) {
        const scene::Scene base = scene::load_scene(scenes / c.file);
        const core::Grid3<float> density = scene::make_density(base);
        const std::vector<glm::dvec3> dirs = transport::output_directions(base.effective_directions());
        const solve::Media full = solve::make_media(base, density, 1, true);
        const std::vector<float>& rho = full.lighting.density.data;
        for (std::size_t e = 0; e < elevations.size(); ++e) {
            const transport::DirectionalSource sun{scene::sun_direction(elevations[e], azimuths[e]), 1.0};
            std::fprintf(stderr, "static-frontier: %s sun at %.0f deg: truth\n", c.file.c_str(), elevations[e]);
            const transport::MonteCarloResult truth = cached_sun_truth(
                full, sun, full.lighting.density.geom, dirs, c.truth_paths,
                ctx.file("sun-truth-" + std::filesystem::path(c.file).stem().string() + "-" +
                         std::to_string(int(elevations[e])) + "-" + std::to_string(c.truth_paths) + ".bin"));
            const double t1 = total(truth.single, rho), tm = total(truth.multiple, rho);
            for (const Config& k : c.configs) {
                scene::Scene s = base;
                s.transport.static_refine = k.refine;
                s.transport.static_exact_orders = k.exact_orders;
                s.transport.static_order2_paths = k.order2_paths;
                if (base.lighting_downsample % k.refine != 0) continue;
                const sky::SolveSettings st = sky::solve_settings(s, density);
                const solve::Media media = sky::static_media(s, density);
                core::Stopwatch sw;
                const sky::LightField f = sky::solve_directional(media, std::span(&sun, 1), dirs, st);
                const double secs = sw.seconds();
                std::vector<float> sum(f.single.data.size());
                for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = f.single.data[i] + f.multiple.data[i];
                std::vector<float> tsum(sum.size());
                for (std::size_t i = 0; i < tsum.size(); ++i) tsum[i] = truth.single.data[i] + truth.multiple.data[i];
                const double e1 = study::cloud_error(f.single.data, truth.single.data, rho);
                const double em = study::cloud_error(f.multiple.data, truth.multiple.data, rho);
                const double et = study::cloud_error(sum, tsum, rho);
                const double r1 = total(f.single, rho) / t1, rm = total(f.multiple, rho) / tm;
                rows << std::filesystem::path(c.file).stem().string() << k.name << double(k.refine)
                     << double(k.exact_orders) << double(k.exact_orders == 2 ? k.order2_paths : 0) << elevations[e]
                     << e1 << em << et << r1 << rm << secs << truth.noise.single << truth.noise.multiple;
                rows.end_row();
                std::fprintf(stderr,
                             "static-frontier: %-16s %-5s sun %4.1f deg: single %.3f multiple %.3f total %.3f "
                             "(ratios %.3f %.3f) in %.1f s (truth noise %.3f %.3f)\n",
                             c.file.c_str(), k.name.c_str(), elevations[e], e1, em, et, r1, rm, secs,
                             truth.noise.single, truth.noise.multiple);
                out.push_back({{"scene", c.file},
                               {"config", k.name},
                               {"elevation", elevations[e]},
                               {"total_error", et},
                               {"multiple_error", em},
                               {"seconds", secs}});
            }
        }
    }
    ctx.summary("static-frontier", {{"rows", out}});
}
