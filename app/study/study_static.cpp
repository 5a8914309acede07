// What the static light's accuracy costs: the sun's and the sky's solves against their truth.
//   static-frontier: the default storm and the day cumulus, the sun at 60, 25 and 5 degrees,
//   each static-light configuration (transport.static_light: refine, exact orders) solved as
//   the renderer's cache would be (sky::solve_directional on sky::static_media), against the
//   truth: Monte Carlo of the sun from the grid's boundary through the full-resolution density,
//   tallied on the lighting grid (transport::monte_carlo with a tally grid), cached in the
//   output folder. Relative L2 of S over the cloud (lighting cells holding density), all
//   directions, single and multiple apart, the whole-cloud totals' ratio, the solve's time.
//   The sky dome likewise (sky::sky_truth: Monte Carlo from the whole dome), for several
//   numbers of dome samples, each end of the gradient and the scene's sky.
//   Outputs: static_frontier.csv, static_sky.csv. --quick: the storm, one elevation, two
//   configurations, an 8-sample sky.
#include "study/study.h"

#include "core/core.h"
#include "scene/scene.h"
#include "sky/sky.h"

#include <cstdio>
#include <functional>
#include <optional>

using namespace fulgur;

namespace {

// A light's truth kept in `file` under `key` (computed by `solve` when the file lacks it).
sky::TruthField cached_truth(const core::GridGeometry& lighting, std::span<const glm::dvec3> dirs, std::uint64_t key,
                             const std::filesystem::path& file, const std::function<sky::TruthField()>& solve) {
    sky::TruthField t;
    const std::vector<glm::dvec3> d(dirs.begin(), dirs.end());
    t.field.single = t.field.multiple = transport::SourceField(lighting, d);
    if (study::read_fields(file, key, t.noise, t.field.single, t.field.multiple)) return t;
    t = solve();
    study::write_fields(file, key, t.noise, t.field.single, t.field.multiple);
    return t;
}

std::uint64_t direction_key(std::uint64_t paths, const glm::dvec3& d) {
    return core::hash_seed(
        core::hash_seed(paths, std::uint64_t(std::llround(d.x * 1e9))),
        core::hash_seed(std::uint64_t(std::llround(d.y * 1e9)), std::uint64_t(std::llround(d.z * 1e9))));
}

double total(std::span<const float> f, const std::vector<float>& rho) {
    core::CompensatedSum s;
    const std::size_t cells = rho.size();
    for (std::size_t i = 0; i < f.size(); ++i)
        if (rho[i % cells] > 0.0f) s.add(f[i]);
    return s.value();
}
double total(const transport::SourceField& f, const std::vector<float>& rho) { return total(f.data, rho); }

double luminance(const glm::dvec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

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
        // The sky's configurations: the dome as N directions (paths 0), or by Monte Carlo with
        // `paths` per basis; the scene's static settings otherwise.
        struct Sky {
            int samples;
            std::uint64_t paths;
        };
        std::vector<Sky> sky;
    };
    std::vector<Case> cases = {{"storm.json",
                                {{"r1", 1, 1},
                                 {"r2", 2, 1},
                                 {"r3", 3, 1},
                                 {"r1o2", 1, 2},
                                 {"r2o2", 2, 2},
                                 {"r3o2 100k", 3, 2, 100'000},
                                 {"r3o2", 3, 2}},
                                4'000'000,
                                {{16, 0}, {32, 0}, {64, 0}, {0, 1'000'000}, {0, 2'000'000}, {0, 4'000'000}}},
                               {"day-cumulus.json",
                                {{"r1", 1, 1},
                                 {"r2", 2, 1},
                                 {"r1o2", 1, 2},
                                 {"r2o2 100k", 2, 2, 100'000},
                                 {"r2o2", 2, 2},
                                 {"r2o2 1600k", 2, 2, 1'600'000}},
                                16'000'000,
                                {{16, 0}, {32, 0}, {0, 1'000'000}, {0, 2'000'000}, {0, 4'000'000}}}};
    std::vector<double> elevations = {60.0, 25.0, 5.0};
    const std::vector<double> azimuths = {-60.0, 30.0, 150.0};
    if (ctx.quick) {
        cases = {{"storm.json", {{"r1", 1, 1}, {"r1o2", 1, 2}}, 500'000, {{8, 0}, {0, 200'000}}}};
        elevations = {25.0};
    }
    if (!ctx.only.empty())
        for (Case& c : cases)
            std::erase_if(c.configs, [&](const Config& k) { return ctx.only.find(k.name) == std::string::npos; });
    study::Csv rows(
        ctx.file("static_frontier.csv"),
        {"scene", "config", "refine", "exact_orders", "order2_paths", "elevation", "single_error", "multiple_error",
         "total_error", "single_ratio", "multiple_ratio", "seconds", "truth_noise_single", "truth_noise_multiple"});
    study::Csv sky_rows(ctx.file("static_sky.csv"),
                        {"scene", "samples", "paths", "basis", "single_error", "multiple_error", "total_error",
                         "single_ratio", "multiple_ratio", "seconds", "truth_noise_single", "truth_noise_multiple"});
    nlohmann::json out = nlohmann::json::array();
    for (const Case& c : cases) {
        const scene::Scene base = scene::load_scene(scenes / c.file);
        const core::Grid3<float> density = scene::make_density(base);
        const std::vector<glm::dvec3> dirs = transport::output_directions(base.effective_directions());
        const solve::Media full = solve::make_media(base, density, 1, true);
        const std::vector<float>& rho = full.lighting.density.data;
        for (std::size_t e = 0; e < elevations.size() && !c.configs.empty(); ++e) {
            const transport::DirectionalSource sun{scene::sun_direction(elevations[e], azimuths[e]), 1.0};
            std::fprintf(stderr, "static-frontier: %s sun at %.0f deg: truth\n", c.file.c_str(), elevations[e]);
            sky::TruthOptions to;
            to.paths = c.truth_paths;
            const sky::TruthField truth = cached_truth(
                full.lighting.density.geom, dirs, direction_key(c.truth_paths, sun.direction),
                ctx.file("sun-truth-" + std::filesystem::path(c.file).stem().string() + "-" +
                         std::to_string(int(elevations[e])) + "-" + std::to_string(c.truth_paths) + ".bin"),
                [&] { return sky::sun_truth(full, sun.direction, dirs, to); });
            const double t1 = total(truth.field.single, rho), tm = total(truth.field.multiple, rho);
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
                for (std::size_t i = 0; i < tsum.size(); ++i)
                    tsum[i] = truth.field.single.data[i] + truth.field.multiple.data[i];
                const double e1 = study::cloud_error(f.single.data, truth.field.single.data, rho);
                const double em = study::cloud_error(f.multiple.data, truth.field.multiple.data, rho);
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
        if (!base.sky || !base.effects.sky || (!ctx.only.empty() && ctx.only.find("sky") == std::string::npos))
            continue;
        // The sky dome: each end of the gradient (or a uniform sky's sum) against its truth,
        // and the scene's sky (the ends weighted by their radiance) as the renderer composes it.
        const bool uniform = base.sky->zenith() == base.sky->horizon();
        sky::TruthOptions to;
        to.paths = c.truth_paths;
        const std::string stem = std::filesystem::path(c.file).stem().string();
        std::fprintf(stderr, "static-frontier: %s sky: truth\n", c.file.c_str());
        const core::GridGeometry& lighting = full.lighting.density.geom;
        const sky::SkyTruth truth = [&] {
            sky::SkyTruth t;
            const std::filesystem::path file =
                ctx.file("sky-truth-" + stem + "-" + std::to_string(c.truth_paths) + ".bin");
            std::optional<sky::SkyTruth> solved;
            const auto solve = [&] {
                if (!solved) solved = sky::sky_truth(full, uniform, dirs, to);
                return *solved;
            };
            const auto part = [&](std::uint64_t k, sky::LightField sky::SkyField::*which) {
                const sky::TruthField f = cached_truth(lighting, dirs, core::hash_seed(c.truth_paths, 100 + k),
                                                       file.string() + "." + std::to_string(k), [&] {
                                                           const sky::SkyTruth& all = solve();
                                                           sky::TruthField one;
                                                           one.field = all.field.*which;
                                                           one.noise = all.noise[k];
                                                           one.sums = all.sums[k];
                                                           one.seconds = all.seconds;
                                                           return one;
                                                       });
                t.field.*which = f.field;
                t.noise.push_back(f.noise);
            };
            if (uniform)
                part(0, &sky::SkyField::uniform);
            else {
                part(0, &sky::SkyField::zenith);
                part(1, &sky::SkyField::horizon);
            }
            return t;
        }();
        const double lz = luminance(base.sky->zenith()), lh = luminance(base.sky->horizon());
        for (const Case::Sky& k : c.sky) {
            // --only skymc: the dome's Monte Carlo rows alone (their truth is cached).
            if (ctx.only.find("skymc") != std::string::npos && k.paths == 0) continue;
            sky::SolveSettings st = sky::solve_settings(base, density);
            st.sky_samples = k.samples > 0 ? k.samples : st.sky_samples;
            st.sky_paths = k.paths;
            const std::string label = k.paths > 0 ? "mc " + std::to_string(k.paths) : std::to_string(k.samples);
            const solve::Media media = sky::static_media(base, density);
            core::Stopwatch sw;
            const sky::SkyField f = sky::solve_sky(media, uniform, dirs, st);
            const double secs = sw.seconds();
            struct Basis {
                std::string name;
                std::vector<float> single, multiple, truth_single, truth_multiple;
                transport::MonteCarloResult::Noise noise;
            };
            std::vector<Basis> bases;
            const auto add = [](std::vector<float>& to_, const transport::SourceField& x, double w) {
                to_.resize(x.data.size(), 0.0f);
                for (std::size_t i = 0; i < x.data.size(); ++i) to_[i] += float(w * x.data[i]);
            };
            const auto basis = [&](const std::string& name,
                                   std::vector<std::pair<sky::LightField sky::SkyField::*, double>> parts,
                                   const transport::MonteCarloResult::Noise& noise) {
                Basis b{name, {}, {}, {}, {}, noise};
                for (const auto& [which, w] : parts) {
                    add(b.single, (f.*which).single, w);
                    add(b.multiple, (f.*which).multiple, w);
                    add(b.truth_single, (truth.field.*which).single, w);
                    add(b.truth_multiple, (truth.field.*which).multiple, w);
                }
                bases.push_back(std::move(b));
            };
            if (uniform) {
                basis("uniform", {{&sky::SkyField::uniform, 1.0}}, truth.noise[0]);
            } else {
                basis("zenith", {{&sky::SkyField::zenith, 1.0}}, truth.noise[0]);
                basis("horizon", {{&sky::SkyField::horizon, 1.0}}, truth.noise[1]);
                // The scene's sky: its noise is at most the larger of the ends'.
                transport::MonteCarloResult::Noise worst;
                worst.single = std::max(truth.noise[0].single, truth.noise[1].single);
                worst.multiple = std::max(truth.noise[0].multiple, truth.noise[1].multiple);
                basis("scene", {{&sky::SkyField::zenith, lz}, {&sky::SkyField::horizon, lh}}, worst);
            }
            for (const Basis& b : bases) {
                std::vector<float> sum(b.single.size()), tsum(b.single.size());
                for (std::size_t i = 0; i < sum.size(); ++i) {
                    sum[i] = b.single[i] + b.multiple[i];
                    tsum[i] = b.truth_single[i] + b.truth_multiple[i];
                }
                const double e1 = study::cloud_error(b.single, b.truth_single, rho);
                const double em = study::cloud_error(b.multiple, b.truth_multiple, rho);
                const double et = study::cloud_error(sum, tsum, rho);
                const double r1 = total(b.single, rho) / total(b.truth_single, rho);
                const double rm = total(b.multiple, rho) / total(b.truth_multiple, rho);
                sky_rows << stem << double(k.samples) << double(k.paths) << b.name << e1 << em << et << r1 << rm << secs
                         << b.noise.single << b.noise.multiple;
                sky_rows.end_row();
                std::fprintf(stderr,
                             "static-frontier: %-16s sky %-10s %-8s: single %.3f multiple %.3f total %.3f "
                             "(ratios %.3f %.3f) in %.1f s (truth noise %.3f %.3f)\n",
                             c.file.c_str(), label.c_str(), b.name.c_str(), e1, em, et, r1, rm, secs, b.noise.single,
                             b.noise.multiple);
                out.push_back({{"scene", c.file},
                               {"config", "sky " + label + " " + b.name},
                               {"total_error", et},
                               {"multiple_error", em},
                               {"seconds", secs}});
            }
        }
    }
    ctx.summary("static-frontier", {{"rows", out}});
}
