// Lattice-Boltzmann studies.
//   lb-convergence: the paper's Figure 5 (total lattice density per step on a 128^3
//   sun-lit cloud) and the iterations to converge against "about twice the longest
//   dimension", for the paper's model and ours.
//   sun-geist: the engine's sun solve in the same configuration, both methods, g = 0 and
//   0.85: steps against 2N and the time per step beside the paper's.
#include "study/study.h"

#include "cloud/cloud.h"
#include "core/core.h"
#include "scene/scene.h"
#include "sky/sky.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <cmath>

using namespace fulgur;

namespace {

// The default scene's cumulonimbus on an n^3 lattice covering the same horizontal extent.
core::Grid3<float> study_cloud(int n, double* voxel) {
    const scene::Scene sc = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json");
    cloud::CumulonimbusParams cp = sc.cloud.generator;
    const double extent = std::max(cp.grid.x, cp.grid.y) * cp.voxel_size;
    cp.voxel_size = extent / (n - 8);  // the original extent plus a 4-voxel margin per side
    cp.grid = {n, n, n};
    *voxel = cp.voxel_size;
    return cloud::generate_cumulonimbus(cp);
}

int first_below(const std::vector<double>& total, double tol) {
    for (std::size_t t = 2; t < total.size(); ++t) {
        const double c = std::fabs(total[t] - total[t - 2]) / (2.0 * std::fabs(total[t]));
        if (c < tol) return int(t + 1);
    }
    return -1;
}

}  // namespace

FULGUR_STUDY(lb_convergence, "lb-convergence",
             "Fig. 5 of Geist 2004: total lattice density per step, 128^3 sun-lit cloud; steps to converge vs 2N") {
    const int n = ctx.quick ? 48 : 128;
    double h = 0.0;
    core::Stopwatch gen;
    transport::LightingMedium m;
    m.density = study_cloud(n, &h);
    const double gen_s = gen.seconds();
    // The paper's Figure 2 medium: extinction 0.25 per lattice hop at full density.
    const double kappa = -std::log(0.75) / h;
    const glm::dvec3 sun = glm::normalize(glm::dvec3(0.4, 0.25, -1.0));
    struct Run {
        std::string label;
        transport::LbCollision collision;
        transport::LbAbsorption absorption;
        double g;
        bool dashed;
    };
    const std::vector<Run> runs = {
        {"paper model: conservative, g = 0", transport::LbCollision::Corrected, transport::LbAbsorption::Conservative,
         0.0, false},
        {"physical absorption, g = 0", transport::LbCollision::Corrected, transport::LbAbsorption::Physical, 0.0,
         false},
        {"conservative, g = 0.85 corrected", transport::LbCollision::Corrected, transport::LbAbsorption::Conservative,
         0.85, true},
        {"physical, g = 0.85 corrected", transport::LbCollision::Corrected, transport::LbAbsorption::Physical, 0.85,
         true},
        {"conservative, g = 0.85 published", transport::LbCollision::Published, transport::LbAbsorption::Conservative,
         0.85, true},
    };
    const int max_steps = 6 * n;
    study::Csv summary(ctx.file("lb_convergence_summary.csv"),
                       {"run", "steps_to_1e-3", "steps_to_1e-4", "steps_to_1e-5", "converged_1e-6", "steps_run",
                        "two_N", "seconds", "MLUPS", "final_total"});
    std::vector<std::vector<double>> histories;
    nlohmann::json js = nlohmann::json::array();
    for (const Run& r : runs) {
        m.optics = transport::Medium{kappa, 0.9, r.g};
        transport::LbSources src;
        src.sun = transport::DirectionalSource{sun, 1.0};
        transport::LbSettings s;
        s.collision = r.collision;
        s.absorption = r.absorption;
        s.tolerance = 1e-6;
        s.max_iterations = max_steps;
        s.record_history = true;
        const std::vector<glm::dvec3> dirs = {glm::dvec3(0, 0, 1)};
        const transport::LbResult res = transport::solve_lattice_boltzmann(m, src, dirs, s);
        const auto& tot = res.total_density;
        const double final_total = tot.empty() ? 0.0 : tot.back();
        histories.push_back(tot);
        const double mlups = double(m.density.size()) * res.iterations / res.seconds / 1e6;
        summary << ("\"" + r.label + "\"") << double(first_below(tot, 1e-3)) << double(first_below(tot, 1e-4))
                << double(first_below(tot, 1e-5)) << double(res.converged) << double(res.iterations) << double(2 * n)
                << res.seconds << mlups << final_total;
        summary.end_row();
        js.push_back({{"run", r.label},
                      {"steps_to_1e-3", first_below(tot, 1e-3)},
                      {"steps_to_1e-4", first_below(tot, 1e-4)},
                      {"steps_to_1e-5", first_below(tot, 1e-5)},
                      {"converged", res.converged},
                      {"steps", res.iterations},
                      {"seconds", res.seconds},
                      {"MLUPS", mlups}});
    }
    {
        std::vector<std::string> header = {"step"};
        for (const Run& r : runs) header.push_back("\"" + r.label + "\"");
        study::Csv csv(ctx.file("lb_convergence.csv"), header);
        for (int t = 0; t < max_steps; ++t) {
            csv << double(t + 1);
            for (const auto& h2 : histories)
                csv << (std::size_t(t) < h2.size() ? h2[std::size_t(t)] / double(m.density.size()) : std::nan(""));
            csv.end_row();
        }
    }
    ctx.summary("lb-convergence",
                {{"grid", n}, {"voxel_m", h}, {"cloud_seconds", gen_s}, {"two_N", 2 * n}, {"runs", js}});
}

// The engine's sun solve (sky::solve_directional) in Geist's published configuration: the
// study cloud on a 128^3 lattice, the Figure-2 medium (extinction 0.25 per hop at full
// density, albedo 0.9), isotropic (Fig. 2) and g = 0.85 (Fig. 3), both methods (Geist's
// boundary injection as published; exact single scattering + the lattice for orders >= 2),
// the scene default lattice settings (physical absorption, corrected collision, tolerance
// 1e-4). Steps to converge against 2N, and the time per step on one thread beside the paper's
// 6.15 s on one 1.6 GHz Pentium 4.
FULGUR_STUDY(sun_geist, "sun-geist",
             "the sun solve in Geist 2004's configuration: 128^3, g = 0 and 0.85, steps vs 2N, s/step vs 6.15 s") {
    const int n = ctx.quick ? 48 : 128;
    double h = 0.0;
    transport::LightingMedium m;
    m.density = study_cloud(n, &h);
    const double kappa = -std::log(0.75) / h;
    solve::Media media{m, m, 1, {}, {}};
    const transport::DirectionalSource sun{glm::normalize(glm::dvec3(0.4, 0.25, -1.0)), 1.0};
    study::Csv csv(ctx.file("sun_geist.csv"),
                   {"method", "g", "directions", "steps", "two_N", "converged", "seconds_single", "seconds_lattice",
                    "seconds_per_step", "paper_seconds_per_step", "energy_residual"});
    nlohmann::json js = nlohmann::json::array();
    const core::ScopedThreadCount one(1);  // the paper's single-CPU figure
    for (const double g : {0.0, 0.85}) {
        media.transport.optics = media.lighting.optics = transport::Medium{kappa, 0.9, g};
        // Isotropic scattering needs one output direction; the anisotropic run, the 26 of the scenes.
        const std::vector<glm::dvec3> dirs = transport::output_directions(g == 0.0 ? 1 : 26);
        for (const sky::Method method : {sky::Method::Lattice, sky::Method::Hybrid}) {
            sky::SolveSettings st;
            st.method = method;
            const sky::LightField f = sky::solve_directional(media, std::span(&sun, 1), dirs, st);
            const double per_step = f.iterations > 0 ? f.seconds_multiple / f.iterations : 0.0;
            const double residual =
                std::fabs(f.injected_total - f.absorbed_total - f.escaped_total - f.stored) / f.injected_total;
            csv << std::string(sky::to_string(method)) << g << double(dirs.size()) << double(f.iterations)
                << double(2 * n) << double(f.converged) << f.seconds_single << f.seconds_multiple << per_step << 6.15
                << residual;
            csv.end_row();
            js.push_back({{"method", sky::to_string(method)},
                          {"g", g},
                          {"directions", dirs.size()},
                          {"steps", f.iterations},
                          {"steps_over_2N", double(f.iterations) / (2.0 * n)},
                          {"converged", f.converged},
                          {"seconds_single", f.seconds_single},
                          {"seconds_lattice", f.seconds_multiple},
                          {"seconds_per_step", per_step},
                          {"paper_seconds_per_step", 6.15},
                          {"energy_residual", residual}});
        }
    }
    ctx.summary("sun-geist", {{"grid", n}, {"voxel_m", h}, {"threads", 1}, {"two_N", 2 * n}, {"runs", js}});
}
