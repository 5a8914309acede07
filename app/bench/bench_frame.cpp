// fulgur-bench frame: the run time's per-frame cost (engine/runtime) against the paper's
// Table 2 and the direct solve.
//
// Configurations (bench/paper_config.h): (a) Dobashi 2007's, a 32x32x4 lighting grid with
// 20x20x7 virtual lights and 26 directions, and (b) the same layer on 64x64x16. Each is baked
// once into a temporary file (xi = 0.9999 energy, float16, single + multiple combined, as
// the paper). Bolts: the default storm scene's lightning section (content/scenes/storm.json),
// cloud-to-ground from the layer, in the layer's box down to the ground; strikes on demand.
//
// Per frame: the stage times of runtime::FramePipeline::build (bolt = active strikes + lit
// stretches; sources; splat; accumulate; inverse Haar), medians over frames spread over
// each flash (leader, return stroke, decay, restrikes) of many seeds, only frames where the
// flash is lit. Bolt *generation* happens once per strike (when it is scheduled), not per
// frame: reported separately. Reconstructing all 26 directions, and the 8 a side view
// needs. One and two threads (core::set_thread_count).
//
// Direct solve: runtime::direct_solve (exact single scattering + lattice-Boltzmann, no
// basis) on the sources of a few frames at the return-stroke peak; the speed-up is its
// time over the basis frame's (all 26 directions, the same output).
//
// --quick: (a) only, with every other virtual light in x and y (10x10x7), fewer frames.
#include "bench/bench.h"
#include "bench/paper_config.h"

#include "bake/bake.h"
#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

using namespace fulgur;

namespace {

std::filesystem::path storm_scene() { return std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json"; }

// The 8 directions a side view of the layer needs most: those closest to the direction
// toward a camera 30 km south of the layer, slightly above it (S is sampled toward the eye).
std::vector<int> side_view_directions(const std::vector<glm::dvec3>& dirs) {
    const glm::dvec3 to_eye = glm::normalize(glm::dvec3(0.0, -1.0, 0.14));
    std::vector<int> idx(dirs.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) {
        return glm::dot(dirs[std::size_t(a)], to_eye) > glm::dot(dirs[std::size_t(b)], to_eye);
    });
    idx.resize(std::min<std::size_t>(8, idx.size()));
    std::sort(idx.begin(), idx.end());
    return idx;
}

double pct(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, std::size_t(q * double(v.size())))];
}

struct Case {
    std::string label;
    bench::PaperConfig config;
};

// A configuration baked into a temporary file and loaded back, with what the bake cost.
struct Baked {
    bake::Report report;
    runtime::BakedBases bases;
    double bake_s = 0.0, load_s = 0.0, file_mb = 0.0;
};

Baked bake_and_load(const bench::Context& ctx, Case& c) {
    const std::filesystem::path fgb = std::filesystem::temp_directory_path() / "fulgur_bench_frame.fgb";
    c.config.plan.threads = ctx.max_threads;
    core::Stopwatch bake_sw;
    bake::Report rep = bake::bake(c.config.scene, c.config.density, c.config.plan, fgb);
    const double bake_s = bake_sw.seconds();
    core::Stopwatch load_sw;
    runtime::BakedBases bases = runtime::BakedBases::load(fgb);
    const double load_s = load_sw.seconds();
    const double file_mb = double(std::filesystem::file_size(fgb)) / 1e6;
    std::filesystem::remove(fgb);
    return {std::move(rep), std::move(bases), bake_s, load_s, file_mb};
}

// What every step of a configuration's run shares: the layer's scene with the storm's
// lightning (strikes on demand), the bolts' domain, the direction sets and the strike plan.
struct Run {
    const bench::Context& ctx;
    const Case& c;
    const runtime::BakedBases& bases;
    scene::Scene s;
    lightning::Box domain;
    solve::Media media;
    int seeds = 0;
    int per_flash = 0;                // frame times spread over each flash
    double spacing = 10.0;            // s between strikes: flashes never overlap
    std::vector<int> all_dirs, side;  // all_dirs is empty: every baked direction

    Run(const bench::Context& context, const Case& cs, const runtime::BakedBases& b,
        const lightning::LightningParams& storm_lightning)
        : ctx(context), c(cs), bases(b), s(cs.config.scene) {
        s.lightning = storm_lightning;
        s.lightning.schedule.strike_rate = 0.0;  // strikes on demand, one per seed
        const core::GridGeometry& g = c.config.density.geom;
        domain = lightning::Box{glm::dvec3(g.origin.x, g.origin.y, s.lightning.bolt.ground_height), g.upper()};
        media = solve::make_media(s, c.config.density);
        seeds = ctx.quick ? 4 : 24;
        per_flash = ctx.quick ? 8 : 24;
        side = side_view_directions(bases.directions());
    }
    runtime::FramePipeline pipeline() const { return runtime::FramePipeline(s, c.config.density, bases, domain); }
};

// Bolt generation, once per strike (20-60 us on the default storm; amortized over frames).
std::vector<double> bolt_generation_ms(const Run& r) {
    std::vector<double> gen_ms;
    core::set_thread_count(1);
    runtime::FramePipeline p = r.pipeline();
    for (int k = 0; k < r.seeds; ++k) {
        core::Stopwatch sw;
        (void)p.storm().generator().generate(std::uint64_t(1000 + k));
        gen_ms.push_back(sw.milliseconds());
    }
    return gen_ms;
}

// A dark frame (between flashes): the whole build() call, wall time.
std::vector<double> dark_frame_us(const Run& r) {
    std::vector<double> dark_us;
    core::set_thread_count(1);
    runtime::FramePipeline p = r.pipeline();
    for (int k = 0; k < r.seeds; ++k) p.strike_at(r.spacing * k, std::uint64_t(1000 + k));
    for (int k = 0; k < r.seeds; ++k)
        for (int j = 0; j < 50; ++j) {
            core::Stopwatch sw;
            const runtime::Frame& f = p.build(r.spacing * k + 5.0 + 0.01 * j, r.all_dirs);
            dark_us.push_back(sw.seconds() * 1e6);
            if (f.lit) dark_us.pop_back();  // not dark after all (never with 10 s between strikes)
        }
    return dark_us;
}

// The fields every JSON line of the configuration repeats.
nlohmann::json base_fields(const Run& r, const Baked& baked, double bw) {
    const core::GridGeometry& g = r.c.config.density.geom;
    const runtime::BakedBases& bases = baked.bases;
    return {{"config", r.c.label},
            {"lighting_grid", {g.dims.x, g.dims.y, g.dims.z}},
            {"virtual_lights", bases.lights().count()},
            {"lights_dropped", baked.report.lights_dropped},
            {"baked_directions", bases.directions().size()},
            {"coefficients", bases.coefficient_count()},
            {"bases_MB", double(bases.memory_bytes()) / 1e6},
            {"bake_seconds", baked.bake_s},
            {"file_MB", baked.file_mb},
            {"load_seconds", baked.load_s},
            {"bolt_generation_ms_per_strike", bench::median(bolt_generation_ms(r))},
            {"dark_frame_us", bench::median(dark_frame_us(r))},
            {"baseline_triad_GBps", bw}};
}

// Frame stage times, per thread count and direction set. Two threads twice: forced (every
// frame split over the threads) and with the default work threshold.
void stage_times(const Run& r, const nlohmann::json& base) {
    struct Mode {
        int threads;
        std::size_t min_work;
    };
    const std::size_t default_min_work = runtime::ReconstructOptions{}.parallel_min_work;
    for (const Mode mode : {Mode{1, 0}, Mode{2, 0}, Mode{2, default_min_work}}) {
        const int threads = mode.threads;
        if (threads > r.ctx.max_threads) continue;
        core::set_thread_count(threads);
        runtime::ReconstructOptions ro;
        ro.parallel_min_work = mode.min_work;
        for (const bool subset : {false, true}) {
            runtime::FramePipeline p = r.pipeline();
            std::vector<double> times;
            for (int k = 0; k < r.seeds; ++k) {
                const std::size_t i = p.strike_at(r.spacing * k, std::uint64_t(1000 + k));
                const double d = p.storm().strike(i).profile.duration;
                for (int j = 0; j < r.per_flash; ++j) times.push_back(r.spacing * k + d * (j + 0.5) / r.per_flash);
            }
            std::vector<double> bolt, src, splat, acc, inv, total, nsrc, nact;
            const std::span<const int> dirs = subset ? std::span<const int>(r.side) : std::span<const int>(r.all_dirs);
            for (int rep_i = 0; rep_i < (r.ctx.quick ? 1 : 2); ++rep_i) {
                // Repeat pass: the bolts were dropped after their flash; rebuild the pipeline
                // so no regeneration lands in the timed frames.
                runtime::FramePipeline q = r.pipeline();
                for (int k = 0; k < r.seeds; ++k) q.strike_at(r.spacing * k, std::uint64_t(1000 + k));
                for (const double t : times) {
                    const runtime::Frame& f = q.build(t, dirs, ro);
                    if (!f.lit) continue;
                    bolt.push_back(f.times.bolt);
                    src.push_back(f.times.sources);
                    splat.push_back(f.times.splat);
                    acc.push_back(f.times.accumulate);
                    inv.push_back(f.times.inverse_haar);
                    total.push_back(f.times.total());
                    nsrc.push_back(double(f.sources.size()));
                    nact.push_back(double(f.weights.active.size()));
                }
            }
            nlohmann::json j = base;
            j["threads"] = threads;
            if (threads > 1) j["parallel_min_work"] = mode.min_work;
            j["directions"] = subset ? int(r.side.size()) : int(r.bases.directions().size());
            if (subset) j["direction_indices"] = r.side;
            j["lit_frames"] = total.size();
            j["median_ms"] = {{"bolt", bench::median(bolt)},        {"sources", bench::median(src)},
                              {"splat", bench::median(splat)},      {"accumulate", bench::median(acc)},
                              {"inverse_haar", bench::median(inv)}, {"total", bench::median(total)}};
            j["p90_total_ms"] = pct(total, 0.9);
            j["median_sources"] = bench::median(nsrc);
            j["median_active_lights"] = bench::median(nact);
            j["paper_seconds"] = 0.06;
            j["paper_machine"] = "Pentium 4 3.5 GHz, all 26 directions (Dobashi 2007, Table 2)";
            j["target_ms_one_core"] = r.c.label.rfind("paper", 0) == 0 ? 1.0 : 10.0;
            r.ctx.emit("frame", j);
        }
    }
}

// Worst case: every virtual light active (10,000 sources spread over the light grid's box:
// many simultaneous strikes). The paper's cost argument: the frame's cost is bounded by the
// number of lights, not of strokes.
void every_light_active(const Run& r, const nlohmann::json& base) {
    const basis::VirtualLightGrid& v = r.bases.lights();
    const glm::dvec3 lo(v.x.front(), v.y.front(), v.z.front()), hi(v.x.back(), v.y.back(), v.z.back());
    core::Rng rng(5, 9);
    std::vector<transport::PointSource> q;
    for (int i = 0; i < 10000; ++i)
        q.push_back({lo + (hi - lo) * glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()), 1e5});
    const lightning::Splatter sp(v);
    lightning::LightWeights w;
    for (const int threads : {1, 2}) {
        if (threads > r.ctx.max_threads) continue;
        core::set_thread_count(threads);
        runtime::Reconstructor rec(r.bases);
        for (const bool subset : {false, true}) {
            std::vector<double> sp_ms, acc, inv;
            runtime::RadianceField out;
            for (int repeat = 0; repeat < (r.ctx.quick ? 3 : 9); ++repeat) {
                core::Stopwatch sw;
                sp.splat(q, w);
                sp_ms.push_back(sw.milliseconds());
                runtime::StageTimes st;
                rec.reconstruct(w, subset ? std::span<const int>(r.side) : std::span<const int>(r.all_dirs), {}, out,
                                st);
                acc.push_back(st.accumulate);
                inv.push_back(st.inverse_haar);
            }
            nlohmann::json j = base;
            j["case"] = "every light active (10,000 sources)";
            j["threads"] = threads;
            j["directions"] = subset ? int(r.side.size()) : int(r.bases.directions().size());
            j["active_lights"] = w.active.size();
            j["median_ms"] = {{"splat", bench::median(sp_ms)},
                              {"accumulate", bench::median(acc)},
                              {"inverse_haar", bench::median(inv)}};
            r.ctx.emit("frame", j);
        }
    }
}

// Each quality preset on the same strikes (return-stroke peak + 2 ms): the frame once the
// strike's own solve is ready (the preset's steady cost), the solve's latency, and the ratio
// of frame times to the paper preset's in this run.
void quality_presets(const Run& r, const nlohmann::json& base) {
    const int strikes = r.ctx.quick ? 2 : 5;
    double paper_ms = 0.0;
    for (std::string_view name : scene::kInteractiveQualityPresets) {
        core::set_thread_count(r.ctx.max_threads);
        std::vector<double> frame_ms, solve_s;
        for (int k = 0; k < strikes; ++k) {
            runtime::FramePipeline p(r.s, r.c.config.density, r.bases, r.domain, scene::quality_preset(name));
            const std::size_t i = p.strike_at(0.0, std::uint64_t(3000 + k));
            const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
            runtime::ReconstructOptions o;
            o.wait_for_strikes = true;
            (void)p.build(t, r.all_dirs, o);  // waits for the strike's solve
            std::vector<double> b;
            for (int repeat = 0; repeat < 6; ++repeat) b.push_back(p.build(t, r.all_dirs, o).times.total());
            frame_ms.push_back(bench::median(b));
            if (runtime::StrikeSolver* solver = p.strike_solver())
                for (const double l : solver->latencies()) solve_s.push_back(l);
            if (runtime::InstantStrikes* is = p.instant_strikes())  // to its noise target
                if (const auto e = is->get(std::uint64_t(3000 + k), p.storm().strike(i).time))
                    solve_s.push_back(e->since_request);
        }
        const double ms = bench::median(frame_ms);
        if (std::string_view(name) == "paper") paper_ms = ms;
        nlohmann::json j = base;
        j["threads"] = r.ctx.max_threads;
        j["comparison"] = "quality preset, all directions, strike solved";
        j["preset"] = name;
        j["strikes"] = strikes;
        j["frame_ms"] = ms;
        j["ratio_to_paper"] = paper_ms > 0.0 ? ms / paper_ms : 0.0;
        j["strike_solve_s"] = solve_s.empty() ? 0.0 : bench::median(solve_s);
        r.ctx.emit("frame", j);
    }
}

// Direct solve vs basis frame on the same frames (return-stroke peak + 2 ms).
void direct_vs_basis(const Run& r, const nlohmann::json& base) {
    const int direct_frames = r.ctx.quick ? 1 : 3;
    for (const int threads : {1, 2}) {
        if (threads > r.ctx.max_threads) continue;
        core::set_thread_count(threads);
        std::vector<double> direct_s, basis_ms, nsrc;
        for (int k = 0; k < direct_frames; ++k) {
            runtime::FramePipeline p = r.pipeline();
            const std::size_t i = p.strike_at(0.0, std::uint64_t(2000 + k));
            const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
            std::vector<double> b;
            std::vector<transport::PointSource> sources;
            for (int repeat = 0; repeat < 5; ++repeat) {  // the first frame pays the bolt's first query
                const runtime::Frame& f = p.build(t, {});
                b.push_back(f.times.total());
                sources = f.sources;
            }
            basis_ms.push_back(bench::median(b));
            nsrc.push_back(double(sources.size()));
            core::Stopwatch sw;
            const transport::SourceField ref = runtime::direct_solve(r.s, r.media, sources);
            direct_s.push_back(sw.seconds());
        }
        nlohmann::json j = base;
        j["threads"] = threads;
        j["comparison"] = "direct solve vs basis frame, all 26 directions";
        j["frames"] = direct_frames;
        j["median_sources"] = bench::median(nsrc);
        j["direct_solve_s"] = bench::median(direct_s);
        j["basis_frame_ms"] = bench::median(basis_ms);
        j["speedup"] = bench::median(direct_s) * 1e3 / bench::median(basis_ms);
        j["paper_speedup"] = "30-60 (0.06 s vs 2.1-3.4 s)";
        j["target_speedup"] = 300;
        r.ctx.emit("frame", j);
    }
}

// One configuration: bake, then each measurement in turn, all on the same bases and strikes.
void run_config(const bench::Context& ctx, Case& c, const lightning::LightningParams& storm_lightning, double bw) {
    const Baked baked = bake_and_load(ctx, c);
    const Run r(ctx, c, baked.bases, storm_lightning);
    const nlohmann::json base = base_fields(r, baked, bw);
    stage_times(r, base);
    every_light_active(r, base);
    quality_presets(r, base);
    direct_vs_basis(r, base);
}

}  // namespace

FULGUR_BENCH(frame,
             "run time per frame (bolt, sources, splat, accumulate, inverse Haar), paper config and 64x64x16, "
             "1 and 2 threads, vs the direct solve") {
    const int saved = core::thread_count();
    const double bw = bench::measure_bandwidth(ctx.max_threads);
    const scene::Scene storm = scene::load_scene(storm_scene());
    std::vector<Case> cases;
    {
        Case a{"paper 32x32x4, 20x20x7 lights", bench::paper_config(32, 4, 0.9999)};
        if (ctx.quick) {  // every other light in x and y: 10x10x7, a quarter of the bake
            basis::VirtualLightGrid& v = a.config.plan.lights;
            std::vector<double> x, y;
            for (std::size_t i = 0; i < v.x.size(); i += 2) x.push_back(v.x[i]), y.push_back(v.y[i]);
            v.x = x;
            v.y = y;
            a.config.plan.metadata.lights = v;
            a.label = "paper 32x32x4, 10x10x7 lights (quick)";
        }
        cases.push_back(std::move(a));
    }
    if (!ctx.quick) cases.push_back({"64x64x16, 20x20x7 lights", bench::paper_config(64, 16, 0.9999)});
    for (Case& c : cases) run_config(ctx, c, storm.lightning, bw);
    core::set_thread_count(saved);
}
