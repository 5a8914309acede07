// Lattice-Boltzmann against the Monte Carlo reference.
//   lb-vs-mc: the default storm cloud on its 36x36x20 lighting grid (500 m voxels,
//   26 output directions, g = 0.6, albedo 0.99), an isotropic 1 W/sr point light 750 m
//   below the cloud base under the density-weighted centre of the base layer. Reference:
//   Monte Carlo (all orders, split into order 1 and orders >= 2). Tested: exact single
//   scattering S1 plus LB multiple scattering fed with S1 and the uncollided fluence phi1,
//   for both absorption models (and the published collision for reference). Relative L2
//   errors of S over cloud voxels, for the total and the multiple-scattering part, with the
//   Monte Carlo noise floor.
//
//   The same comparison is repeated on finer lighting grids (downsample 2: 250 m, and 1:
//   125 m, the density grid itself; both solvers on the same finer medium), with the fields
//   averaged back onto the 500 m grid, to separate the lattice's resolution error (one
//   collision per voxel crossing) from everything else.
#include "study/study.h"

#include "cloud/cloud.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/vec2.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

// The columns every per-voxel and profile row carries after its position and density: the direction-mean
// exact single scattering, Monte Carlo's single and multiple scattering with the latter's
// standard error, and the lattice's multiple scattering under both absorption mappings.
const std::array<std::string, 6> kSolverColumns = {
    "S1", "mc_single", "mc_multiple", "mc_multiple_se", "lb_multiple_physical", "lb_multiple_conservative"};

/// A field S[m * cells + c] in double.
using Field = std::vector<double>;

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

/// Block average of a fine field onto the coarse grid (factor f per axis). With `se`, the
/// entries are standard errors of independent voxels: sqrt(sum se^2) / f^3.
Field coarsen(const SourceField& fine, const core::GridGeometry& coarse, int f, bool se = false) {
    const std::size_t M = fine.directions.size(), nc = coarse.cell_count(), nf = fine.cells();
    if (f == 1) return Field(fine.data.begin(), fine.data.end());
    Field r(M * nc, 0.0);
    const core::GridGeometry& g = fine.geom;
    const double inv = 1.0 / double(f * f * f);
    for (std::size_t m = 0; m < M; ++m)
        for (int k = 0; k < g.dims.z; ++k)
            for (int j = 0; j < g.dims.y; ++j)
                for (int i = 0; i < g.dims.x; ++i) {
                    const double v = fine.data[m * nf + g.index(i, j, k)];
                    r[m * nc + coarse.index(i / f, j / f, k / f)] += se ? v * v : v;
                }
    for (double& v : r) v = se ? std::sqrt(v) * inv : v * inv;
    return r;
}

/// Relative L2 error ||x - ref|| / ||ref|| over the listed cells and the directions in
/// [m0, m1) (all directions by default).
double rel_l2(const Field& x, const Field& ref, const std::vector<std::size_t>& cells, std::size_t ncell, std::size_t M,
              std::size_t m0 = 0, std::size_t m1 = std::size_t(-1)) {
    core::RelativeL2 e;
    for (std::size_t m = m0; m < std::min(M, m1); ++m)
        for (std::size_t c : cells) e.add(x[m * ncell + c], ref[m * ncell + c]);
    return e.reference_norm() > 0.0 ? e.value() : std::nan("");
}

/// Noise floor ||se|| / ||ref||: the relative L2 error an exact solution shows against the
/// Monte Carlo estimate, in expectation (the measured error is ~sqrt(bias^2 + floor^2)).
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

double field_sum(const Field& f, const std::vector<std::size_t>& cells, std::size_t ncell, std::size_t M) {
    double s = 0.0;
    for (std::size_t m = 0; m < M; ++m)
        for (std::size_t c : cells) s += f[m * ncell + c];
    return s;
}

/// Mean over directions at one cell.
double dir_mean(const Field& f, std::size_t c, std::size_t ncell, std::size_t M) {
    double s = 0.0;
    for (std::size_t m = 0; m < M; ++m) s += f[m * ncell + c];
    return s / double(M);
}

struct Run {
    std::string label;
    LbCollision collision;
    LbAbsorption absorption;
    double tolerance;
    bool use_phi1;
    LbThickVoxels thick = LbSettings{}.thick_voxels;
};

struct RunResult {
    Field mult;                 ///< LB multiple scattering, on the 500 m grid
    double native_total = 0.0;  ///< relative L2 on the solve's own grid (its cloud voxels)
    double native_multiple = 0.0;
    int iterations = 0;
    bool converged = false;
    double seconds = 0.0;
    double injected = 0.0, escaped = 0.0;  ///< W per step in the steady state
    std::size_t negative_entries = 0;      ///< S entries < 0 (all voxels and directions)
    double most_negative = 0.0;            ///< min S / max S
};

/// Everything solved on one lighting grid, with the fields averaged onto the 500 m grid.
struct Solve {
    int downsample = 4;
    core::GridGeometry geom;
    std::size_t native_cloud_voxels = 0;
    double max_tau_hop = 0.0;
    Field s1, mc1, mcm, se1, sem;
    double native_floor_total = 0.0, native_floor_multiple = 0.0;
    double ss_seconds = 0.0, mc_seconds = 0.0;
    std::uint64_t mc_paths = 0;
    double mc_scattered = 0.0, mc_escaped = 0.0;  ///< W scattered at least once; of it, escaped
    std::vector<RunResult> runs;
};

Solve solve_at(const scene::Scene& scene, const core::Grid3<float>& density, int downsample, const PointSource& light,
               const std::vector<glm::dvec3>& dirs, std::uint64_t paths, const std::vector<Run>& runs,
               const core::GridGeometry& coarse, float cloud_threshold) {
    scene::Scene sc = scene;
    sc.lighting_downsample = downsample;
    const LightingMedium m = scene::make_lighting_medium(sc, density);
    const core::GridGeometry& g = m.density.geom;
    const int f = int(std::lround(coarse.voxel_size / g.voxel_size));
    if (g.dims.x != coarse.dims.x * f || g.dims.y != coarse.dims.y * f || g.dims.z != coarse.dims.z * f)
        throw core::Error("lb-vs-mc", "lighting grid at downsample " + std::to_string(downsample) +
                                          " does not nest in the 500 m grid");
    const std::size_t n = g.cell_count(), M = dirs.size();
    Solve s;
    s.downsample = downsample;
    s.geom = g;
    std::vector<std::size_t> cloud;
    for (std::size_t c = 0; c < n; ++c)
        if (m.density.data[c] > cloud_threshold) {
            cloud.push_back(c);
            s.max_tau_hop = std::max(s.max_tau_hop, m.sigma_t(c) * g.voxel_size);
        }
    s.native_cloud_voxels = cloud.size();

    // Exact single scattering and, from the same quadrature, the uncollided fluence phi1.
    core::Stopwatch w1;
    core::Grid3<float> phi1;
    SingleScatteringOptions so;  // default tolerance 1e-3
    so.uncollided_fluence = &phi1;
    const SourceField S1 = single_scattering(m, light, dirs, so);
    s.ss_seconds = w1.seconds();

    // Monte Carlo reference.
    Field native_mct, native_mcm, native_set, native_sem;
    {
        MonteCarloOptions mo;
        mo.paths = paths;
        mo.batches = 32;
        mo.seed = 20240603;
        const MonteCarloResult mc = monte_carlo(m, light, dirs, mo);
        s.mc_seconds = mc.seconds;
        s.mc_paths = paths;
        s.mc_scattered = mc.energy.scattered_mean();
        s.mc_escaped = mc.energy.escaped_scattered_mean();
        s.mc1 = coarsen(mc.single, coarse, f);
        s.mcm = coarsen(mc.multiple, coarse, f);
        s.se1 = coarsen(mc.single_se, coarse, f, true);
        s.sem = coarsen(mc.multiple_se, coarse, f, true);
        native_mcm.assign(mc.multiple.data.begin(), mc.multiple.data.end());
        native_mct = native_mcm;
        for (std::size_t i = 0; i < native_mct.size(); ++i) native_mct[i] += double(mc.single.data[i]);
        native_sem.assign(mc.multiple_se.data.begin(), mc.multiple_se.data.end());
        native_set = quad_sum(Field(mc.single_se.data.begin(), mc.single_se.data.end()), native_sem);
    }
    s.s1 = coarsen(S1, coarse, f);
    s.native_floor_total = noise_floor(native_set, native_mct, cloud, n, M);
    s.native_floor_multiple = noise_floor(native_sem, native_mcm, cloud, n, M);

    for (const Run& run : runs) {
        LbSources src;
        src.first_scattered = &S1;
        if (run.use_phi1) src.first_scattered_fluence = &phi1;
        LbSettings ls;
        ls.collision = run.collision;
        ls.absorption = run.absorption;
        ls.tolerance = run.tolerance;
        ls.thick_voxels = run.thick;
        const LbResult res = solve_lattice_boltzmann(m, src, dirs, ls);
        RunResult rr;
        rr.mult = coarsen(res.source, coarse, f);
        Field nat_mult(res.source.data.begin(), res.source.data.end()), nat_tot = nat_mult;
        for (std::size_t i = 0; i < nat_tot.size(); ++i) nat_tot[i] += double(S1.data[i]);
        rr.native_total = rel_l2(nat_tot, native_mct, cloud, n, M);
        rr.native_multiple = rel_l2(nat_mult, native_mcm, cloud, n, M);
        rr.iterations = res.iterations;
        rr.converged = res.converged;
        rr.seconds = res.seconds;
        rr.injected = res.injected_per_step;
        rr.escaped = res.escaped_last_step;
        s.runs.push_back(std::move(rr));
        // Over-relaxation (diffusion_matched) can leave negative S entries: count them.
        std::size_t negative = 0;
        float smin = 0.0f, smax = 0.0f;
        for (float v : res.source.data) {
            negative += v < 0.0f;
            smin = std::min(smin, v);
            smax = std::max(smax, v);
        }
        s.runs.back().negative_entries = negative;
        s.runs.back().most_negative = smax > 0.0f ? double(smin) / double(smax) : 0.0;
        std::fprintf(stderr, "lb-vs-mc: %3.0f m grid, %-24s %4d steps, %.2f s, %zu negative S entries (min/max %.2g)\n",
                     g.voxel_size, run.label.c_str(), res.iterations, res.seconds, negative,
                     s.runs.back().most_negative);
    }
    std::fprintf(stderr, "lb-vs-mc: %3.0f m grid: single scattering %.1f s, Monte Carlo %llu paths %.1f s\n",
                 g.voxel_size, s.ss_seconds, static_cast<unsigned long long>(paths), s.mc_seconds);
    return s;
}

}  // namespace

FULGUR_STUDY(lb_vs_mc, "lb-vs-mc",
             "LB (+ exact single scattering) vs Monte Carlo on the default storm, point light below the base: "
             "relative L2 of S over cloud voxels; also on 250 m and 125 m lighting grids") {
    // --- The scene's medium on its lighting grid ------------------------------------------------
    const scene::Scene scene_file =
        scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json");
    // The comparison grid is 500 m (downsample 4), where the 250 m and 125 m grids nest; the
    // scene's own lighting grid (the bake's) is solved as well at the end when it differs.
    scene::Scene sc = scene_file;
    sc.lighting_downsample = 4;
    core::Stopwatch gen;
    const core::Grid3<float> density = scene::make_density(sc);
    const LightingMedium m = scene::make_lighting_medium(sc, density);
    const double gen_s = gen.seconds();
    const core::GridGeometry& g = m.density.geom;
    const std::size_t n = g.cell_count();
    const double h = g.voxel_size;
    const auto dirs = output_directions(sc.effective_directions());
    const std::size_t M = dirs.size();

    // --- Cloud voxels: density > 0.05 (the scene's virtual-light density threshold); the
    //     figures over every voxel with density > 0 are reported too. -------------------------
    constexpr float kCloud = 0.05f;
    std::vector<std::size_t> cloud, any;
    for (std::size_t c = 0; c < n; ++c) {
        if (m.density.data[c] > 0.0f) any.push_back(c);
        if (m.density.data[c] > kCloud) cloud.push_back(c);
    }

    // --- The light: density-weighted centre of the lowest cloud layer, 750 m below the base ----
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
    const double below = 750.0;  // the middle of the 500 m lighting layer below the base
    const PointSource light{{centroid.x, centroid.y, base - below}, 1.0};
    const glm::dvec3 lv = g.to_voxel(light.position);
    const int li = int(std::floor(lv.x)), lj = int(std::floor(lv.y));

    // Runs 0-1: the default thick-voxel mapping; 2-3: the other one (solved on every grid).
    const LbThickVoxels def = LbSettings{}.thick_voxels;
    const LbThickVoxels other =
        def == LbThickVoxels::Saturate ? LbThickVoxels::DiffusionMatched : LbThickVoxels::Saturate;
    auto tname = [](LbThickVoxels t) { return std::string(t == LbThickVoxels::Saturate ? "saturate" : "matched"); };
    const std::vector<Run> runs = {
        {"physical " + tname(def), LbCollision::Corrected, LbAbsorption::Physical, 1e-4, true, def},
        {"conservative " + tname(def), LbCollision::Corrected, LbAbsorption::Conservative, 1e-4, true, def},
        {"physical " + tname(other), LbCollision::Corrected, LbAbsorption::Physical, 1e-4, true, other},
        {"conservative " + tname(other), LbCollision::Corrected, LbAbsorption::Conservative, 1e-4, true, other},
        {"physical tol 1e-6", LbCollision::Corrected, LbAbsorption::Physical, 1e-6, true, def},
        {"physical without phi1", LbCollision::Corrected, LbAbsorption::Physical, 1e-4, false, def},
        {"published physical", LbCollision::Published, LbAbsorption::Physical, 1e-4, true, def},
        {"published conservative", LbCollision::Published, LbAbsorption::Conservative, 1e-4, true, def},
    };
    const std::vector<Run> fine_runs(runs.begin(), runs.begin() + 4);

    // --- Solves: the scene's grid (500 m), then finer lighting grids ---------------------------
    const std::uint64_t paths = ctx.quick ? 200'000 : 20'000'000;
    std::vector<Solve> solves;
    solves.push_back(solve_at(sc, density, sc.lighting_downsample, light, dirs, paths, runs, g, kCloud));
    for (int ds : ctx.quick ? std::vector<int>{2} : std::vector<int>{2, 1})
        solves.push_back(solve_at(sc, density, ds, light, dirs, ctx.quick ? paths : paths / 2, fine_runs, g, kCloud));
    const Solve& S = solves[0];
    const Field mct = sum(S.mc1, S.mcm), set = quad_sum(S.se1, S.sem);
    // (The order-1 and multiple tallies come from the same paths and are not independent;
    // their standard errors added in quadrature approximate the total's.)
    const double floor_t = noise_floor(set, mct, cloud, n, M), floor_m = noise_floor(S.sem, S.mcm, cloud, n, M);
    const double floor_t_any = noise_floor(set, mct, any, n, M), floor_m_any = noise_floor(S.sem, S.mcm, any, n, M);
    const double floor_1 = noise_floor(S.se1, S.mc1, cloud, n, M);
    const double err_s1 = rel_l2(S.s1, S.mc1, cloud, n, M);

    // --- Per run, 500 m grid ----------------------------------------------------------------------
    const double bin_edges[] = {0.0, 0.25, 0.5, 1.0, 1e9};  // axis-hop optical depth sigma_t h
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
                    {"run", "tau_hop_lo", "tau_hop_hi", "voxels", "relL2_total", "relL2_multiple",
                     "noise_floor_multiple", "sum_S_multiple_ratio"});
    nlohmann::json js_runs = nlohmann::json::array();
    for (std::size_t r = 0; r < runs.size(); ++r) {
        const Run& run = runs[r];
        const RunResult& rr = S.runs[r];
        const Field tot = sum(S.s1, rr.mult);
        const double et = rel_l2(tot, mct, cloud, n, M), em = rel_l2(rr.mult, S.mcm, cloud, n, M);
        const double et_any = rel_l2(tot, mct, any, n, M), em_any = rel_l2(rr.mult, S.mcm, any, n, M);
        const double ratio_t = field_sum(tot, cloud, n, M) / field_sum(mct, cloud, n, M);
        const double ratio_m = field_sum(rr.mult, cloud, n, M) / field_sum(S.mcm, cloud, n, M);
        const double power_ratio = rr.injected / S.mc_scattered;
        const double esc_lb = rr.escaped / rr.injected, esc_mc = S.mc_escaped / S.mc_scattered;
        csv << ("\"" + run.label + "\"")
            << std::string(run.collision == LbCollision::Corrected ? "corrected" : "published")
            << std::string(run.absorption == LbAbsorption::Physical ? "physical" : "conservative") << run.tolerance
            << double(run.use_phi1) << double(rr.iterations) << double(rr.converged) << rr.seconds << et << em << et_any
            << em_any << denoised(et, floor_t) << denoised(em, floor_m) << ratio_t << ratio_m << power_ratio << esc_lb
            << esc_mc;
        csv.end_row();
        for (std::size_t b = 0; b + 1 < std::size(bin_edges); ++b) {
            const auto cells = in_bin(b);
            bins << ("\"" + run.label + "\"") << bin_edges[b] << bin_edges[b + 1] << double(cells.size())
                 << rel_l2(tot, mct, cells, n, M) << rel_l2(rr.mult, S.mcm, cells, n, M)
                 << noise_floor(S.sem, S.mcm, cells, n, M)
                 << field_sum(rr.mult, cells, n, M) / field_sum(S.mcm, cells, n, M);
            bins.end_row();
        }
        js_runs.push_back({{"run", run.label},
                           {"iterations", rr.iterations},
                           {"converged", rr.converged},
                           {"lb_seconds", rr.seconds},
                           {"relL2_total", et},
                           {"relL2_multiple", em},
                           {"relL2_total_all_voxels", et_any},
                           {"relL2_multiple_all_voxels", em_any},
                           {"sum_S_total_ratio", ratio_t},
                           {"sum_S_multiple_ratio", ratio_m},
                           {"scattered_power_ratio", power_ratio},
                           {"escaped_fraction_lb", esc_lb},
                           {"negative_S_entries", rr.negative_entries},
                           {"min_S_over_max_S", rr.most_negative}});
    }

    // --- Resolution: finer lighting grids, compared on the 500 m grid ------------------------------
    nlohmann::json js_res = nlohmann::json::array();
    {
        study::Csv rcsv(ctx.file("lb_vs_mc_resolution.csv"), {"downsample",
                                                              "voxel_m",
                                                              "max_tau_hop",
                                                              "run",
                                                              "iterations",
                                                              "lb_seconds",
                                                              "mc_paths",
                                                              "mc_seconds",
                                                              "ss_seconds",
                                                              "relL2_total_500m",
                                                              "relL2_multiple_500m",
                                                              "noise_floor_total_500m",
                                                              "noise_floor_multiple_500m",
                                                              "sum_S_multiple_ratio_500m",
                                                              "relL2_total_native",
                                                              "relL2_multiple_native",
                                                              "noise_floor_total_native",
                                                              "noise_floor_multiple_native",
                                                              "native_cloud_voxels",
                                                              "escaped_fraction_lb",
                                                              "escaped_fraction_mc"});
        for (const Solve& s : solves) {
            const Field t = sum(s.mc1, s.mcm), st = quad_sum(s.se1, s.sem);
            const double ft = noise_floor(st, t, cloud, n, M), fm = noise_floor(s.sem, s.mcm, cloud, n, M);
            for (std::size_t r = 0; r < std::min<std::size_t>(4, s.runs.size()); ++r) {
                const RunResult& rr = s.runs[r];
                const double et = rel_l2(sum(s.s1, rr.mult), t, cloud, n, M), em = rel_l2(rr.mult, s.mcm, cloud, n, M);
                const double ratio = field_sum(rr.mult, cloud, n, M) / field_sum(s.mcm, cloud, n, M);
                const std::uint64_t p = s.mc_paths;
                rcsv << double(s.downsample) << s.geom.voxel_size << s.max_tau_hop << ("\"" + runs[r].label + "\"")
                     << double(rr.iterations) << rr.seconds << double(p) << s.mc_seconds << s.ss_seconds << et << em
                     << ft << fm << ratio << rr.native_total << rr.native_multiple << s.native_floor_total
                     << s.native_floor_multiple << double(s.native_cloud_voxels) << rr.escaped / rr.injected
                     << s.mc_escaped / s.mc_scattered;
                rcsv.end_row();
                js_res.push_back({{"voxel_m", s.geom.voxel_size},
                                  {"run", runs[r].label},
                                  {"relL2_total_500m", et},
                                  {"relL2_multiple_500m", em},
                                  {"sum_S_multiple_ratio_500m", ratio},
                                  {"relL2_total_native", rr.native_total},
                                  {"relL2_multiple_native", rr.native_multiple},
                                  {"noise_floor_multiple_native", s.native_floor_multiple},
                                  {"iterations", rr.iterations},
                                  {"lb_seconds", rr.seconds},
                                  {"mc_paths", p},
                                  {"mc_seconds", s.mc_seconds}});
                std::fprintf(stderr,
                             "lb-vs-mc: %3.0f m grid %-22s total %.4f multiple %.4f (500 m); native %.4f / %.4f\n",
                             s.geom.voxel_size, runs[r].label.c_str(), et, em, rr.native_total, rr.native_multiple);
            }
        }
    }

    // --- The scene's own lighting grid (what the bake uses), if it is not the 500 m one ---------
    if (scene_file.lighting_downsample != sc.lighting_downsample) {
        const LightingMedium ms = scene::make_lighting_medium(scene_file, density);
        const Solve own = solve_at(scene_file, density, scene_file.lighting_downsample, light, dirs, paths / 2,
                                   fine_runs, ms.density.geom, kCloud);
        for (std::size_t r = 0; r < own.runs.size(); ++r) {
            const RunResult& rr = own.runs[r];
            js_res.push_back({{"voxel_m", own.geom.voxel_size},
                              {"grid", "scene (bake) lighting grid"},
                              {"run", runs[r].label},
                              {"relL2_total_native", rr.native_total},
                              {"relL2_multiple_native", rr.native_multiple},
                              {"noise_floor_multiple_native", own.native_floor_multiple},
                              {"iterations", rr.iterations}});
            std::fprintf(stderr, "lb-vs-mc: scene grid %3.0f m %-22s native total %.4f multiple %.4f\n",
                         own.geom.voxel_size, runs[r].label.c_str(), rr.native_total, rr.native_multiple);
        }
    }

    // --- Per direction (physical model, 500 m) -----------------------------------------------------
    {
        study::Csv dcsv(ctx.file("lb_vs_mc_directions.csv"),
                        {"m", "sx", "sy", "sz", "relL2_total_physical", "relL2_multiple_physical",
                         "noise_floor_multiple", "sum_S_multiple_ratio_physical"});
        const Field tot = sum(S.s1, S.runs[0].mult);
        for (std::size_t mm = 0; mm < M; ++mm) {
            double a = 0.0, b = 0.0;
            for (std::size_t c : cloud) {
                a += S.runs[0].mult[mm * n + c];
                b += S.mcm[mm * n + c];
            }
            dcsv << double(mm) << dirs[mm].x << dirs[mm].y << dirs[mm].z << rel_l2(tot, mct, cloud, n, M, mm, mm + 1)
                 << rel_l2(S.runs[0].mult, S.mcm, cloud, n, M, mm, mm + 1)
                 << noise_floor(S.sem, S.mcm, cloud, n, M, mm, mm + 1) << a / b;
            dcsv.end_row();
        }
    }

    // --- Per voxel (direction means, 500 m) ---------------------------------------------------------
    {
        std::vector<std::string> header = {"i", "j", "k", "density", "tau_hop"};
        header.insert(header.end(), kSolverColumns.begin(), kSolverColumns.end());
        for (std::size_t q = 1; q < solves.size(); ++q) {
            const std::string v = std::to_string(int(solves[q].geom.voxel_size)) + "m";
            header.push_back("mc_multiple_" + v);
            header.push_back("lb_multiple_physical_" + v);
        }
        study::Csv vcsv(ctx.file("lb_vs_mc_voxels.csv"), header);
        for (std::size_t c : any) {
            const core::Int3 v = g.unindex(c);
            vcsv << double(v.x) << double(v.y) << double(v.z) << double(m.density.data[c]) << m.sigma_t(c) * h
                 << dir_mean(S.s1, c, n, M) << dir_mean(S.mc1, c, n, M) << dir_mean(S.mcm, c, n, M)
                 << dir_mean(S.sem, c, n, M) << dir_mean(S.runs[0].mult, c, n, M) << dir_mean(S.runs[1].mult, c, n, M);
            for (std::size_t q = 1; q < solves.size(); ++q)
                vcsv << dir_mean(solves[q].mcm, c, n, M) << dir_mean(solves[q].runs[0].mult, c, n, M);
            vcsv.end_row();
        }
    }

    // --- Vertical profile through the light's column (direction-mean S, 500 m) ----------------------
    {
        // The lattice's multiple scattering on the other grids and with the third mapping, by
        // their labels (the plot script draws every column).
        std::vector<std::string> header = {"k", "z_m", "density"};
        header.insert(header.end(), kSolverColumns.begin(), kSolverColumns.end());
        for (std::size_t q = 1; q < solves.size(); ++q)
            header.push_back("lb_multiple_physical_" + std::to_string(int(solves[q].geom.voxel_size)) + "m");
        header.push_back("lb_multiple_physical_" + runs[2].label.substr(9) + "_mapping");
        study::Csv pcsv(ctx.file("lb_vs_mc_profile.csv"), header);
        for (int k = 0; k < g.dims.z; ++k) {
            const std::size_t c = g.index(li, lj, k);
            const double z = g.centre(li, lj, k).z / 1000.0;
            const double a1 = dir_mean(S.s1, c, n, M), b1 = dir_mean(S.mc1, c, n, M), bm = dir_mean(S.mcm, c, n, M);
            const double lp = dir_mean(S.runs[0].mult, c, n, M), lc = dir_mean(S.runs[1].mult, c, n, M);
            pcsv << double(k) << 1000.0 * z << double(m.density.data[c]) << a1 << b1 << bm << dir_mean(S.sem, c, n, M)
                 << lp << lc;
            for (std::size_t q = 1; q < solves.size(); ++q) pcsv << dir_mean(solves[q].runs[0].mult, c, n, M);
            pcsv << dir_mean(S.runs[2].mult, c, n, M);
            pcsv.end_row();
        }
    }

    // --- Summary -----------------------------------------------------------------------------------
    ctx.summary("lb-vs-mc",
                {{"grid", {g.dims.x, g.dims.y, g.dims.z}},
                 {"voxel_m", h},
                 {"directions", M},
                 {"medium", {{"extinction", m.optics.extinction}, {"albedo", m.optics.albedo}, {"g", m.optics.g}}},
                 {"light", {light.position.x, light.position.y, light.position.z}},
                 {"cloud_base_m", base},
                 {"cloud_voxels_rho_gt_0.05", cloud.size()},
                 {"cloud_voxels_rho_gt_0", any.size()},
                 {"max_hop_optical_depth", S.max_tau_hop},
                 {"cloud_seconds", gen_s},
                 {"single_scattering_seconds", S.ss_seconds},
                 {"mc_paths", paths},
                 {"mc_seconds", S.mc_seconds},
                 {"threads", core::thread_count()},
                 {"mc_noise_floor_total", floor_t},
                 {"mc_noise_floor_multiple", floor_m},
                 {"mc_noise_floor_total_all_voxels", floor_t_any},
                 {"mc_noise_floor_multiple_all_voxels", floor_m_any},
                 {"mc_noise_floor_single", floor_1},
                 {"relL2_S1_vs_mc_single", err_s1},
                 {"mc_escaped_fraction_of_scattered", S.mc_escaped / S.mc_scattered},
                 {"runs", js_runs},
                 {"resolution", js_res}});
    // Against the truth, one light at a time, today's lattice and the refined one.
    study::lb_vs_truth(ctx);
}
