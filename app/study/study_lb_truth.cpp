// The lattice against the truth, one light at a time (part of lb-vs-mc): the default storm,
// an isotropic 1 W/sr light in the core (the cloud's density-weighted centre), at its edge
// (the last point with density > 0.02 on the way out along +x at the core's height) and
// 1.5 km below its base; each solved by solve::solve (exact single scattering + the lattice on
// the transport grid) with today's lattice (transport.refine 1, thick voxels saturate or
// diffusion_matched) and the new ones (refine 2, 3; order 2 by Monte Carlo, the lattice for
// orders >= 3), against the truth (Monte Carlo
// through the full-resolution density, tallied on the lighting grid). Relative L2 of single,
// multiple and total over the cloud voxels, and the ratio of totals, for all cloud voxels and
// per band of the lighting voxels' hop optical depth; the solve's time per light.
// Output: lb_vs_truth.csv (scripts/plot_studies.py draws it).
#include "study/study.h"

#include "bake/bake.h"
#include "cloud/cloud.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <glm/geometric.hpp>

#include <cstdio>

using namespace fulgur;

namespace fulgur::study {

void lb_vs_truth(const Context& ctx) {
    const scene::Scene base = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json");
    const core::Grid3<float> density = scene::make_density(base);
    const core::GridGeometry& g = density.geom;
    glm::dvec3 centre(0.0);
    double mass = 0.0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                centre += double(density.at(i, j, k)) * g.centre(i, j, k);
                mass += density.at(i, j, k);
            }
    centre /= mass;
    glm::dvec3 edge = centre;
    for (double x = centre.x; x < g.upper().x; x += 50.0)
        if (density.sample({x, centre.y, centre.z}) > 0.02f) edge.x = x;
    const double cloud_base = cloud::cloud_base_height(density, 0.05f);
    const std::vector<std::pair<std::string, glm::dvec3>> lights = {
        {"core", centre}, {"edge", edge}, {"below", {centre.x, centre.y, cloud_base - 1500.0}}};

    struct Lattice {
        std::string name;
        int refine;
        std::string thick;
        int exact_orders = 1;
        std::uint64_t order2_paths = 50'000;
    };
    std::vector<Lattice> lattices = {{"refine 1 saturate", 1, "saturate"},
                                     {"refine 1 diffusion_matched", 1, "diffusion_matched"},
                                     {"refine 2", 2, "diffusion_matched"},
                                     {"refine 1, order 2 exact", 1, "diffusion_matched", 2},
                                     {"refine 2, order 2 exact", 2, "diffusion_matched", 2},
                                     {"refine 2, order 2 exact (20k paths)", 2, "diffusion_matched", 2, 20'000}};
    if (!ctx.quick) {
        lattices.push_back({"refine 3", 3, "diffusion_matched"});
        lattices.push_back({"refine 3, order 2 exact", 3, "diffusion_matched", 2});
    }

    const solve::Media lighting_media = solve::make_media(base, density);
    const transport::LightingMedium& lm = lighting_media.lighting;
    const std::vector<float>& rho = lm.density.data;
    const std::size_t cells = rho.size();
    const double h = lm.density.geom.voxel_size;
    struct Band {
        std::string name;
        double lo, hi;  // hop optical depth of the lighting voxel (sigma_t h)
    };
    const std::vector<Band> bands = {
        {"all", 0.0, 1e30}, {"tau<0.5", 0.0, 0.5}, {"tau 0.5-1.5", 0.5, 1.5}, {"tau>=1.5", 1.5, 1e30}};

    Csv csv(ctx.file("lb_vs_truth.csv"), {"light", "lattice", "band", "voxels", "error_single", "error_multiple",
                                          "error_total", "ratio_multiple", "ratio_total", "solve_s", "truth_noise"});
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& [light_name, position] : lights) {
        runtime::TruthOptions to;
        to.paths = ctx.quick ? 300'000 : 4'000'000;
        const transport::PointSource p{position, 1.0};
        const runtime::Truth truth = runtime::truth(base, density, {}, std::span(&p, 1), to);
        std::fprintf(stderr, "lb-vs-truth: light %s at (%.0f, %.0f, %.0f): truth %.1f s, noise %.4f\n",
                     light_name.c_str(), position.x, position.y, position.z, truth.seconds, truth.noise.total);
        for (const Lattice& l : lattices) {
            scene::Scene s = base;
            s.transport.refine = l.refine;
            s.transport.lb_thick_voxels = l.thick;
            s.transport.lb_exact_orders = l.exact_orders;
            s.transport.lb_order2_paths = l.order2_paths;
            const solve::Media media = solve::make_media(s, density);
            core::Stopwatch sw;
            const solve::Solution sol =
                solve::solve(s, media, std::span(&p, 1), transport::output_directions(s.effective_directions()));
            const double seconds = sw.seconds();
            for (const Band& band : bands) {
                core::RelativeL2 e1, e2, et;
                double sm = 0.0, smt = 0.0, st = 0.0, stt = 0.0;
                std::size_t voxels = 0;
                for (std::size_t c = 0; c < cells; ++c) {
                    const double tau = lm.sigma_t(c) * h;
                    if (!(rho[c] > 0.0f) || tau < band.lo || tau >= band.hi) continue;
                    ++voxels;
                    for (std::size_t m = 0; m < sol.single.directions.size(); ++m) {
                        const std::size_t i = m * cells + c;
                        const double a1 = sol.single.data[i], a2 = sol.multiple.data[i];
                        const double t1 = truth.single.data[i], t2 = truth.multiple.data[i];
                        e1.add(a1, t1);
                        e2.add(a2, t2);
                        et.add(a1 + a2, t1 + t2);
                        sm += a2;
                        smt += t2;
                        st += a1 + a2;
                        stt += t1 + t2;
                    }
                }
                if (voxels == 0) continue;
                csv << light_name << l.name << band.name << double(voxels) << e1.value() << e2.value() << et.value()
                    << sm / smt << st / stt << seconds << truth.noise.total;
                csv.end_row();
                if (band.name == "all") {
                    std::fprintf(
                        stderr, "lb-vs-truth: %-6s %-27s single %.3f multiple %.3f (ratio %.3f) total %.3f, %.2f s\n",
                        light_name.c_str(), l.name.c_str(), e1.value(), e2.value(), sm / smt, et.value(), seconds);
                    rows.push_back({{"light", light_name},
                                    {"lattice", l.name},
                                    {"error_multiple", e2.value()},
                                    {"ratio_multiple", sm / smt},
                                    {"error_total", et.value()},
                                    {"solve_s", seconds}});
                }
            }
        }
    }
    ctx.summary("lb-vs-truth", {{"rows", rows}});
}

}  // namespace fulgur::study
