// fulgur-bench strike_grid: what keeping the solved strikes on the per-strike transport grid
// (quality.grid "transport") costs on the default storm (content/scenes/storm.json, baked
// beside the scene if stale), against the same preset on the lighting grid in the same run.
//
// Per configuration (per_strike_mc on the 750 m lighting grid; per_strike_mc kept on the grid
// refined by 2 and by 3, and by 3 tallied toward the camera), on the same strikes (return-stroke peak + 2 ms): the strike's solve
// (wall time from request to ready), the frame once it is solved (FramePipeline::build: the
// bases' reconstruction, the upsample onto the finer grid and the strikes' light added on both
// grids; median of repeats) for all 26 directions and for a side view's share of them,
// and the bytes a strike's light and a frame hold. What it buys is measured against Cycles
// (docs/presets.md, "Where a solved strike's S is kept").
#include "bench/bench.h"
#include "bench/default_storm.h"

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <glm/geometric.hpp>

using namespace fulgur;

namespace {

std::size_t field_bytes(const transport::SourceField& f) { return f.data.size() * sizeof(float); }

std::size_t light_bytes(const runtime::StrikeLight& l) {
    std::size_t b = 0;
    for (std::size_t q = 0; q < 2; ++q)
        b += field_bytes(l.single[q]) + field_bytes(l.multiple[q]) + field_bytes(l.fine_single[q]) +
             field_bytes(l.fine_multiple[q]);
    return b;
}

std::size_t frame_bytes(const runtime::Frame& f) {
    std::size_t b = 0;
    for (const auto& v : f.radiance.values) b += v.size() * sizeof(float);
    for (const auto& v : f.fine.values) b += v.size() * sizeof(float);
    return b;
}

}  // namespace

FULGUR_BENCH(strike_grid,
             "solved strikes kept on the per-strike transport grid (quality.grid) on the default storm: the "
             "strike's solve, the frame and the memory against the lighting grid in the same run") {
    const bench::DefaultStorm storm = bench::default_storm();
    const scene::Scene& s = storm.scene;
    const core::Grid3<float>& density = storm.density;
    const runtime::BakedBases& bases = *storm.bases;
    const int strikes = ctx.quick ? 1 : 3, repeats = ctx.quick ? 3 : 7;
    // A side view's share of the directions: those within 60 degrees of the direction toward
    // the default camera (-y: the orbit's azimuth -90, nearly level).
    std::vector<int> side;
    const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
    for (std::size_t m = 0; m < dirs.size(); ++m)
        if (glm::dot(glm::normalize(dirs[m]), glm::dvec3(0.0, -1.0, 0.0)) > 0.5) side.push_back(int(m));
    core::set_thread_count(ctx.max_threads);

    struct Row {
        std::string name;
        int refine = 1;
        double solve_s = 0.0, frame_all_ms = 0.0, frame_side_ms = 0.0, light_mb = 0.0, frame_mb = 0.0;
    };
    std::vector<Row> rows;
    // The last configuration also tallies the strike toward the scene's camera (quality
    // "directions": "camera"): one phase per deposit instead of 26.
    for (const auto& [refine, toward] :
         {std::pair{1, false}, std::pair{2, false}, std::pair{3, false}, std::pair{3, true}}) {
        if (refine > 1 && s.lighting_downsample % refine != 0) continue;
        scene::Quality q = scene::quality_preset("per_strike_mc");
        if (refine > 1) {
            q.keep_transport_grid = true;
            q.refine = refine;
        }
        q.toward_camera = toward;
        Row r;
        r.name = refine == 1 ? "per_strike_mc, lighting grid"
                             : "per_strike_mc, kept on the grid refined by " + std::to_string(refine) +
                                   (toward ? ", toward the camera" : "");
        r.refine = refine;
        std::vector<double> solve, all, part, light, frame;
        for (int k = 0; k < strikes; ++k) {
            runtime::FramePipeline p(s, density, bases, {}, q);
            const std::size_t i = p.strike_at(0.0, std::uint64_t(1 + k));
            const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
            runtime::ReconstructOptions o;
            o.wait_for_strikes = true;
            (void)p.build(t, {}, o);  // waits for the strike's solve
            for (const double l : p.strike_solver()->latencies()) solve.push_back(l);
            std::vector<double> a, b;
            for (int n = 0; n < repeats; ++n) a.push_back(p.build(t, {}, o).times.total());
            frame.push_back(double(frame_bytes(p.build(t, {}, o))));
            for (int n = 0; n < repeats; ++n) b.push_back(p.build(t, side, o).times.total());
            all.push_back(bench::median(a));
            part.push_back(bench::median(b));
            const lightning::Strike& st = p.storm().strike(i);
            if (const auto l = p.strike_solver()->get(st.seed, st.time)) light.push_back(double(light_bytes(*l)));
        }
        r.solve_s = bench::median(solve);
        r.frame_all_ms = bench::median(all);
        r.frame_side_ms = bench::median(part);
        r.light_mb = light.empty() ? 0.0 : bench::median(light) / 1e6;
        r.frame_mb = bench::median(frame) / 1e6;
        rows.push_back(r);
    }
    for (const Row& r : rows) {
        const Row& b = rows.front();
        nlohmann::json j = {{"scene", "storm.json"}, {"threads", ctx.max_threads}, {"strikes", strikes}};
        j["case"] = r.name;
        j["refine"] = r.refine;
        j["strike_solve_s"] = r.solve_s;
        j["frame_all_directions_ms"] = r.frame_all_ms;
        j["frame_side_view_ms"] = r.frame_side_ms;
        j["side_view_directions"] = side.size();
        j["strike_light_mb"] = r.light_mb;
        j["frame_mb"] = r.frame_mb;
        j["baseline"] = b.name;
        j["solve_ratio"] = b.solve_s > 0.0 ? r.solve_s / b.solve_s : 0.0;
        j["frame_all_ratio"] = b.frame_all_ms > 0.0 ? r.frame_all_ms / b.frame_all_ms : 0.0;
        j["frame_side_ratio"] = b.frame_side_ms > 0.0 ? r.frame_side_ms / b.frame_side_ms : 0.0;
        ctx.emit("strike_grid", j);
    }
}
