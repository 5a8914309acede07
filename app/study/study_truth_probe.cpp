// Temporary probe: truth noise/time and the direct solve / basis frame against it.
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

using namespace fulgur;

namespace {
double rl2(const std::vector<float>& a, const std::vector<float>& b, const std::vector<float>& rho, std::size_t cells,
           std::size_t nd) {
    double d = 0, n = 0;
    for (std::size_t m = 0; m < nd; ++m)
        for (std::size_t i = 0; i < cells; ++i)
            if (rho[i] > 0) {
                double x = a[m * cells + i], y = b[m * cells + i];
                d += (x - y) * (x - y);
                n += y * y;
            }
    return std::sqrt(d / n);
}
std::vector<float> g_rho;
double ratio(const std::vector<float>& a, const std::vector<float>& b) {
    double x = 0, y = 0;
    const std::size_t n = g_rho.size();
    for (std::size_t i = 0; i < a.size(); ++i)
        if (g_rho[i % n] > 0) x += a[i], y += b[i];
    return x / y;
}
}  // namespace

FULGUR_STUDY(truth_probe, "truth-probe", "probe") {
    const std::filesystem::path scene_path = std::getenv("SCENE") ? std::filesystem::path(std::getenv("SCENE")) : std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json";
    const scene::Scene s = scene::load_scene(scene_path);
    const core::Grid3<float> density = scene::make_density(s);
    const std::filesystem::path fgb = bake::default_fgb_path(s);
    bake::bake_if_stale(s, density, fgb);
    const runtime::BakedBases bases = runtime::BakedBases::load(fgb, bake::scene_key(s, density));
    const bake::Media media = bake::make_media(s, density);
    const transport::LightingMedium& medium = media.lighting;
    const std::size_t cells = medium.density.size();
    g_rho = medium.density.data;
    const std::uint64_t paths = std::getenv("PATHS") ? std::strtoull(std::getenv("PATHS"), nullptr, 10) : 4000000;
    const int nseeds = std::getenv("SEEDS") ? std::atoi(std::getenv("SEEDS")) : 5;
    for (std::uint64_t seed = 1; seed <= std::uint64_t(nseeds); ++seed) {
        runtime::FramePipeline p(s, density, bases);
        const std::size_t k = p.strike_at(0.0, seed);
        const double t = p.storm().strike(k).profile.stroke_onset.at(0) + 0.002;
        const runtime::Frame& f = p.build(t, {});
        std::vector<std::vector<float>> R = f.radiance.values;
        std::vector<float> Rf;
        for (auto& v : R) Rf.insert(Rf.end(), v.begin(), v.end());
        const auto segs = f.segments;
        const auto srcs = f.sources;
        runtime::TruthOptions to;
        to.paths = paths;
        to.seed = seed;
        if (std::getenv("EXT")) to.weight = transport::MonteCarloOptions::TallyWeight::Extinction;
        const runtime::Truth T = runtime::truth(s, density, segs, {}, to);
        if (std::getenv("COARSE")) {
            std::vector<transport::LineSource> lines;
            for (auto& g : segs) lines.push_back({g.a, g.b, g.intensity});
            std::vector<transport::PointSource> pts;
            for (auto& q : srcs) pts.push_back({q.position, q.intensity});
            transport::MonteCarloOptions mo;
            mo.paths = paths; mo.seed = seed; mo.halves = true;
            const auto dirs = transport::output_directions(s.effective_directions());
            auto C = transport::monte_carlo(medium, {}, lines, medium.density.geom, dirs, mo);
            auto P = transport::monte_carlo(medium, pts, {}, medium.density.geom, dirs, mo);
            const std::size_t nd = dirs.size();
            std::printf("{\"coarse_lines_vs_truth\":[%.4f,%.4f],\"coarse_points_vs_coarse_lines\":[%.4f,%.4f]}\n",
                rl2(C.single.data, T.single.data, medium.density.data, cells, nd), rl2(C.multiple.data, T.multiple.data, medium.density.data, cells, nd),
                rl2(P.single.data, C.single.data, medium.density.data, cells, nd), rl2(P.multiple.data, C.multiple.data, medium.density.data, cells, nd));
            runtime::Components cc{true, false};
            const transport::SourceField DD1 = runtime::direct_solve(s, media, srcs, cc);
            std::printf("{\"direct_single_vs_coarse_points_mc\":%.4f}\n", rl2(DD1.data, P.single.data, medium.density.data, cells, nd));
        }
        if (std::getenv("STRIKE")) {
            runtime::StrikeSolveOptions so;
            if (std::getenv("SP")) so.single_paths = std::strtoull(std::getenv("SP"), nullptr, 10);
            if (std::getenv("MP")) so.multiple_paths = std::strtoull(std::getenv("MP"), nullptr, 10);
            const std::string mult = std::getenv("STRIKE");
            so.multiple = mult == "mc" ? runtime::StrikeSolveOptions::Multiple::MonteCarlo
                          : mult == "none" ? runtime::StrikeSolveOptions::Multiple::None
                                           : runtime::StrikeSolveOptions::Multiple::Lattice;
            so.seed = seed;
            const auto& bolt = p.storm().bolt(k);
            const runtime::StrikeLight L = runtime::solve_strike(s, density, media, bolt, so);
            const auto st = lightning::flash_state(p.storm().strike(k).profile, s.lightning.timing, t - p.storm().strike(k).time);
            std::vector<float> s1(T.single.data.size()), sm(s1.size());
            for (std::size_t i = 0; i < s1.size(); ++i) {
                s1[i] = float(st.main_glow * L.single[0].data[i] + st.branch_glow * L.single[1].data[i]);
                if (L.has_multiple()) sm[i] = float(st.main_glow * L.multiple[0].data[i] + st.branch_glow * L.multiple[1].data[i]);
            }
            std::vector<float> tt(s1.size());
            for (std::size_t i = 0; i < s1.size(); ++i) tt[i] = s1[i] + sm[i];
            const std::size_t nd = T.single.directions.size();
            std::printf("{\"strike\":\"%s\",\"s_single\":%.2f,\"s_multiple\":%.2f,\"noise\":[%.4f,%.4f],\"vs_truth\":[%.4f,%.4f,%.4f],\"ratio\":[%.3f,%.3f],\"leader\":%g}\n",
                mult.c_str(), L.seconds_single, L.seconds_multiple, L.noise.single, L.noise.multiple,
                rl2(s1, T.single.data, medium.density.data, cells, nd), rl2(sm, T.multiple.data, medium.density.data, cells, nd),
                rl2(tt, T.sum().data, medium.density.data, cells, nd), ratio(s1, T.single.data), ratio(sm, T.multiple.data), st.leader_glow);
            std::fflush(stdout);
            if (std::getenv("NODIRECT")) continue;
        }
        core::Stopwatch sw;
        runtime::Components c1{true, false}, c2{false, true};
        const transport::SourceField D1 = runtime::direct_solve(s, media, srcs, c1);
        const transport::SourceField D2 = runtime::direct_solve(s, media, srcs, c2);
        const double dsec = sw.seconds();
        const transport::SourceField Tt = T.sum();
        std::vector<float> Dt(D1.data.size());
        for (std::size_t i = 0; i < Dt.size(); ++i) Dt[i] = D1.data[i] + D2.data[i];
        const std::size_t nd = T.single.directions.size();
        std::printf(
            "{\"seed\":%llu,\"segments\":%zu,\"paths\":%llu,\"truth_s\":%.1f,\"noise\":[%.4f,%.4f,%.4f],"
            "\"direct_s\":%.2f,\"direct_vs_truth\":[%.4f,%.4f,%.4f],\"direct_ratio\":[%.3f,%.3f],"
            "\"basis_vs_truth\":%.4f,\"basis_ratio\":%.3f}\n",
            (unsigned long long)seed, segs.size(), (unsigned long long)T.paths, T.seconds, T.noise.single,
            T.noise.multiple, T.noise.total, dsec, rl2(D1.data, T.single.data, medium.density.data, cells, nd),
            rl2(D2.data, T.multiple.data, medium.density.data, cells, nd), rl2(Dt, Tt.data, medium.density.data, cells, nd),
            ratio(D1.data, T.single.data), ratio(D2.data, T.multiple.data),
            rl2(Rf, Tt.data, medium.density.data, cells, nd), ratio(Rf, Tt.data));
        std::fflush(stdout);
    }
}
