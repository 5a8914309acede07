// How soon a strike nobody scheduled is lit right.
//   latency: for the default storm (5 strikes), dusk-storm and vdb-cloud (3 strikes each), each
//   strike at its first return stroke + 2 ms, each preset's frame (and instant's without its
//   near-field correction: instant_no_near_field; with the correction's multiple part by the
//   kernel instead of the strike's diffusion solve: instant_kernel; with 128 rays per point
//   instead of 32: instant_128; with the strike's single scattering cast through the lighting
//   grid instead of the full-resolution density: instant_lighting_single) as it is shown X ms of wall
//   time after the strike became known (X = 0, 16, 50, 100, 300, 1000; lookahead 0; frames
//   built at 60 fps meanwhile: runtime::build_since_known), against the truth of that frame
//   (runtime::truth): relative L2 of S over the cloud voxels, all directions. Also the frame
//   thread's cost while the strike is being solved (median build), the instant preset's
//   weight of its own estimate, and the worker's wall and CPU time so far.
//   Also each strike triggered at its leader's start with the storm clock running (the frames
//   of its leader built at their own time, 60 fps), its return stroke's frame against the same
//   truth: what a "Strike now" shows when the flash is brightest.
//   Outputs: latency.csv (one row per scene, preset, strike and X), latency_summary.csv
//   (worst strike per scene, preset and X), latency_leader.csv (one row per scene, preset and
//   strike triggered at its leader's start); scripts/plot_studies.py draws the curves.
//   --quick: the default storm, 2 strikes, 3 latencies, fewer truth paths.
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>

using namespace fulgur;
using study::cached_truth;
using study::cloud_error;
using study::flat;

FULGUR_STUDY(latency, "latency",
             "each preset's error against the truth as a function of wall time since an unscheduled strike became "
             "known (0-1000 ms, lookahead 0, frames at 60 fps meanwhile), default storm, dusk-storm and vdb-cloud; "
             "the frame thread's cost and the solver's time") {
    struct Case {
        std::string file;
        int strikes;
    };
    std::vector<Case> cases = {{"storm.json", 5}, {"dusk-storm.json", 3}, {"vdb-cloud.json", 3}};
    std::vector<double> latencies = {0, 16, 50, 100, 300, 1000};
    // Configurations: the presets, and the instant preset without its near-field correction,
    // with the kernel's multiple part, with 128 rays (what each buys at each latency, measured
    // in the same run).
    std::vector<std::string> presets = {
        "paper",       "per_strike_mc",          "instant", "instant_kernel", "instant_no_near_field",
        "instant_128", "instant_lighting_single"};
    std::uint64_t truth_paths = 2'000'000;
    if (ctx.quick) {
        cases = {{"storm.json", 2}};
        latencies = {0, 100, 300};
        truth_paths = 300'000;
    }
    if (!ctx.only.empty()) {
        std::erase_if(presets, [&](const std::string& p) { return ctx.only.find(p) == std::string::npos; });
        if (presets.empty())
            throw core::Error("--only",
                              "names no configuration of paper, per_strike_mc, instant, instant_kernel, "
                              "instant_no_near_field, instant_128, instant_lighting_single");
    }

    study::Csv rows(ctx.file("latency.csv"),
                    {"scene", "preset", "seed", "since_known_ms", "error_vs_truth", "frame_ms_median", "frame_ms_max",
                     "frames", "instant_weight", "worker_s", "single_paths", "multiple_paths", "estimate_noise",
                     "bases_error", "truth_noise"});
    // A strike triggered at its leader's start with the storm clock running: the return
    // stroke's frame (+2 ms) as a frame loop shows it, the leader's frames built meanwhile
    // (what the demo's "Strike now" and a game event that starts a whole flash get).
    study::Csv leader_rows(ctx.file("latency_leader.csv"),
                           {"scene", "preset", "seed", "leader_ms", "error_vs_truth", "frames", "instant_weight",
                            "worker_s", "single_paths", "multiple_paths", "estimate_noise"});
    study::Csv summary(ctx.file("latency_summary.csv"),
                       {"scene", "preset", "since_known_ms", "worst_error", "median_error", "frame_ms_median"});
    nlohmann::json out = nlohmann::json::array();
    for (const Case& c : cases) {
        std::fprintf(stderr, "latency: %s: bake\n", c.file.c_str());
        const study::StrikeScene prepared = study::strike_scene(c.file);
        const auto& [s, density, bases, media] = prepared;
        const std::vector<float>& rho = media.lighting.density.data;
        std::map<std::pair<std::string, double>, std::vector<double>> errors, frame_ms;
        std::map<std::string, std::vector<double>> leader_errors;
        for (int k = 0; k < c.strikes; ++k) {
            const std::uint64_t seed = std::uint64_t(k + 1);
            // The truth of the frame (from a paper pipeline: the lit channel does not depend on
            // the preset).
            std::fprintf(stderr, "latency: %s: truth of strike %llu\n", c.file.c_str(),
                         static_cast<unsigned long long>(seed));
            const study::StrikeFrame sf =
                study::strike_frame(ctx, prepared, std::filesystem::path(c.file).stem().string(), seed, truth_paths);
            const double t = sf.time;
            const runtime::Truth& truth = sf.truth;
            const transport::SourceField tt = truth.sum();
            for (const std::string& name : presets) {
                const bool variant = name.starts_with("instant_");
                scene::Quality q = scene::quality_preset(variant ? "instant" : name);
                if (name == "instant_no_near_field") q.near_field_rays = 0;
                if (name == "instant_kernel") q.near_field_multiple = "kernel";
                if (name == "instant_128") q.near_field_rays = 128;
                if (name == "instant_lighting_single") q.near_field_fine_rays = 0;
                q.lookahead = 0.0;  // nobody scheduled it
                // The latencies, then (x < 0) the strike triggered at its leader's start.
                std::vector<double> xs = latencies;
                xs.push_back(-1.0);
                for (const double x_or_leader : xs) {
                    runtime::FramePipeline p(s, density, bases, {}, q);
                    const bool leader = x_or_leader < 0.0;
                    // Triggered at its leader's start: an unscheduled strike, as "Strike now".
                    const double start = p.storm().strike(p.strike_at(0.0, seed, !leader)).time;
                    const double x = leader ? (t - start) * 1000.0 : x_or_leader;
                    runtime::SinceKnown seen;
                    const runtime::Frame& f = runtime::build_since_known(p, t, x, {}, {}, &seen, leader);
                    const double e = cloud_error(flat(f.radiance), tt.data, rho);
                    double worker_s = 0.0, noise = 0.0, eb = -1.0, sp = 0.0, mp = 0.0;
                    if (runtime::InstantStrikes* is = p.instant_strikes()) {
                        if (const auto est = is->get(seed, start)) {
                            worker_s = est->worker_seconds;
                            noise = est->light.noise.total;
                            eb = est->bases_error;
                            sp = double(est->single_paths);
                            mp = double(est->multiple_paths);
                        }
                        is->set_paused(true);
                    } else if (runtime::StrikeSolver* ss = p.strike_solver()) {
                        if (const auto L = ss->get(seed, start))
                            worker_s = L->seconds_single + L->seconds_multiple + L->seconds_ground;
                        ss->set_paused(true);
                    }
                    if (leader) {
                        leader_rows << std::filesystem::path(c.file).stem().string() << name << double(seed) << x << e
                                    << double(seen.frames) << f.instant_weight << worker_s << sp << mp << noise;
                        leader_rows.end_row();
                        leader_errors[name].push_back(e);
                        std::fprintf(stderr,
                                     "latency: %-16s %-14s seed %llu triggered at its leader's start, %.0f ms before "
                                     "its return stroke: error %.3f (weight %.2f, noise %.3f)\n",
                                     c.file.c_str(), name.c_str(), static_cast<unsigned long long>(seed), x, e,
                                     f.instant_weight, noise);
                        continue;
                    }
                    rows << std::filesystem::path(c.file).stem().string() << name << double(seed) << x << e
                         << seen.median_frame_ms << seen.max_frame_ms << double(seen.frames) << f.instant_weight
                         << worker_s << sp << mp << noise << eb << truth.noise.total;
                    rows.end_row();
                    errors[{name, x}].push_back(e);
                    frame_ms[{name, x}].push_back(seen.median_frame_ms);
                    std::fprintf(stderr,
                                 "latency: %-16s %-14s seed %llu at %5.0f ms: error %.3f (weight %.2f, noise %.3f, "
                                 "bases %.3f), frame %.2f ms\n",
                                 c.file.c_str(), name.c_str(), static_cast<unsigned long long>(seed), x, e,
                                 f.instant_weight, noise, eb, seen.median_frame_ms);
                }
            }
        }
        for (const std::string& name : presets)
            for (const double x : latencies) {
                std::vector<double> v = errors[{name, x}], ms = frame_ms[{name, x}];
                std::sort(v.begin(), v.end());
                std::sort(ms.begin(), ms.end());
                summary << std::filesystem::path(c.file).stem().string() << name << x << v.back() << v[v.size() / 2]
                        << ms[ms.size() / 2];
                summary.end_row();
                out.push_back({{"scene", c.file}, {"preset", name}, {"since_known_ms", x}, {"worst_error", v.back()}});
            }
        for (const std::string& name : presets) {
            const std::vector<double>& v = leader_errors[name];
            out.push_back({{"scene", c.file},
                           {"preset", name},
                           {"triggered_at_leader_start", true},
                           {"worst_error", *std::max_element(v.begin(), v.end())}});
        }
    }
    ctx.summary("latency", {{"rows", out}, {"truth_paths", truth_paths}});
}
