// fulgur-bench instant: the instant preset's progressive strike solve on the default storm
// (content/scenes/storm.json, baked beside the scene if stale).
//
//   paths: Monte Carlo cost per path of each part (single: expected-value uncollided only;
//     multiple: whole paths), 1 and 2 threads, and the cost of one estimate (result()); in the
//     cloud alone and, as InstantStrikes traces a scene with rain, in the cloud with
//     content/scenes/storm-full.json's rain (the same strike, the same run).
//   timeline: strikes nobody scheduled (seeds 1-3, lookahead 0): wall time from the request
//     to the first estimate, and the estimate's noise and weight against the bases at 16, 50,
//     100, 300 and 1000 ms.
//   near field: runtime::NearField's correction of a strike (both glow groups, the lights'
//     models kept) at 32 and 128 rays, and the lights' models once, against the paper frame
//     of the same strike in the same run.
//   strike diffusion: the correction as the instant preset makes it (runtime::StrikeDiffusion,
//     its single scattering cast through the full-resolution density with 128 rays, and through
//     the lighting grid with 32; the two groups at once, one per core) per strike, and the
//     main channel's group alone on one thread, against the same paper frame.
//   frame: the frame thread's cost (wall and the thread's own CPU time, median) while the
//     strike is being solved, instant against paper in the same run, all 26 directions and
//     the 8 a side view needs; for instant also over the frames that blend the bases in
//     (the estimate's weight under 1: the strokes' share of the bases is added).
#include "bench/bench.h"
#include "bench/default_storm.h"

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"
#include "sky/sky.h"

#include <time.h>

#include <array>
#include <chrono>
#include <thread>

using namespace fulgur;

namespace {

double thread_cpu_ms() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

}  // namespace

FULGUR_BENCH(instant,
             "instant preset on the default storm: Monte Carlo cost per path (1, 2 threads), first-estimate "
             "latency and noise over time for unscheduled strikes, the frame thread's cost against paper") {
    const bench::DefaultStorm storm = bench::default_storm();
    const scene::Scene& s = storm.scene;
    const core::Grid3<float>& density = storm.density;
    const runtime::BakedBases& bases = *storm.bases;
    const solve::Media media = solve::make_media(s, density);
    const int strikes = ctx.quick ? 1 : 3;
    const nlohmann::json base = {{"scene", "storm.json"}};

    // --- paths ---
    {
        runtime::FramePipeline probe(s, density, bases, {}, scene::quality_preset("paper"));
        const lightning::Bolt bolt = probe.storm().bolt(probe.strike_at(0.0, 1));
        const std::vector<transport::LineSource> lines = runtime::strike_line_sources(bolt);
        const transport::LightingMedium fine{density, s.medium};
        const transport::MonteCarloMedium tracing(fine, media.lighting.density.geom);
        const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
        // The medium with rain as InstantStrikes makes it (the truth's), its noise over the cloud.
        scene::Scene wet_scene = s;
        wet_scene.rain =
            scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm-full.json").rain;
        const solve::Media wet = sky::make_static_media(wet_scene, density, 1, true);
        const transport::MonteCarloMedium wet_tracing(wet.full, media.lighting.density.geom);
        for (const int threads : {1, 2})
            for (const bool rain : {false, true}) {
                if (threads > ctx.max_threads) continue;
                core::set_thread_count(threads);
                for (const bool whole : {false, true}) {
                    transport::MonteCarloOptions o;
                    o.groups = 2;
                    if (rain) {
                        o.phase_mix = wet.lighting.phase_mix.get();
                        o.noise_cells = &tracing.cloud();
                    }
                    if (!whole) {
                        o.max_scatterings = 0;
                        o.tally_multiple = false;
                        o.uncollided_only = true;
                    } else {
                        o.tally_single = false;  // as InstantStrikes traces them
                    }
                    transport::ProgressiveMonteCarlo p(rain ? wet_tracing : tracing, {}, lines, dirs, o);
                    const std::uint64_t n = (whole ? 4'000 : 20'000) / (ctx.quick ? 4 : 1);
                    p.advance(n);  // warm: first touch of the buffers
                    std::vector<double> us, result_ms;
                    for (int r = 0; r < 3; ++r) {
                        core::Stopwatch sw;
                        p.advance(n);
                        us.push_back(sw.seconds() * 1e6 / double(n));
                        sw.reset();
                        (void)p.result();
                        result_ms.push_back(sw.milliseconds());
                    }
                    nlohmann::json j = base;
                    j["part"] = whole ? "multiple (whole paths, order 1 not tallied)" : "single (uncollided)";
                    j["medium"] = rain ? "cloud and storm-full's rain" : "cloud";
                    j["threads"] = threads;
                    j["us_per_path_median"] = bench::median(us);
                    j["result_ms_median"] = bench::median(result_ms);
                    ctx.emit("instant_paths", j);
                }
            }
        core::set_thread_count(ctx.max_threads);
    }

    // --- timeline ---
    for (int k = 0; k < strikes; ++k) {
        const std::uint64_t seed = std::uint64_t(k + 1);
        runtime::FramePipeline probe(s, density, bases, {}, scene::quality_preset("paper"));
        const std::size_t i = probe.strike_at(0.0, seed);
        const lightning::Bolt bolt = probe.storm().bolt(i);
        const double start = probe.storm().strike(i).time;
        const runtime::InstantOptions io = runtime::instant_options(scene::quality_preset("instant"));
        runtime::InstantStrikes is(s, density, media, &bases, io, ctx.max_threads);
        core::Stopwatch sw;
        is.request(seed, start, bolt);
        double first_ms = -1.0;
        nlohmann::json at = nlohmann::json::array();
        const double marks[] = {16, 50, 100, 300, 1000};
        std::size_t next = 0;
        while (next < std::size(marks)) {
            std::this_thread::sleep_for(std::chrono::microseconds(500));
            const double now = sw.milliseconds();
            const auto e = is.get(seed, start);
            if (e && first_ms < 0.0) first_ms = now;
            if (now >= marks[next]) {
                at.push_back({{"ms", marks[next]},
                              {"noise", e ? e->light.noise.total : -1.0},
                              {"weight", e ? e->weight() : 0.0},
                              {"bases_error", e ? e->bases_error : -1.0},
                              {"single_paths", e ? e->single_paths : 0},
                              {"multiple_paths", e ? e->multiple_paths : 0}});
                ++next;
            }
        }
        nlohmann::json j = base;
        j["seed"] = seed;
        j["threads"] = ctx.max_threads;
        j["first_estimate_ms"] = first_ms;
        j["at"] = at;
        ctx.emit("instant_timeline", j);
    }

    // --- frame ---
    // Every strike of the latency study (docs/presets.md): the fifth's bases stay in the
    // blend longest (their error is the smallest) and its bolt lights the most virtual lights.
    const int frame_strikes = ctx.quick ? 1 : 5;
    for (const bool side : {false, true}) {
        const std::vector<int> dirs = side ? std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7} : std::vector<int>{};
        double paper_cpu = 0.0;
        for (const char* name : {"paper", "instant"}) {
            std::vector<double> wall, cpu, blending_cpu;
            for (int k = 0; k < frame_strikes; ++k) {
                scene::Quality q = scene::quality_preset(name);
                q.lookahead = 0.0;
                runtime::FramePipeline p(s, density, bases, {}, q);
                const std::size_t i = p.strike_at(0.0, std::uint64_t(k + 1));
                const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
                core::Stopwatch sw;
                for (int f = 0; f < (ctx.quick ? 12 : 30); ++f) {  // 60 fps while the strike is solved
                    const double c0 = thread_cpu_ms();
                    core::Stopwatch fw;
                    const runtime::Frame& built = p.build(t, dirs);
                    wall.push_back(fw.milliseconds());
                    cpu.push_back(thread_cpu_ms() - c0);
                    if (built.strikes_solved > 0 && built.instant_weight < 1.0) blending_cpu.push_back(cpu.back());
                    const double wait = double(f + 1) * 1000.0 / 60.0 - sw.milliseconds();
                    if (wait > 0.0) std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(wait));
                }
            }
            nlohmann::json j = base;
            j["preset"] = name;
            j["directions"] = side ? 8 : 26;
            j["threads"] = ctx.max_threads;
            j["frame_wall_ms_median"] = bench::median(wall);
            j["frame_thread_cpu_ms_median"] = bench::median(cpu);
            if (std::string_view(name) == "paper") paper_cpu = bench::median(cpu);
            j["cpu_ratio_to_paper"] = paper_cpu > 0.0 ? bench::median(cpu) / paper_cpu : 0.0;
            if (!blending_cpu.empty()) {
                j["blending_frames"] = blending_cpu.size();
                j["blending_frame_thread_cpu_ms_median"] = bench::median(blending_cpu);
                j["blending_cpu_ratio_to_paper"] = paper_cpu > 0.0 ? bench::median(blending_cpu) / paper_cpu : 0.0;
            }
            ctx.emit("instant_frame", j);
        }
    }

    // --- near field ---
    // The correction a strike's frames before its first estimate carry (runtime::NearField),
    // both glow groups, per strike once the lights' models are kept, against the paper frame
    // of the same strike (all 26 directions) in the same run.
    for (const int rays : {32, 128}) {
        runtime::NearFieldOptions no;
        no.rays = rays;
        const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
        const runtime::NearField nf(media.lighting, bases.lights(), dirs, no);
        core::Stopwatch lw;
        for (std::size_t l = 0; l < nf.light_count(); ++l) nf.keep_light(l);
        const double lights_ms = lw.milliseconds();
        std::vector<double> strike_ms, paper_ms;
        for (int k = 0; k < strikes; ++k) {
            runtime::FramePipeline p(s, density, bases, {}, scene::quality_preset("paper"));
            const std::size_t i = p.strike_at(0.0, std::uint64_t(k + 1));
            const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
            const lightning::Bolt bolt = p.storm().bolt(i);
            strike_ms.push_back(1e3 * bench::time_median(ctx.quick ? 1 : 5, [&] {
                                    for (std::size_t q = 0; q < 2; ++q) (void)nf.strokes(bolt, q);
                                }));
            paper_ms.push_back(1e3 * bench::time_median(ctx.quick ? 1 : 5, [&] { (void)p.build(t, {}); }));
        }
        nlohmann::json j = base;
        j["rays"] = rays;
        j["threads"] = ctx.max_threads;
        j["lights"] = nf.light_count();
        j["lights_ms"] = lights_ms;
        j["strike_ms_median"] = bench::median(strike_ms);
        j["paper_frame_ms_median"] = bench::median(paper_ms);
        j["ratio_to_paper_frame"] = bench::median(strike_ms) / std::max(1e-9, bench::median(paper_ms));
        ctx.emit("instant_near_field", j);
    }

    // --- the strike's diffusion solve ---
    // The correction as the instant preset makes it: runtime::StrikeDiffusion (its rays' single
    // scattering and its diffusion solve; NearField only for the points), the two glow groups at
    // once, one per core, per strike, against the paper frame of the same strike in the same
    // run; also the main channel's group alone on one thread, with its iterations. Its single
    // scattering cast through the full-resolution density (the instant preset's) and through
    // the lighting grid.
    {
        runtime::NearFieldOptions no;
        no.rays = 32;
        no.multiple = false;
        const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
        const runtime::NearField nf(media.lighting, bases.lights(), dirs, no);
        for (std::size_t l = 0; l < nf.light_count(); ++l) nf.keep_light(l);
        const transport::LightingMedium full{density, s.medium};
        for (const bool fine : {true, false}) {
            runtime::StrikeDiffusionOptions so;
            const runtime::StrikeDiffusion sd(media.lighting, bases, dirs, so, fine ? &full : nullptr);
            std::vector<double> correction_ms, diffusion_ms, paper_ms, iterations, points;
            for (int k = 0; k < strikes; ++k) {
                runtime::FramePipeline p(s, density, bases, {}, scene::quality_preset("paper"));
                const std::size_t i = p.strike_at(0.0, std::uint64_t(k + 1));
                const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
                const lightning::Bolt bolt = p.storm().bolt(i);
                const std::array<std::vector<transport::PointSource>, 2> src = {nf.stroke_sources(bolt, 0),
                                                                                nf.stroke_sources(bolt, 1)};
                correction_ms.push_back(1e3 * bench::time_median(ctx.quick ? 1 : 5, [&] {
                                            core::parallel_for_dynamic(0, 2, [&](std::int64_t q) {
                                                runtime::NearFieldParts part;
                                                if (!sd.replaces_single()) nf.add(src[std::size_t(q)], part);
                                                sd.add(src[std::size_t(q)], part);
                                            });
                                        }));
                diffusion_ms.push_back(1e3 * bench::time_median(ctx.quick ? 1 : 5, [&] {
                                           runtime::NearFieldParts part;
                                           sd.add(src[0], part);
                                       }));
                iterations.push_back(double(sd.last_iterations()));
                points.push_back(double(src[0].size() + src[1].size()));
                paper_ms.push_back(1e3 * bench::time_median(ctx.quick ? 1 : 5, [&] { (void)p.build(t, {}); }));
            }
            nlohmann::json j = base;
            j["single"] = fine ? "cast through the full-resolution density" : "cast through the lighting grid";
            j["rays"] = fine ? so.fine_rays : so.rays;
            j["threads"] = ctx.max_threads;
            j["correction_ms_median"] = bench::median(correction_ms);
            j["main_group_ms_median"] = bench::median(diffusion_ms);
            j["iterations_median"] = bench::median(iterations);
            j["points_median"] = bench::median(points);
            j["paper_frame_ms_median"] = bench::median(paper_ms);
            j["ratio_to_paper_frame"] = bench::median(correction_ms) / std::max(1e-9, bench::median(paper_ms));
            ctx.emit("instant_strike_diffusion", j);
        }
    }
}
