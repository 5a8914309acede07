// fulgur-bench bolt: the lightning module's per-frame costs on one thread — bolt
// generation, lit stretches + point sources, trilinear splatting (a typical bolt and 10,000
// sources), and the "which strikes are active" query. Baseline: splatting with a binary
// search per axis (the naive lookup) on the same sources. Cloud: the default storm's.
#include "bench/bench.h"

#include "basis/basis.h"
#include "cloud/cloud.h"
#include "core/core.h"
#include "lightning/lightning.h"

#include <algorithm>
#include <cmath>

using namespace fulgur;

namespace {

/// Dobashi section 5 style over the cloud's footprint: 400 m horizontally and above the
/// cloud base, wider layers below it.
basis::VirtualLightGrid bench_lights(const core::Grid3<float>& cloud) {
    basis::VirtualLightGrid v;
    const glm::dvec3 lo = cloud.geom.origin, hi = cloud.geom.upper();
    for (double x = lo.x; x <= hi.x + 1e-9; x += 400.0) v.x.push_back(x);
    for (double y = lo.y; y <= hi.y + 1e-9; y += 400.0) v.y.push_back(y);
    const double base = cloud::cloud_base_height(cloud);
    v.z = {0.0};
    for (double gap = 400.0, z = base; z - gap > v.z.back() + 200.0; gap *= 1.6) v.z.insert(v.z.begin() + 1, z - gap);
    for (double z = base; z <= hi.z + 1e-9; z += 400.0) v.z.push_back(z);
    std::sort(v.z.begin(), v.z.end());
    return v;
}

}  // namespace

FULGUR_BENCH(bolt, "lightning: bolt generation, point sources, splatting (typical bolt and 10k sources), 1 thread") {
    // The default storm's cloud (generated on all threads; the measurements use one).
    const auto cloud = cloud::generate_cumulonimbus(cloud::CumulonimbusParams{});
    core::set_thread_count(1);
    const auto lights = bench_lights(cloud);
    const lightning::Splatter splatter(lights);
    const int bolts = ctx.quick ? 10 : 60;
    const int repeats = ctx.quick ? 3 : 9;

    for (const lightning::Kind kind :
         {lightning::Kind::CloudToGround, lightning::Kind::IntraCloud, lightning::Kind::CloudToCloud}) {
        lightning::BoltParams p;
        p.kind = kind;
        const lightning::BoltGenerator gen(p, cloud);
        // Generation: median over seeds of the per-bolt time.
        std::vector<double> t_gen, t_src, t_splat, t_splat_bs;
        std::vector<double> segments, sources, lit_lights;
        lightning::FlashState peak;
        peak.main_glow = peak.branch_glow = 1.0;
        std::vector<lightning::LitSegment> lit;
        std::vector<transport::PointSource> q;
        lightning::LightWeights w;
        splatter.reset(w);
        for (int s = 1; s <= bolts; ++s) {
            core::Stopwatch sw;
            const lightning::Bolt b = gen.generate(std::uint64_t(s));
            t_gen.push_back(sw.seconds());
            segments.push_back(double(b.segments.size()));
            // Lit stretches + point sources at the return-stroke peak (repeat: microseconds).
            const int inner = 50;
            sw.reset();
            for (int r = 0; r < inner; ++r) {
                lit.clear();
                q.clear();
                lightning::lit_segments(b, peak, lit);
                lightning::append_point_sources(lit, splatter.source_spacing(), q);
            }
            t_src.push_back(sw.seconds() / inner);
            sources.push_back(double(q.size()));
            sw.reset();
            for (int r = 0; r < inner; ++r) splatter.splat(q, w);
            t_splat.push_back(sw.seconds() / inner);
            lit_lights.push_back(double(w.active.size()));
            sw.reset();
            for (int r = 0; r < inner; ++r) {
                splatter.reset(w);
                splatter.accumulate_binary_search(q, w);
            }
            t_splat_bs.push_back(sw.seconds() / inner);
        }
        ctx.emit("bolt", {{"case", "typical_bolt"},
                          {"kind", std::string(lightning::kind_name(kind))},
                          {"threads", 1},
                          {"bolts", bolts},
                          {"median_segments", bench::median(segments)},
                          {"median_point_sources", bench::median(sources)},
                          {"median_active_lights", bench::median(lit_lights)},
                          {"generate_ms", 1e3 * bench::median(t_gen)},
                          {"point_sources_ms", 1e3 * bench::median(t_src)},
                          {"splat_ms", 1e3 * bench::median(t_splat)},
                          {"baseline_splat_binary_search_ms", 1e3 * bench::median(t_splat_bs)}});
    }

    // 10,000 point sources spread over the light grid's box (some outside it).
    {
        core::Rng r(1, 1);
        std::vector<transport::PointSource> q(10000);
        for (auto& s : q) {
            // The light grid's box grown by 5% per side: ~10% of the sources fall outside.
            const glm::dvec3 lo(lights.x.front(), lights.y.front(), lights.z.front());
            const glm::dvec3 hi(lights.x.back(), lights.y.back(), lights.z.back());
            const glm::dvec3 pad = 0.05 * (hi - lo);
            s.position = lo - pad + glm::dvec3(r.uniform(), r.uniform(), r.uniform()) * (hi - lo + 2.0 * pad);
            s.intensity = 1e5 * r.uniform();
        }
        lightning::LightWeights w;
        const int inner = ctx.quick ? 5 : 50;
        const double lut = bench::time_median(repeats,
                                              [&] {
                                                  for (int k = 0; k < inner; ++k) splatter.splat(q, w);
                                              }) /
                           inner;
        const double bs = bench::time_median(repeats,
                                             [&] {
                                                 for (int k = 0; k < inner; ++k) {
                                                     splatter.reset(w);
                                                     splatter.accumulate_binary_search(q, w);
                                                 }
                                             }) /
                          inner;
        ctx.emit("bolt", {{"case", "10k_sources"},
                          {"grid", {lights.x.size(), lights.y.size(), lights.z.size()}},
                          {"threads", 1},
                          {"lights", splatter.light_count()},
                          {"active_lights", w.active.size()},
                          {"clamped", w.clamped},
                          {"splat_ms", 1e3 * lut},
                          {"ns_per_source", 1e9 * lut / 1e4},
                          {"baseline_splat_binary_search_ms", 1e3 * bs}});
    }

    // The per-frame schedule query over a long storm (about 720 strikes in an hour).
    {
        lightning::LightningParams p;
        p.schedule.strike_rate = 0.2;
        p.bolt.max_depth = 1;
        lightning::Storm storm(p, cloud);
        core::Stopwatch sw;
        storm.active(3600.0);  // schedules (and generates) every strike of the hour
        const double schedule_s = sw.seconds();
        const int frames = 60 * 60;  // one minute at 60 fps, late in the hour
        std::size_t lit_frames = 0;
        const double t = bench::time_median(repeats, [&] {
            lit_frames = 0;
            for (int f = 0; f < frames; ++f) lit_frames += storm.any_active(3000.0 + f / 60.0);
        });
        ctx.emit("bolt", {{"case", "active_query"},
                          {"threads", 1},
                          {"strikes", storm.strike_count()},
                          {"schedule_hour_s", schedule_s},
                          {"query_us", 1e6 * t / frames},
                          {"lit_frames_per_minute", lit_frames}});
    }
}
