// What accuracy costs in time, against the truth.
//   frontier: the default storm, 5 strikes (seeds 1-5) at their first return stroke + 2 ms;
//   every quality preset (paper, hybrid, per_strike) and the knobs that matter (virtual-light
//   spacing h_usr, lighting-grid resolution, the transport grid's refinement, xi, output
//   directions, single-scattering tolerance, the per-strike solver and its paths). Each
//   configuration's frame S is compared with the truth of the same strike (runtime::truth:
//   Monte Carlo of the lit channel through the full-resolution density) over cloud voxels:
//   total, single and multiple relative L2, and a side-view image (study::side_view). Costs:
//   the frame's time on this machine (all 26 directions, median of 5 builds), the strike's
//   own solve (seconds, on the worker thread, once per strike), their sum amortized over the
//   60 frames between strikes at 60 fps (the default storm strikes once a second), the bake's
//   time and file size, and the run time's memory.
//   Outputs: frontier.csv (one row per configuration; worst and median over the strikes),
//   frontier_strikes.csv (one row per configuration and strike); scripts/plot_frontier.py draws
//   them with the Pareto front. --quick: 2 strikes, fewer paths, the scene's own bake only.
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <tuple>

using namespace fulgur;
using study::cloud_error;
using study::flat;

namespace {

// A configuration: a scene variant (what is baked and how the run time lights frames).
struct Config {
    std::string name;          // short label for the chart
    scene::Scene scene;        // the default storm with the knobs changed
    std::string bake;          // the bake it uses (label; configurations share bakes)
    bool own_fallback = true;  // false: per-strike configurations reuse the scene's bake as fallback
};

struct Bake {
    std::filesystem::path fgb;
    double seconds = 0.0;  // measured (this run or a previous one, from its report), else the plan's estimate
    bool estimated = false;
    double file_mb = 0.0;
    std::unique_ptr<runtime::BakedBases> bases;
};

struct Strike {
    std::uint64_t seed = 0;
    double t = 0.0;
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

// The bake a configuration needs, baked into the study's folder when missing or stale; its
// time from this bake's report (kept beside the file) or, for a fresh file without one, the
// plan's estimate.
Bake& ensure_bake(std::map<std::string, Bake>& bakes, const std::string& label, const scene::Scene& s,
                  const core::Grid3<float>& density, const study::Context& ctx) {
    Bake& b = bakes[label];
    if (b.bases) return b;
    // The scene's own bake is the one the demo uses (beside the scene); the variants' go into
    // the study's folder.
    b.fgb = label == "storm" ? bake::default_fgb_path(s) : ctx.file("bakes") / (label + ".fgb");
    std::filesystem::create_directories(b.fgb.parent_path());
    const std::filesystem::path report = b.fgb.string() + ".seconds";
    std::fprintf(stderr, "frontier: bake %s\n", label.c_str());
    if (const std::optional<bake::Report> r = bake::bake_if_stale(s, density, b.fgb)) {
        b.seconds = r->seconds_total;
        std::ofstream(report) << core::format_number(b.seconds, 9) << "\n";
    } else if (std::ifstream in(report); in >> b.seconds) {
    } else {
        b.seconds = bake::make_plan(s, density).expected_seconds;
        b.estimated = true;
    }
    b.file_mb = double(std::filesystem::file_size(b.fgb)) / 1e6;
    b.bases = std::make_unique<runtime::BakedBases>(runtime::BakedBases::load(b.fgb, bake::scene_key(s, density)));
    return b;
}

}  // namespace

FULGUR_STUDY(frontier, "frontier",
             "every quality preset and the knobs that matter on the default storm, 5 strikes: error against the "
             "truth (total, single, multiple, side-view image) against frame time, per-strike solve, bake time, file "
             "size and memory; the Pareto front (scripts/plot_frontier.py)") {
    const scene::Scene base = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json");
    const core::Grid3<float> storm_density = scene::make_density(base);
    const int seeds = ctx.quick ? 2 : 5;
    const std::uint64_t truth_paths = ctx.quick ? 300'000 : 4'000'000;
    constexpr double kFramesPerStrike = 60.0;  // 60 fps, one strike a second (the default storm)

    // --- configurations ---
    std::vector<Config> configs;
    auto variant = [&](const std::string& name, const std::string& bake_label, auto&& edit) {
        Config c{name, base, bake_label};
        c.scene.lightning.schedule.strike_rate = 0.0;      // only the study's strikes
        c.scene.quality = scene::quality_preset("paper");  // each variant names its own
        edit(c.scene);
        configs.push_back(std::move(c));
    };
    auto preset = [](const char* p) { return [p](scene::Scene& s) { s.quality = scene::quality_preset(p); }; };
    // The presets on the scene's own bake; the lattices of the bake (today's: refine 1, order 1
    // by the lattice; the new: a finer transport grid, order 2 exact); the per-strike solve's
    // knobs; and the paper's knobs, each against today's lattice (cheap bakes: the knob's own
    // effect, on the same footing as the paper's numbers).
    variant("paper", "storm", preset("paper"));
    variant("hybrid", "storm", preset("hybrid"));
    variant("per_strike", "storm", preset("per_strike"));
    variant("per_strike_mc", "storm", preset("per_strike_mc"));
    // The presets on the storm with sub-voxel detail (content/scenes/storm-full.json's): its
    // own bake, bolts and truths, through the voxel means of the eroded density.
    const std::optional<cloud::SubvoxelDetail> detail =
        scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm-full.json").cloud.detail;
    for (const char* p : {"paper", "hybrid", "per_strike", "per_strike_mc"})
        variant(std::string(p) + " detail", "storm_detail", [&, p](scene::Scene& s) {
            s.quality = scene::quality_preset(p);
            s.cloud.detail = detail;
        });
    // The same with storm-full's rain shaft: the truth traces the drops as drops, the lattice's
    // presets carry them as cloud of equal transport coefficient (the bake never sees the rain).
    const std::optional<cloud::RainParams> rain =
        scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm-full.json").rain;
    for (const char* p : {"paper", "hybrid", "per_strike", "per_strike_mc"})
        variant(std::string(p) + " detail rain", "storm_detail", [&, p](scene::Scene& s) {
            s.quality = scene::quality_preset(p);
            s.cloud.detail = detail;
            s.rain = rain;
        });
    if (!ctx.quick) {
        auto lattice = [](int refine, int orders) {
            return [refine, orders](scene::Scene& s) {
                s.transport.refine = refine;
                s.transport.lb_exact_orders = orders;
            };
        };
        for (const std::pair<int, int>& ro : {std::pair{1, 1}, std::pair{2, 1}, std::pair{2, 2}}) {
            const int refine = ro.first, orders = ro.second;  // named copies: lambdas capture them
            const std::string l = "r" + std::to_string(refine) + (orders == 2 ? "o2" : "");
            for (const char* p : {"paper", "hybrid"})
                variant(std::string(p) + " lattice " + l, l, [=](scene::Scene& s) {
                    lattice(refine, orders)(s);
                    s.quality = scene::quality_preset(p);
                });
        }
        for (const int r : {1, 2, 3})
            for (const int orders : {1, 2})
                variant("per_strike strike refine " + std::to_string(r) + (orders == 2 ? " order 2" : ""), "storm",
                        [r, orders](scene::Scene& s) {
                            s.quality = scene::quality_preset("per_strike");
                            s.quality.refine = r;
                            s.quality.exact_orders = orders;
                        });
        for (const std::uint64_t paths : {200'000ull, 1'000'000ull})
            variant("per_strike MC " + std::to_string(paths / 1000) + "k", "storm", [paths](scene::Scene& s) {
                s.quality = scene::quality_preset("per_strike");
                s.quality.multiple = "monte_carlo";
                s.quality.multiple_paths = paths;
            });
        // Monte Carlo for both parts with fewer paths: noise against time.
        for (const std::uint64_t paths : {25'000ull, 50'000ull, 100'000ull})
            variant("per_strike MC " + std::to_string(paths / 1000) + "k+" + std::to_string(paths / 1000) + "k",
                    "storm", [paths](scene::Scene& s) {
                        s.quality = scene::quality_preset("per_strike");
                        s.quality.single_paths = paths;
                        s.quality.multiple = "monte_carlo";
                        s.quality.multiple_paths = paths;
                    });
        for (const std::uint64_t paths : {50'000ull, 1'000'000ull})
            variant("hybrid single " + std::to_string(paths / 1000) + "k", "storm", [paths](scene::Scene& s) {
                s.quality = scene::quality_preset("hybrid");
                s.quality.single_paths = paths;
            });
        auto knob = [&](const std::string& name, const std::string& label, auto&& edit) {
            variant("paper r1 " + name, "r1_" + label, [&](scene::Scene& s) {
                lattice(1, 1)(s);
                edit(s);
            });
        };
        knob("h_usr 3000", "husr3000", [](scene::Scene& s) { s.virtual_lights.h_usr = 3000.0; });
        knob("h_usr 750", "husr750", [](scene::Scene& s) { s.virtual_lights.h_usr = 750.0; });
        knob("xi 0.99", "xi099", [](scene::Scene& s) { s.compression.xi = 0.99; });
        knob("500 m grid", "ds4", [](scene::Scene& s) { s.lighting_downsample = 4; });
        knob("ss tol 1e-3", "sstol", [](scene::Scene& s) { s.transport.ss_tolerance = 1e-3; });
        knob("18 dirs", "dirs18", [](scene::Scene& s) { s.directions = 18; });
    }
    if (!ctx.only.empty()) {
        // Comma-separated names; "prefix*" keeps every name that starts with the prefix.
        const auto keep = [&](const std::string& name) {
            std::size_t a = 0;
            while (a <= ctx.only.size()) {
                const std::size_t b = std::min(ctx.only.find(',', a), ctx.only.size());
                const std::string want = ctx.only.substr(a, b - a);
                if (!want.empty() && want.back() == '*' ? name.starts_with(want.substr(0, want.size() - 1))
                                                        : name == want)
                    return true;
                a = b + 1;
            }
            return false;
        };
        std::erase_if(configs, [&](const Config& c) { return !keep(c.name); });
        if (configs.empty()) throw core::Error("--only", "no configuration is named \"" + ctx.only + "\"");
    }
    // The density of a configuration: the storm's, or with the configuration's detail.
    std::optional<core::Grid3<float>> detailed;
    auto density_of = [&](const Config& c) -> const core::Grid3<float>& {
        if (!c.scene.cloud.detail) return storm_density;
        if (!detailed) detailed = scene::make_density(c.scene);
        return *detailed;
    };
    // A variant whose bake is the scene's own (same key) uses the scene's file.
    const basis::BakeKey base_key = bake::scene_key(base, storm_density);
    for (Config& c : configs)
        if (bake::scene_key(c.scene, density_of(c)) == base_key) c.bake = "storm";

    // --- strikes and their truths (one per lighting grid, direction set, detail and rain) ---
    std::vector<Strike> strikes;
    std::map<std::tuple<std::uint64_t, int, int, bool, bool>, runtime::Truth> truths;
    std::map<std::string, Bake> bakes;

    study::Csv per_strike(ctx.file("frontier_strikes.csv"),
                          {"config", "seed", "error_vs_truth", "error_single", "error_multiple", "error_image",
                           "frame_ms", "strike_s", "truth_noise"});
    study::Csv table(ctx.file("frontier.csv"), {"config",
                                                "preset",
                                                "h_usr_m",
                                                "lighting_voxel_m",
                                                "refine",
                                                "xi",
                                                "directions",
                                                "ss_tolerance",
                                                "single_paths",
                                                "multiple_solver",
                                                "multiple_paths",
                                                "error_vs_truth",
                                                "error_vs_truth_median",
                                                "error_single",
                                                "error_multiple",
                                                "error_image",
                                                "frame_ms",
                                                "strike_s",
                                                "amortized_frame_ms",
                                                "bake_s",
                                                "bake_estimated",
                                                "file_MB",
                                                "memory_MB",
                                                "truth_noise"});
    nlohmann::json rows = nlohmann::json::array();
    for (const Config& c : configs) {
        const scene::Scene& s = c.scene;
        const core::Grid3<float>& density = density_of(c);
        Bake& b = ensure_bake(bakes, c.bake, s, density, ctx);
        const solve::Media media = solve::make_media(s, density);
        const std::vector<float>& rho = media.lighting.density.data;
        const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
        const std::size_t toward = study::toward_side_camera(dirs);
        std::vector<double> err, err1, err2, err_img, frame_ms, strike_s, noise;
        double memory_mb = double(b.bases->memory_bytes()) / 1e6;
        for (int k = 0; k < seeds; ++k) {
            const std::uint64_t seed = std::uint64_t(k + 1);
            runtime::FramePipeline p(s, density, *b.bases, {}, s.quality);
            const std::size_t i = p.strike_at(0.0, seed);
            const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
            runtime::ReconstructOptions o;
            o.wait_for_strikes = true;
            o.components = {true, false};
            const std::vector<float> single = flat(p.build(t, {}, o).radiance);
            o.components = {false, true};
            const std::vector<float> multiple = flat(p.build(t, {}, o).radiance);
            o.components = {true, true};
            std::vector<double> ms;
            for (int r = 0; r < 6; ++r) ms.push_back(p.build(t, {}, o).times.total());
            ms.erase(ms.begin());  // the first build after the others may still fault pages in
            const runtime::Frame& f = p.build(t, {}, o);
            const std::vector<float> total = flat(f.radiance);
            double solve_s = 0.0;
            if (runtime::StrikeSolver* solver = p.strike_solver()) {
                const lightning::Strike& sk = p.storm().strike(i);
                const std::shared_ptr<const runtime::StrikeLight> L = solver->get(sk.seed, sk.time);
                if (L) solve_s = L->seconds_single + L->seconds_multiple + L->seconds_ground;
                memory_mb = double(b.bases->memory_bytes()) / 1e6 +
                            (L ? 4.0 * double(L->single[0].data.size() * sizeof(float)) / 1e6 : 0.0);
            }
            const auto key = std::make_tuple(seed, s.lighting_downsample, int(dirs.size()), s.cloud.detail.has_value(),
                                             s.rain.has_value());
            if (!truths.count(key)) {
                runtime::TruthOptions to;
                to.paths = truth_paths;
                to.seed = seed;
                std::fprintf(stderr, "frontier: truth of strike %llu (%d m lighting voxels, %zu directions)\n",
                             static_cast<unsigned long long>(seed), int(media.lighting.density.geom.voxel_size),
                             dirs.size());
                truths[key] = runtime::truth(s, density, f.segments, {}, to);
            }
            const runtime::Truth& T = truths[key];
            const transport::SourceField tt = T.sum();
            const std::size_t cells = rho.size();
            const double e = cloud_error(total, tt.data, rho), e1 = cloud_error(single, T.single.data, rho),
                         e2 = cloud_error(multiple, T.multiple.data, rho);
            const double ei = core::relative_l2(
                std::span<const double>(
                    study::side_view(media.lighting, toward,
                                     [&](std::size_t m, std::size_t v) { return double(total[m * cells + v]); })),
                std::span<const double>(study::side_view(media.lighting, toward, [&](std::size_t m, std::size_t v) {
                    return double(tt.data[m * cells + v]);
                })));
            err.push_back(e);
            err1.push_back(e1);
            err2.push_back(e2);
            err_img.push_back(ei);
            frame_ms.push_back(median(ms));
            strike_s.push_back(solve_s);
            noise.push_back(T.noise.total);
            per_strike << c.name << double(seed) << e << e1 << e2 << ei << median(ms) << solve_s << T.noise.total;
            per_strike.end_row();
            std::fprintf(stderr,
                         "frontier: %-22s seed %llu: error %.3f (single %.3f, multiple %.3f, image %.3f), "
                         "frame %.3f ms, strike %.2f s\n",
                         c.name.c_str(), static_cast<unsigned long long>(seed), e, e1, e2, ei, median(ms), solve_s);
        }
        const double worst = *std::max_element(err.begin(), err.end());
        const double fms = median(frame_ms), ss = median(strike_s);
        const double amortized = fms + 1e3 * ss / kFramesPerStrike;
        const scene::Quality& q = s.quality;
        table << c.name << std::string(scene::to_string(q.preset)) << s.virtual_lights.h_usr
              << media.lighting.density.geom.voxel_size
              << double(q.preset != scene::Quality::Preset::Paper && q.refine > 0 ? q.refine : s.transport.refine)
              << s.compression.xi << double(dirs.size()) << s.transport.ss_tolerance
              << double(q.preset == scene::Quality::Preset::Paper ? 0 : q.single_paths) << q.multiple
              << double(q.multiple_paths) << worst << median(err) << *std::max_element(err1.begin(), err1.end())
              << *std::max_element(err2.begin(), err2.end()) << *std::max_element(err_img.begin(), err_img.end()) << fms
              << ss << amortized << b.seconds << double(b.estimated) << b.file_mb << memory_mb
              << *std::max_element(noise.begin(), noise.end());
        table.end_row();
        rows.push_back({{"config", c.name},
                        {"error_vs_truth", worst},
                        {"frame_ms", fms},
                        {"strike_s", ss},
                        {"amortized_frame_ms", amortized},
                        {"bake_s", b.seconds},
                        {"file_MB", b.file_mb}});
    }
    ctx.summary("frontier", {{"configs", rows}, {"strikes", seeds}, {"truth_paths", truth_paths}});
}
