// Lattice-Boltzmann against the Monte Carlo reference (issue 3's last deliverable).
//   lb-vs-mc: the default storm cloud on its 36x36x20 lighting grid (500 m voxels,
//   26 output directions, g = 0.6, albedo 0.99), an isotropic 1 W/sr point light 750 m
//   below the cloud base under the centre of the base layer. Reference: Monte Carlo (all
//   orders, split into order 1 and orders >= 2). Tested: exact single scattering S1 plus
//   LB multiple scattering fed with S1 and the uncollided fluence phi1, for both absorption
//   models (and the published collision for reference). Relative L2 errors of S over cloud
//   voxels, for the total and the multiple-scattering part, with the Monte Carlo noise floor.
#include "study/study.h"

#include "cloud/cloud.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

/// A field S[m * cells + c] in double (sums of solver outputs).
using Field = std::vector<double>;

Field to_field(const SourceField& f) { return Field(f.data.begin(), f.data.end()); }

Field sum(const Field& a, const Field& b) {
    Field r(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) r[i] = a[i] + b[i];
    return r;
}

/// sqrt(a^2 + b^2) per entry (standard error of a sum of independent estimates).
Field quad_sum(const Field& a, const Field& b) {
    Field r(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) r[i] = std::sqrt(a[i] * a[i] + b[i] * b[i]);
    return r;
}

/// Relative L2 error ||x - ref|| / ||ref|| over the listed cells and the directions in
/// [m0, m1) (all directions by default).
double rel_l2(const Field& x, const Field& ref, const std::vector<std::size_t>& cells, std::size_t ncell,
              std::size_t M, std::size_t m0 = 0, std::size_t m1 = std::size_t(-1)) {
    double num = 0.0, den = 0.0;
    for (std::size_t m = m0; m < std::min(M, m1); ++m)
        for (std::size_t c : cells) {
            const double r = ref[m * ncell + c], d = x[m * ncell + c] - r;
            num += d * d;
            den += r * r;
        }
    return den > 0.0 ? std::sqrt(num / den) : std::nan("");
}

/// Noise floor: ||se|| / ||ref|| (the relative L2 error an exact solution would show
/// against this Monte Carlo estimate, in expectation).
double noise_floor(const Field& se, const Field& ref, const std::vector<std::size_t>& cells, std::size_t ncell,
                   std::size_t M, std::size_t m0 = 0, std::size_t m1 = std::size_t(-1)) {
    double num = 0.0, den = 0.0;
    for (std::size_t m = m0; m < std::min(M, m1); ++m)
        for (std::size_t c : cells) {
            num += se[m * ncell + c] * se[m * ncell + c];
            den += ref[m * ncell + c] * ref[m * ncell + c];
        }
    return den > 0.0 ? std::sqrt(num / den) : std::nan("");
}

/// Error with the expected noise contribution removed: sqrt(max(0, e^2 - floor^2)).
double denoised(double e, double floor) { return std::sqrt(std::max(0.0, e * e - floor * floor)); }

/// Mean over directions at one cell.
double dir_mean(const Field& f, std::size_t c, std::size_t ncell, std::size_t M) {
    double s = 0.0;
    for (std::size_t m = 0; m < M; ++m) s += f[m * ncell + c];
    return s / double(M);
}

}  // namespace

FULGUR_STUDY(lb_vs_mc, "lb-vs-mc",
             "LB (+ exact single scattering) vs Monte Carlo on the default storm, point light below the base: "
             "relative L2 of S over cloud voxels") {
    // --- The scene's medium on its lighting grid ------------------------------------------------
    const scene::Scene sc = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json");
    core::Stopwatch gen;
    const core::Grid3<float> density = scene::make_density(sc);
    const LightingMedium m = scene::make_lighting_medium(sc, density);
    const double gen_s = gen.seconds();
    const core::GridGeometry& g = m.density.geom;
    const std::size_t n = g.cell_count();
    const double h = g.voxel_size;
    const auto dirs = output_directions(sc.effective_directions());
    const std::size_t M = dirs.size();

    // --- Cloud voxels: density > 0.05 (the scene's virtual-light density threshold) and > 0 --
    constexpr float kCloud = 0.05f;
    std::vector<std::size_t> cloud, any;
    for (std::size_t c = 0; c < n; ++c) {
        if (m.density.data[c] > 0.0f) any.push_back(c);
        if (m.density.data[c] > kCloud) cloud.push_back(c);
    }

    // --- The light: centre (density-weighted) of the lowest cloud layer, 750 m below the base --
    const double base = cloud::cloud_base_height(m.density, kCloud);
    const int kb = int(std::lround((base - g.origin.z) / h));
    glm::dvec2 centroid(0.0);
    double wsum = 0.0;
    for (int j = 0; j < g.dims.y; ++j)
        for (int i = 0; i < g.dims.x; ++i) {
            const double w = m.density.at(i, j, kb);
            if (!(w > kCloud)) continue;
            const glm::dvec3 x = g.centre(i, j, kb);
            centroid += w * glm::dvec2(x.x, x.y);
            wsum += w;
        }
    centroid /= wsum;
    const double below = 750.0;  // mid-layer of the lighting voxel below the base: not on a face
    const PointSource light{{centroid.x, centroid.y, base - below}, 1.0};
    const glm::dvec3 lv = g.to_voxel(light.position);
    const int li = int(std::floor(lv.x)), lj = int(std::floor(lv.y));

    // --- Exact single scattering S1 and the uncollided fluence phi1 -----------------------------
    core::Stopwatch w1;
    const SourceField S1 = single_scattering(m, light, dirs);  // default tolerance 1e-3
    LightingMedium probe = m;  // albedo 1, g 0, one direction: S = phi1 / (4 pi)
    probe.optics.albedo = 1.0;
    probe.optics.g = 0.0;
    const SourceField S_iso = single_scattering(probe, light, output_directions(1));
    core::Grid3<float> phi1(g, 0.0f);
    for (std::size_t c = 0; c < n; ++c) phi1.data[c] = float(4.0 * std::numbers::pi * double(S_iso.data[c]));
    const double ss_s = w1.seconds();

    // --- Monte Carlo reference (all orders) ----------------------------------------------------
    MonteCarloOptions mo;
    mo.paths = ctx.quick ? 200'000 : 6'000'000;
    mo.batches = 32;
    mo.seed = 20240603;
    const MonteCarloResult mc = monte_carlo(m, light, dirs, mo);
    const Field mc1 = to_field(mc.single), mcm = to_field(mc.multiple);
    const Field mct = sum(mc1, mcm);
    const Field se1 = to_field(mc.single_se), sem = to_field(mc.multiple_se);
    // The order-1 and multiple tallies come from the same paths and are not independent;
    // adding their standard errors in quadrature is an approximation of the total's.
    const Field set = quad_sum(se1, sem);
    const Field s1 = to_field(S1);

    // MC energy split (W): power scattered at least once, and where it ends.
    double mc_abs_multi = 0.0, mc_esc_multi = 0.0;
    for (int k = 1; k < EnergyTally::kOrders; ++k) {
        mc_abs_multi += mc.energy.absorbed_by_order[std::size_t(k)].mean;
        mc_esc_multi += mc.energy.escaped_by_order[std::size_t(k)].mean;
    }
    const double mc_scattered = mc_abs_multi + mc_esc_multi + mc.energy.truncated.mean;

    // --- Lattice-Boltzmann runs ------------------------------------------------------------------
    struct Run {
        std::string label;
        LbCollision collision;
        LbAbsorption absorption;
        double tolerance;
        bool use_phi1;
    };
    const std::vector<Run> runs = {
        {"physical", LbCollision::Corrected, LbAbsorption::Physical, 1e-4, true},
        {"conservative", LbCollision::Corrected, LbAbsorption::Conservative, 1e-4, true},
        {"physical tol 1e-6", LbCollision::Corrected, LbAbsorption::Physical, 1e-6, true},
        {"physical without phi1", LbCollision::Corrected, LbAbsorption::Physical, 1e-4, false},
        {"published physical", LbCollision::Published, LbAbsorption::Physical, 1e-4, true},
        {"published conservative", LbCollision::Published, LbAbsorption::Conservative, 1e-4, true},
    };

    // Error bins by the voxel's axis-hop optical depth sigma_t h (under-resolved voxels).
    const double bin_edges[] = {0.0, 0.25, 0.5, 1.0, 1e9};
    auto in_bin = [&](std::size_t b) {
        std::vector<std::size_t> r;
        for (std::size_t c : cloud) {
            const double tau = m.sigma_t(c) * h;
            if (tau > bin_edges[b] && tau <= bin_edges[b + 1]) r.push_back(c);
        }
        return r;
    };

    study::Csv csv(ctx.file("lb_vs_mc.csv"),
                   {"run", "collision", "absorption", "tolerance", "phi1", "iterations", "converged", "lb_seconds",
                    "relL2_total", "relL2_multiple", "relL2_total_all_voxels", "relL2_multiple_all_voxels",
                    "relL2_total_denoised", "relL2_multiple_denoised", "sum_S_total_ratio", "sum_S_multiple_ratio",
                    "scattered_power_ratio", "escaped_fraction_lb", "escaped_fraction_mc"});
    study::Csv bins(ctx.file("lb_vs_mc_tau_bins.csv"),
                    {"run", "tau_hop_lo", "tau_hop_hi", "voxels", "relL2_total", "relL2_multiple", "noise_floor_multiple",
                     "sum_S_multiple_ratio"});
    const double floor_t = noise_floor(set, mct, cloud, n, M), floor_m = noise_floor(sem, mcm, cloud, n, M);
    const double floor_t_any = noise_floor(set, mct, any, n, M), floor_m_any = noise_floor(sem, mcm, any, n, M);
    const double floor_1 = noise_floor(se1, mc1, cloud, n, M);
    const double err_s1 = rel_l2(s1, mc1, cloud, n, M);
    auto field_sum = [&](const Field& f, const std::vector<std::size_t>& cells) {
        double s = 0.0;
        for (std::size_t mm = 0; mm < M; ++mm)
            for (std::size_t c : cells) s += f[mm * n + c];
        return s;
    };

    nlohmann::json js_runs = nlohmann::json::array();
    std::vector<Field> lb_mult(runs.size());
    for (std::size_t r = 0; r < runs.size(); ++r) {
        const Run& run = runs[r];
        LbSources src;
        src.first_scattered = &S1;
        if (run.use_phi1) src.first_scattered_fluence = &phi1;
        LbSettings s;
        s.collision = run.collision;
        s.absorption = run.absorption;
        s.tolerance = run.tolerance;
        const LbResult res = solve_lattice_boltzmann(m, src, dirs, s);
        lb_mult[r] = to_field(res.source);
        const Field tot = sum(s1, lb_mult[r]);
        const double et = rel_l2(tot, mct, cloud, n, M), em = rel_l2(lb_mult[r], mcm, cloud, n, M);
        const double et_any = rel_l2(tot, mct, any, n, M), em_any = rel_l2(lb_mult[r], mcm, any, n, M);
        const double ratio_t = field_sum(tot, cloud) / field_sum(mct, cloud);
        const double ratio_m = field_sum(lb_mult[r], cloud) / field_sum(mcm, cloud);
        const double power_ratio = res.injected_per_step / mc_scattered;
        const double esc_lb = res.escaped_last_step / res.injected_per_step, esc_mc = mc_esc_multi / mc_scattered;
        csv << ("\"" + run.label + "\"") << std::string(run.collision == LbCollision::Corrected ? "corrected" : "published")
            << std::string(run.absorption == LbAbsorption::Physical ? "physical" : "conservative") << run.tolerance
            << double(run.use_phi1) << double(res.iterations) << double(res.converged) << res.seconds << et << em << et_any
            << em_any << denoised(et, floor_t) << denoised(em, floor_m) << ratio_t << ratio_m << power_ratio << esc_lb
            << esc_mc;
        csv.end_row();
        for (std::size_t b = 0; b + 1 < std::size(bin_edges); ++b) {
            const auto cells = in_bin(b);
            bins << ("\"" + run.label + "\"") << bin_edges[b] << bin_edges[b + 1] << double(cells.size())
                 << rel_l2(tot, mct, cells, n, M) << rel_l2(lb_mult[r], mcm, cells, n, M)
                 << noise_floor(sem, mcm, cells, n, M) << field_sum(lb_mult[r], cells) / field_sum(mcm, cells);
            bins.end_row();
        }
        js_runs.push_back({{"run", run.label},
                           {"iterations", res.iterations},
                           {"converged", res.converged},
                           {"lb_seconds", res.seconds},
                           {"relL2_total", et},
                           {"relL2_multiple", em},
                           {"relL2_total_all_voxels", et_any},
                           {"relL2_multiple_all_voxels", em_any},
                           {"sum_S_total_ratio", ratio_t},
                           {"sum_S_multiple_ratio", ratio_m},
                           {"scattered_power_ratio", power_ratio},
                           {"escaped_fraction_lb", esc_lb}});
        std::fprintf(stderr, "lb-vs-mc: %-24s it %4d  total %.4f  multiple %.4f  sumS_mult ratio %.4f  (%.2f s)\n",
                     run.label.c_str(), res.iterations, et, em, ratio_m, res.seconds);
    }

    // --- Per direction (physical model) ----------------------------------------------------------
    {
        study::Csv dcsv(ctx.file("lb_vs_mc_directions.csv"),
                        {"m", "sx", "sy", "sz", "relL2_total_physical", "relL2_multiple_physical", "noise_floor_multiple",
                         "sum_S_multiple_ratio_physical"});
        const Field tot = sum(s1, lb_mult[0]);
        for (std::size_t mm = 0; mm < M; ++mm) {
            double a = 0.0, b = 0.0;
            for (std::size_t c : cloud) {
                a += lb_mult[0][mm * n + c];
                b += mcm[mm * n + c];
            }
            dcsv << double(mm) << dirs[mm].x << dirs[mm].y << dirs[mm].z << rel_l2(tot, mct, cloud, n, M, mm, mm + 1)
                 << rel_l2(lb_mult[0], mcm, cloud, n, M, mm, mm + 1) << noise_floor(sem, mcm, cloud, n, M, mm, mm + 1)
                 << a / b;
            dcsv.end_row();
        }
    }

    // --- Per voxel (direction means) -------------------------------------------------------------
    {
        study::Csv vcsv(ctx.file("lb_vs_mc_voxels.csv"),
                        {"i", "j", "k", "density", "tau_hop", "S1", "mc_single", "mc_multiple", "mc_multiple_se",
                         "lb_multiple_physical", "lb_multiple_conservative"});
        for (std::size_t c : any) {
            const core::Int3 v = g.unindex(c);
            vcsv << double(v.x) << double(v.y) << double(v.z) << double(m.density.data[c]) << m.sigma_t(c) * h
                 << dir_mean(s1, c, n, M) << dir_mean(mc1, c, n, M) << dir_mean(mcm, c, n, M) << dir_mean(sem, c, n, M)
                 << dir_mean(lb_mult[0], c, n, M) << dir_mean(lb_mult[1], c, n, M);
            vcsv.end_row();
        }
    }

    // --- Vertical profile through the light's column (direction-mean S) -------------------------
    {
        study::Series mct_s{"Monte Carlo total", {}, {}, "#000000", false, true};
        study::Series mcm_s{"Monte Carlo multiple", {}, {}, "#777777", false, true};
        study::Series s1_s{"exact single S1", {}, {}, "#1f77b4", true, false};
        study::Series lp_s{"S1 + LB physical", {}, {}, "#d62728", false, false};
        study::Series lc_s{"S1 + LB conservative", {}, {}, "#2ca02c", false, false};
        study::Series lpm_s{"LB physical multiple", {}, {}, "#d62728", true, false};
        study::Csv pcsv(ctx.file("lb_vs_mc_profile.csv"),
                        {"k", "z_m", "density", "S1", "mc_single", "mc_multiple", "mc_multiple_se", "lb_multiple_physical",
                         "lb_multiple_conservative"});
        for (int k = 0; k < g.dims.z; ++k) {
            const std::size_t c = g.index(li, lj, k);
            const double z = g.centre(li, lj, k).z / 1000.0;
            const double a1 = dir_mean(s1, c, n, M), b1 = dir_mean(mc1, c, n, M), bm = dir_mean(mcm, c, n, M);
            const double lp = dir_mean(lb_mult[0], c, n, M), lc = dir_mean(lb_mult[1], c, n, M);
            pcsv << double(k) << 1000.0 * z << double(m.density.data[c]) << a1 << b1 << bm << dir_mean(sem, c, n, M) << lp
                 << lc;
            pcsv.end_row();
            if (!(m.density.data[c] > 0.0f)) continue;
            mct_s.x.push_back(z), mct_s.y.push_back(b1 + bm);
            mcm_s.x.push_back(z), mcm_s.y.push_back(bm);
            s1_s.x.push_back(z), s1_s.y.push_back(a1);
            lp_s.x.push_back(z), lp_s.y.push_back(a1 + lp);
            lc_s.x.push_back(z), lc_s.y.push_back(a1 + lc);
            lpm_s.x.push_back(z), lpm_s.y.push_back(lp);
        }
        study::PlotOptions po;
        po.title = "S (mean over 26 directions) in the light's column, cloud voxels";
        po.x_label = "height (km)";
        po.y_label = "S (W m^-2 sr^-1)";
        po.log_y = true;
        po.vlines = {{base / 1000.0, "cloud base"}};
        study::write_svg_plot(ctx.file("lb_vs_mc_profile.svg"), {mct_s, mcm_s, s1_s, lp_s, lc_s, lpm_s}, po);
    }

    // --- Summary -------------------------------------------------------------------------------
    double tau_max = 0.0;
    for (std::size_t c : cloud) tau_max = std::max(tau_max, m.sigma_t(c) * h);
    ctx.summary("lb-vs-mc",
                {{"grid", {g.dims.x, g.dims.y, g.dims.z}},
                 {"voxel_m", h},
                 {"directions", M},
                 {"medium", {{"extinction", m.optics.extinction}, {"albedo", m.optics.albedo}, {"g", m.optics.g}}},
                 {"light", {light.position.x, light.position.y, light.position.z}},
                 {"cloud_base_m", base},
                 {"cloud_voxels_rho_gt_0.05", cloud.size()},
                 {"cloud_voxels_rho_gt_0", any.size()},
                 {"max_hop_optical_depth", tau_max},
                 {"cloud_seconds", gen_s},
                 {"single_scattering_seconds", ss_s},
                 {"mc_paths", mo.paths},
                 {"mc_seconds", mc.seconds},
                 {"mc_threads", core::thread_count()},
                 {"mc_noise_floor_total", floor_t},
                 {"mc_noise_floor_multiple", floor_m},
                 {"mc_noise_floor_total_all_voxels", floor_t_any},
                 {"mc_noise_floor_multiple_all_voxels", floor_m_any},
                 {"mc_noise_floor_single", floor_1},
                 {"relL2_S1_vs_mc_single", err_s1},
                 {"mc_escaped_fraction_of_scattered", mc_esc_multi / mc_scattered},
                 {"runs", js_runs}});
}
