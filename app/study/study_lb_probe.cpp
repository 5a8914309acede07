// Temporary probe: LB on refined lattices vs the fine-grid truth, single lights.
#include "study/study.h"

#include "cloud/cloud.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>

using namespace fulgur;
using namespace fulgur::transport;

namespace {
std::vector<float> coarsen(const SourceField& f, const core::GridGeometry& c, int r) {
    const std::size_t M = f.directions.size(), nc = c.cell_count(), nf = f.cells();
    std::vector<double> acc(M * nc, 0.0);
    const core::GridGeometry& g = f.geom;
    for (std::size_t m = 0; m < M; ++m)
        for (int k = 0; k < g.dims.z; ++k)
            for (int j = 0; j < g.dims.y; ++j)
                for (int i = 0; i < g.dims.x; ++i)
                    acc[m * nc + c.index(i / r, j / r, k / r)] += f.data[m * nf + g.index(i, j, k)];
    std::vector<float> out(acc.size());
    for (std::size_t i = 0; i < acc.size(); ++i) out[i] = float(acc[i] / double(r * r * r));
    return out;
}
double rl2(const std::vector<float>& a, const std::vector<float>& b, const std::vector<float>& rho, std::size_t nd) {
    const std::size_t cells = rho.size();
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
double ratio(const std::vector<float>& a, const std::vector<float>& b, const std::vector<float>& rho) {
    double x = 0, y = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (rho[i % rho.size()] > 0) x += a[i], y += b[i];
    return x / y;
}
}  // namespace

FULGUR_STUDY(lb_probe, "lb-probe", "probe") {
    const std::filesystem::path scene_path = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json";
    const scene::Scene s = scene::load_scene(scene_path);
    const core::Grid3<float> density = scene::make_density(s);
    const LightingMedium coarse = scene::make_lighting_medium(s, density);
    const core::GridGeometry& cg = coarse.density.geom;
    const auto dirs = output_directions(s.effective_directions());
    const std::size_t nd = dirs.size();
    // light positions
    const core::GridGeometry& g = density.geom;
    glm::dvec3 cen(0.0);
    double wsum = 0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const double r = density.at(i, j, k);
                cen += r * g.centre(i, j, k);
                wsum += r;
            }
    cen /= wsum;
    const double base = cloud::cloud_base_height(density, 0.05);
    glm::dvec3 edge = cen;
    for (double x = cen.x; x < g.upper().x; x += 50.0)
        if (density.sample({x, cen.y, cen.z}) > 0.02f) edge.x = x;
    std::vector<std::pair<std::string, glm::dvec3>> lights = {
        {"core", cen}, {"edge", edge}, {"below", {cen.x, cen.y, base - 1500.0}}};
    const std::uint64_t paths = std::getenv("PATHS") ? std::strtoull(std::getenv("PATHS"), nullptr, 10) : 2000000;
    std::vector<int> refines = {1, 2, 3};
    if (std::getenv("REFINES")) {
        refines.clear();
        for (const char* p = std::getenv("REFINES"); *p; ++p)
            if (*p >= '1' && *p <= '9') refines.push_back(*p - '0');
    }
    for (auto& [name, pos] : lights) {
        if (std::getenv("ONLY") && name != std::getenv("ONLY")) continue;
        std::printf("light %s at (%.0f, %.0f, %.0f), density there %.3f\n", name.c_str(), pos.x, pos.y, pos.z,
                    density.sample(pos));
        runtime::TruthOptions to;
        to.paths = paths;
        std::vector<transport::PointSource> pts = {{pos, 1.0}};
        const runtime::Truth T = runtime::truth(s, density, {}, pts, to);
        std::printf("  truth %.1f s noise %.4f/%.4f\n", T.seconds, T.noise.single, T.noise.multiple);
        for (int r : refines) {
            const int ds = s.lighting_downsample / r;
            LightingMedium fm;
            fm.density = core::downsample(density, ds);
            fm.optics = s.medium;
            {
                MonteCarloOptions mo;
                mo.paths = paths / 2;
                const std::vector<PointSource> one = {PointSource{pos, 1.0}};
                const MonteCarloResult C = monte_carlo(fm, one, {}, cg, dirs, mo);
                std::printf("  MC on the %.0f m medium vs truth: single %.4f multiple %.4f (ratio %.3f)\n",
                            fm.density.geom.voxel_size, rl2(C.single.data, T.single.data, coarse.density.data, nd),
                            rl2(C.multiple.data, T.multiple.data, coarse.density.data, nd),
                            ratio(C.multiple.data, T.multiple.data, coarse.density.data));
            }
            for (int tv = 0; tv < (std::getenv("SAT") ? 2 : 1); ++tv) {
                core::Stopwatch sw;
                SingleScatteringOptions so;
                so.tolerance = s.transport.ss_tolerance;
                so.skip_far_empty = false;
                core::Grid3<float> phi1;
                so.uncollided_fluence = &phi1;
                const SourceField S1 = single_scattering(fm, PointSource{pos, 1.0}, dirs, so);
                const double t_ss = sw.seconds();
                LbSources src;
                src.first_scattered = &S1;
                src.first_scattered_fluence = &phi1;
                LbSettings lb;
                lb.thick_voxels = tv ? LbThickVoxels::Saturate : LbThickVoxels::DiffusionMatched;
                if (std::getenv("TOL")) lb.tolerance = std::atof(std::getenv("TOL"));
                const LbResult R = solve_lattice_boltzmann(fm, src, dirs, lb);
                const double t_all = sw.seconds();
                const std::vector<float> ms = coarsen(R.source, cg, r), ss = coarsen(S1, cg, r);
                std::vector<float> tot(ms.size()), Tt(ms.size());
                for (std::size_t i = 0; i < ms.size(); ++i) tot[i] = ms[i] + ss[i], Tt[i] = T.single.data[i] + T.multiple.data[i];
                std::printf(
                    "  refine %d (%.0f m) %s: single %.4f (ratio %.3f) multiple %.4f (ratio %.3f) total %.4f; ss %.2f s, "
                    "lb %.2f s, %d it\n",
                    r, fm.density.geom.voxel_size, tv ? "saturate" : "matched", rl2(ss, T.single.data, coarse.density.data, nd),
                    ratio(ss, T.single.data, coarse.density.data), rl2(ms, T.multiple.data, coarse.density.data, nd),
                    ratio(ms, T.multiple.data, coarse.density.data), rl2(tot, Tt, coarse.density.data, nd), t_ss,
                    t_all - t_ss, R.iterations);
                // bands
                auto band = [&](auto pred, const char* lab) {
                    std::vector<float> mask(coarse.density.data.size(), 0.0f);
                    int cnt = 0;
                    for (int k = 0; k < cg.dims.z; ++k)
                        for (int j = 0; j < cg.dims.y; ++j)
                            for (int i = 0; i < cg.dims.x; ++i) {
                                const std::size_t c = cg.index(i, j, k);
                                if (coarse.density.data[c] > 0 && pred(c, glm::length(cg.centre(i, j, k) - pos))) {
                                    mask[c] = 1.0f;
                                    ++cnt;
                                }
                            }
                    if (cnt == 0) return;
                    std::printf("    %-14s n=%4d multiple %.4f ratio %.3f\n", lab, cnt, rl2(ms, T.multiple.data, mask, nd),
                                ratio(ms, T.multiple.data, mask));
                };
                const double h = cg.voxel_size;
                auto tau = [&](std::size_t c) { return coarse.sigma_t(c) * h; };
                band([&](std::size_t c, double) { return tau(c) < 0.5; }, "tau<0.5");
                band([&](std::size_t c, double) { return tau(c) >= 0.5 && tau(c) < 1.5; }, "tau 0.5-1.5");
                band([&](std::size_t c, double) { return tau(c) >= 1.5; }, "tau>=1.5");
                band([&](std::size_t, double d) { return d < 1.5 * h; }, "d<1.5h");
                band([&](std::size_t, double d) { return d >= 1.5 * h && d < 3 * h; }, "d 1.5-3h");
                band([&](std::size_t, double d) { return d >= 3 * h; }, "d>=3h");
                std::fflush(stdout);
            }
        }
    }
}
