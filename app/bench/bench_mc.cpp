// Monte Carlo paths/s and single-scattering voxels/s (per direction count) on 1 and 2 threads,
// and the single-scattering accuracy/time study behind docs/transport.md's table.
#include "bench/bench.h"
#include "bench/paper_config.h"

#include "cloud/cloud.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

namespace {

using namespace fulgur;
using namespace fulgur::transport;
using bench::dobashi_layer;
using bench::dobashi_lights;

std::filesystem::path storm_scene() { return std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json"; }

LightingMedium storm_medium() {
    const scene::Scene sc = scene::load_scene(storm_scene());
    return scene::make_lighting_medium(sc, scene::make_density(sc));
}

/// Every stride-th light of a list (deterministic subset for timing).
std::vector<glm::dvec3> every(const std::vector<glm::dvec3>& v, std::size_t stride, std::size_t offset = 0) {
    std::vector<glm::dvec3> s;
    for (std::size_t i = offset; i < v.size(); i += stride) s.push_back(v[i]);
    return s;
}

struct SsTiming {
    double seconds_per_light = 0.0;
};

SsTiming time_ss(const LightingMedium& m, const std::vector<glm::dvec3>& lights, int ndir, int threads, int repeats,
                 const SingleScatteringOptions& o) {
    core::set_thread_count(threads);
    SourceField f;
    f.directions = output_directions(ndir);
    const double t = bench::time_median(repeats, [&] {
        for (const auto& p : lights) single_scattering(m, PointSource{p, 1.0}, f, o);
    });
    return {t / double(lights.size())};
}

/// The naive baseline: S sampled at voxel centres (one DDA per voxel, no voxel average), as
/// a point-sampled method would do (and as Dobashi 2007 evaluates its direct term).
double naive_centre_seconds(const LightingMedium& m, const std::vector<glm::dvec3>& lights, int ndir, int threads) {
    core::set_thread_count(threads);
    const auto dirs = output_directions(ndir);
    const core::GridGeometry& g = m.density.geom;
    std::vector<float> out(g.cell_count() * dirs.size());
    core::Stopwatch w;
    for (const auto& p : lights)
        core::parallel_for(0, std::int64_t(g.cell_count()), [&](std::int64_t c) {
            const core::Int3 v = g.unindex(std::size_t(c));
            const glm::dvec3 x = g.centre(v.x, v.y, v.z), r = x - p;
            const double r2 = glm::dot(r, r), T = transmittance(m, p, x);
            for (std::size_t k = 0; k < dirs.size(); ++k)
                out[k * g.cell_count() + std::size_t(c)] =
                    float(m.optics.albedo * hg_phase(glm::dot(dirs[k], r) / std::sqrt(r2), m.optics.g) * T / r2);
        });
    return w.seconds() / double(lights.size());
}

}  // namespace

FULGUR_BENCH(mc, "Monte Carlo paths/s and single-scattering voxels/s (1, 6, 26 directions) on 1 and 2 threads") {
    const int repeats = ctx.quick ? 1 : 3;
    ctx.emit("mc", {{"baseline", "memory"}, {"threads", 1}, {"triad_GBps", bench::measure_bandwidth(1)}});

    // --- Monte Carlo on the default storm cloud (scene light, 26 directions) ------------------
    const LightingMedium storm = storm_medium();
    const scene::Scene sc = scene::load_scene(storm_scene());
    const PointSource light{sc.point_lights.at(0).position, 1.0};
    const auto dirs26 = output_directions(26);
    struct McRun {
        const char* what;
        int max_scatterings;
        std::uint64_t paths;
        int macro;
    };
    const std::uint64_t base = ctx.quick ? 20'000 : 200'000;
    for (const McRun run : {McRun{"full transport (all orders)", std::numeric_limits<int>::max(), base, 4},
                            McRun{"full transport, one global majorant", std::numeric_limits<int>::max(), base, 0},
                            McRun{"order 1 only (expected-value rays)", 0, base * 10, 4}}) {
        double rate[3] = {0, 0, 0};
        MonteCarloResult last;
        for (int t = 1; t <= std::min(2, ctx.max_threads); ++t) {
            core::set_thread_count(t);
            MonteCarloOptions o;
            o.paths = run.paths;
            o.max_scatterings = run.max_scatterings;
            o.macro_cell = run.macro;
            const double s = bench::time_median(repeats, [&] { last = monte_carlo(storm, light, dirs26, o); });
            rate[t] = double(run.paths) / s;
            ctx.emit("mc", {{"case", run.what},
                            {"grid", "36x36x20 storm"},
                            {"directions", 26},
                            {"threads", t},
                            {"paths", run.paths},
                            {"paths_per_s", rate[t]},
                            {"collisions_per_path", double(last.collisions) / double(run.paths)},
                            {"null_collisions_per_path", double(last.null_collisions) / double(run.paths)}});
        }
        if (rate[2] > 0) ctx.emit("mc", {{"case", run.what}, {"speedup_2t_over_1t", rate[2] / rate[1]}});
    }

    // --- Single scattering: voxels/s per direction count --------------------------------------
    struct SsCase {
        const char* what;
        LightingMedium medium;
        std::vector<glm::dvec3> lights;
        std::size_t total_lights;
    };
    std::vector<SsCase> cases;
    {
        std::vector<glm::dvec3> storm_lights;
        for (int k = 0; k < 4; ++k)
            for (int j = 0; j < 3; ++j)
                for (int i = 0; i < 3; ++i)
                    storm_lights.push_back(
                        {-6000.0 + 6000.0 * i + 170.0, -6000.0 + 6000.0 * j - 230.0, 500.0 + 2800.0 * k});
        cases.push_back(
            {"storm 36x36x20 (500 m)", storm, ctx.quick ? every(storm_lights, 12) : every(storm_lights, 3), 0});
    }
    const auto dl = dobashi_lights();
    cases.push_back({"Dobashi layer 32x32x4 (400 m), 2800 virtual lights", dobashi_layer(32, 4),
                     ctx.quick ? every(dl, 700, 13) : every(dl, 70, 13), dl.size()});
    cases.push_back({"Dobashi layer 64x64x16 (200 m), 2800 virtual lights", dobashi_layer(64, 16),
                     ctx.quick ? every(dl, 1400, 13) : every(dl, 350, 13), dl.size()});
    for (const SsCase& c : cases) {
        const std::size_t cells = c.medium.density.geom.cell_count();
        for (int ndir : {1, 6, 26}) {
            double spl[3] = {0, 0, 0};
            for (int t = 1; t <= std::min(2, ctx.max_threads); ++t) {
                const SsTiming tm = time_ss(c.medium, c.lights, ndir, t, repeats, SingleScatteringOptions{});
                spl[t] = tm.seconds_per_light;
                nlohmann::json j = {{"case", c.what},
                                    {"solver", "single_scattering"},
                                    {"tolerance", SingleScatteringOptions{}.tolerance},
                                    {"directions", ndir},
                                    {"threads", t},
                                    {"lights_timed", c.lights.size()},
                                    {"seconds_per_light", spl[t]},
                                    {"voxels_per_s", double(cells) / spl[t]}};
                if (c.total_lights) j["seconds_for_all_lights"] = spl[t] * double(c.total_lights);
                ctx.emit("mc", j);
            }
            if (spl[2] > 0)
                ctx.emit("mc", {{"case", c.what}, {"directions", ndir}, {"speedup_2t_over_1t", spl[1] / spl[2]}});
        }
        // Other tolerances (26 directions, 2 threads) and the naive centre-sample baseline.
        for (double tol : {1e-1, 1e-2}) {
            SingleScatteringOptions o;
            o.tolerance = tol;
            const SsTiming tm = time_ss(c.medium, c.lights, 26, std::min(2, ctx.max_threads), repeats, o);
            nlohmann::json j = {{"case", c.what},
                                {"solver", "single_scattering"},
                                {"tolerance", tol},
                                {"directions", 26},
                                {"threads", std::min(2, ctx.max_threads)},
                                {"seconds_per_light", tm.seconds_per_light},
                                {"voxels_per_s", double(cells) / tm.seconds_per_light}};
            if (c.total_lights) j["seconds_for_all_lights"] = tm.seconds_per_light * double(c.total_lights);
            ctx.emit("mc", j);
        }
        const double naive = naive_centre_seconds(c.medium, c.lights, 26, std::min(2, ctx.max_threads));
        nlohmann::json j = {{"case", c.what},
                            {"baseline", "naive centre sample (1 ray per voxel, not a voxel average)"},
                            {"directions", 26},
                            {"threads", std::min(2, ctx.max_threads)},
                            {"seconds_per_light", naive},
                            {"voxels_per_s", double(cells) / naive}};
        if (c.total_lights) j["seconds_for_all_lights"] = naive * double(c.total_lights);
        ctx.emit("mc", j);
    }
    core::set_thread_count(std::min(2, ctx.max_threads));
}

FULGUR_BENCH(ss_accuracy,
             "single-scattering error vs time per tolerance on the storm cloud against a brute-force reference "
             "(docs/transport.md table)") {
    const LightingMedium m = storm_medium();
    const scene::Scene sc = scene::load_scene(storm_scene());
    const auto dirs = output_directions(26);
    std::vector<glm::dvec3> lights = {
        sc.point_lights.at(0).position, {2170.0, -1730.0, 3300.0}, {-6230.0, 770.0, 6100.0}, {430.0, 260.0, 4100.0}};
    if (ctx.quick) lights.resize(1);
    const core::GridGeometry& g = m.density.geom;
    const std::size_t cells = g.cell_count(), nd = dirs.size();
    // The reference: single_scattering_reference (the voxel in 16^3 cells, 3^3 Gauss nodes each,
    // nothing of the quadrature's planning) on a sample of the cloud's voxels: every stride-th
    // voxel holding density, and the light's 27 (where they hold density). Its own error is
    // estimated from the same voxels in 8^3 cells (it falls as the cube of the cell size, so the
    // 16^3 value is ~8x closer than the 8^3 one).
    const int ref_cells = ctx.quick ? 8 : 16;
    const std::size_t want = ctx.quick ? 40 : 250;
    std::vector<std::size_t> cloud;
    for (std::size_t c = 0; c < cells; ++c)
        if (m.density.data[c] > 0.0f) cloud.push_back(c);
    const std::size_t stride = std::max<std::size_t>(1, cloud.size() / want);
    core::set_thread_count(2);
    struct Sample {
        std::vector<std::size_t> voxels;
        std::vector<double> ref, ref_coarse;  // [voxel][direction]
    };
    std::vector<Sample> samples(lights.size());
    core::Stopwatch ref_clock;
    for (std::size_t l = 0; l < lights.size(); ++l) {
        Sample& smp = samples[l];
        for (std::size_t i = (l * 7) % stride; i < cloud.size(); i += stride) smp.voxels.push_back(cloud[i]);
        const core::Int3 lv = g.clamped_voxel(lights[l]);
        for (int dz = -1; dz <= 1 && g.contains(lights[l]); ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const core::Int3 v{lv.x + dx, lv.y + dy, lv.z + dz};
                    if (v.x < 0 || v.y < 0 || v.z < 0 || v.x >= g.dims.x || v.y >= g.dims.y || v.z >= g.dims.z)
                        continue;
                    const std::size_t c = g.index(v.x, v.y, v.z);
                    if (m.density.data[c] > 0.0f &&
                        std::find(smp.voxels.begin(), smp.voxels.end(), c) == smp.voxels.end())
                        smp.voxels.push_back(c);
                }
        smp.ref.assign(smp.voxels.size() * nd, 0.0);
        smp.ref_coarse.assign(smp.voxels.size() * nd, 0.0);
        core::parallel_for_dynamic(0, std::int64_t(smp.voxels.size()), [&](std::int64_t i) {
            const core::Int3 v = g.unindex(smp.voxels[std::size_t(i)]);
            const auto fine = single_scattering_reference(m, PointSource{lights[l], 1.0}, dirs, v, ref_cells);
            const auto coarse = single_scattering_reference(m, PointSource{lights[l], 1.0}, dirs, v, ref_cells / 2);
            std::copy(fine.begin(), fine.end(), smp.ref.begin() + i * std::ptrdiff_t(nd));
            std::copy(coarse.begin(), coarse.end(), smp.ref_coarse.begin() + i * std::ptrdiff_t(nd));
        });
    }
    const double ref_seconds = ref_clock.seconds();
    core::set_thread_count(1);
    // Errors over the sampled voxel-directions: L1 (energy-weighted), the median and 99th
    // percentile of the relative error, the largest where S > 1e-3 of the light's largest.
    struct Errors {
        double l1 = 0.0, p50 = 0.0, p99 = 0.0, max_bright = 0.0;
    };
    // over: one sample per light (its voxels and reference); value_of(l, i, d) the value tested.
    const auto errors_over = [&](const std::vector<Sample>& over, const auto& value_of) {
        double l1n = 0.0, l1d = 0.0;
        Errors e;
        std::vector<double> rel;
        for (std::size_t l = 0; l < over.size(); ++l) {
            const Sample& smp = over[l];
            const double smax = *std::max_element(smp.ref.begin(), smp.ref.end());
            for (std::size_t i = 0; i < smp.voxels.size(); ++i)
                for (std::size_t d = 0; d < nd; ++d) {
                    const double r = smp.ref[i * nd + d], v = value_of(l, i, d);
                    l1n += std::fabs(v - r);
                    l1d += r;
                    if (!(r > 0.0)) continue;
                    rel.push_back(std::fabs(v - r) / r);
                    if (r > 1e-3 * smax) e.max_bright = std::max(e.max_bright, std::fabs(v - r) / r);
                }
        }
        std::sort(rel.begin(), rel.end());
        e.l1 = l1n / l1d;
        if (!rel.empty()) e.p50 = rel[rel.size() / 2], e.p99 = rel[rel.size() * 99 / 100];
        return e;
    };
    const auto errors_of = [&](const auto& value_of) { return errors_over(samples, value_of); };
    const Errors own =
        errors_of([&](std::size_t l, std::size_t i, std::size_t d) { return samples[l].ref_coarse[i * nd + d]; });
    std::size_t sampled = 0;
    for (const Sample& smp : samples) sampled += smp.voxels.size();
    const std::string grid = std::to_string(g.dims.x) + "x" + std::to_string(g.dims.y) + "x" +
                             std::to_string(g.dims.z) + " storm, 26 directions";
    ctx.emit("ss_accuracy_reference",
             {{"reference", "single_scattering_reference, " + std::to_string(ref_cells) + "^3 cells per voxel"},
              {"voxels_per_light", double(sampled) / double(lights.size())},
              {"seconds_2_threads", ref_seconds},
              {"L1_relative_error_of_half_the_cells", own.l1},
              {"p99_rel_error_of_half_the_cells", own.p99},
              {"max_rel_error_bright_of_half_the_cells", own.max_bright},
              {"grid", grid}});
    const auto report = [&](const std::string& rule, double tol, const std::vector<SourceField>& got, double seconds) {
        const Errors e = errors_of([&](std::size_t l, std::size_t i, std::size_t d) {
            return double(got[l].data[d * cells + samples[l].voxels[i]]);
        });
        ctx.emit("ss_accuracy", {{"rule", rule},
                                 {"tolerance", tol},
                                 {"L1_relative_error", e.l1},
                                 {"max_rel_error_bright_voxels", e.max_bright},
                                 {"p99_rel_error_cloud_voxels", e.p99},
                                 {"p50_rel_error_cloud_voxels", e.p50},
                                 {"seconds_per_light_1_thread", seconds},
                                 {"lights", lights.size()},
                                 {"sampled_voxels_per_light", double(sampled) / double(lights.size())},
                                 {"grid", grid}});
    };
    for (double tol : {1e-1, 1e-2, 1e-3, 1e-4, 1e-5}) {
        SingleScatteringOptions o;
        o.tolerance = tol;
        std::vector<SourceField> got;
        core::Stopwatch w;
        for (const auto& p : lights) got.push_back(single_scattering(m, PointSource{p, 1.0}, dirs, o));
        report("adaptive (voxel average)", tol, got, w.seconds() / double(lights.size()));
    }
    // The sun's single scattering (each voxel's entry faces refined to the tolerance) against
    // the same reference, at the default storm's three test elevations, on the same sample of voxels.
    {
        core::set_thread_count(2);
        const double az = glm::radians(30.0);
        for (const double elev : {60.0, 25.0, 5.0}) {
            const double e = glm::radians(elev);
            const DirectionalSource sun{
                -glm::dvec3(std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)), 1.0};
            // The first light's voxels, with the sun's reference.
            std::vector<Sample> sun_sample(1);
            Sample& smp = sun_sample[0];
            smp.voxels = samples[0].voxels;
            smp.ref.assign(smp.voxels.size() * nd, 0.0);
            core::parallel_for_dynamic(0, std::int64_t(smp.voxels.size()), [&](std::int64_t i) {
                const auto r =
                    single_scattering_reference(m, sun, dirs, g.unindex(smp.voxels[std::size_t(i)]), ref_cells);
                std::copy(r.begin(), r.end(), smp.ref.begin() + i * std::ptrdiff_t(nd));
            });
            core::set_thread_count(1);
            for (double tol : {1e-1, 1e-2, 1e-3, 1e-4}) {
                SingleScatteringOptions o;
                o.tolerance = tol;
                core::Stopwatch w;
                const SourceField got = single_scattering(m, sun, dirs, o);
                const double seconds = w.seconds();
                const Errors err = errors_over(sun_sample, [&](std::size_t, std::size_t i, std::size_t d) {
                    return double(got.data[d * cells + smp.voxels[i]]);
                });
                ctx.emit("ss_accuracy_sun", {{"elevation_deg", elev},
                                             {"tolerance", tol},
                                             {"L1_relative_error", err.l1},
                                             {"max_rel_error_bright_voxels", err.max_bright},
                                             {"seconds_1_thread", seconds},
                                             {"sampled_voxels", smp.voxels.size()},
                                             {"grid", grid}});
            }
            core::set_thread_count(2);
        }
    }
    // Naive: the value at the voxel centre instead of the voxel average.
    {
        std::vector<SourceField> got;
        core::Stopwatch w;
        for (const auto& p : lights) {
            SourceField f(g, dirs);
            for (std::size_t c = 0; c < cells; ++c) {
                const core::Int3 v = g.unindex(c);
                const glm::dvec3 x = g.centre(v.x, v.y, v.z), r = x - p;
                const double r2 = glm::dot(r, r), T = transmittance(m, p, x);
                for (std::size_t k = 0; k < nd; ++k)
                    f.data[k * cells + c] =
                        float(m.optics.albedo * hg_phase(glm::dot(dirs[k], r) / std::sqrt(r2), m.optics.g) * T / r2);
            }
            got.push_back(std::move(f));
        }
        report("naive centre sample", 0.0, got, w.seconds() / double(lights.size()));
    }
    core::set_thread_count(2);
}
