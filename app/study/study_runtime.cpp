// Run-time accuracy.
//   runtime-accuracy: the basis method (engine/runtime: splat onto virtual lights, compressed
//   bases, sparse sum + inverse Haar) against the direct solve of the same frame (the
//   frame's point sources fed to exact single scattering + lattice-Boltzmann, no basis) on
//   the default storm scene, for 5 seeds at the first return stroke: relative L2 error of S
//   over cloud voxels (all directions), total and per component, and the time of each.
//
//   The error is split into its causes with two more solves per seed:
//     V  = the active virtual lights with their weights e_l, solved directly (one solve);
//     U  = sum_l e_l * (light l solved alone) = the bake's bases before compression and drop.
//   R - D = (V - D)  splat: each source replaced by the 8 lights of its cell (Eq. 6)
//         + (U - V)  non-linearity of the solver (lattice-Boltzmann fluence renormalization)
//         + (R - U)  compression (xi) and dropped lights.
//   U costs one solve per active light (a small bake), skipped with --quick.
//   The scene's .fgb is baked first if missing or stale (~2 minutes on 2 cores).
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

using namespace fulgur;

namespace {

struct Parts {
    transport::SourceField single, multiple;
};

// solve::solve on point sources, both parts (what runtime::direct_solve sums).
Parts solve_parts(const scene::Scene& s, const solve::Media& m, std::span<const transport::PointSource> q,
                  double* seconds = nullptr) {
    std::vector<transport::PointSource> pts;
    for (const transport::PointSource& p : q)
        if (p.intensity != 0.0) pts.push_back(p);
    const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
    core::Stopwatch sw;
    solve::Solution sol = solve::solve(s, m, pts, dirs);
    if (seconds) *seconds = sw.seconds();
    return {std::move(sol.single), std::move(sol.multiple)};
}

// Relative L2 of a - b over cloud voxels, all directions, relative to |b| (or to `norm`).
struct L2 {
    const std::vector<float>& density;
    std::size_t cells;
    // value(m, i) -> double
    template <class F>
    double operator()(std::size_t nd, F value) const {
        double s = 0.0;
        for (std::size_t m = 0; m < nd; ++m)
            for (std::size_t i = 0; i < cells; ++i)
                if (density[i] > 0.0f) {
                    const double v = value(m, i);
                    s += v * v;
                }
        return std::sqrt(s);
    }
};

const float* dir_ptr(const transport::SourceField& f, std::size_t m) { return f.data.data() + m * f.cells(); }

}  // namespace

FULGUR_STUDY(runtime_accuracy, "runtime-accuracy",
             "basis method vs direct solve on the default storm, 5 seeds: relative L2 of S over the cloud, per "
             "component, and what the error comes from (splat, solver non-linearity, compression)") {
    const std::filesystem::path scene_path = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm.json";
    const scene::Scene s = scene::load_scene(scene_path);
    const core::Grid3<float> density = scene::make_density(s);
    const std::filesystem::path fgb = bake::default_fgb_path(s);
    double bake_s = 0.0;
    if (const std::optional<bake::Report> r = bake::bake_if_stale(s, density, fgb, {}, [&](const std::string& why) {
            std::fprintf(stderr, "runtime-accuracy: baking %s (%s)\n", fgb.string().c_str(), why.c_str());
        })) {
        bake_s = r->seconds_total;
        std::fprintf(stderr, "runtime-accuracy: baked in %.1f s (%zu lights, %zu dropped, %.1f MB)\n", bake_s,
                     r->lights, r->lights_dropped, double(r->file_bytes) / 1e6);
    }
    const runtime::BakedBases bases = runtime::BakedBases::load(fgb, bake::scene_key(s, density));
    basis::FgbReader reader(fgb);  // per-light coefficient counts (dropped lights)
    const solve::Media media = solve::make_media(s, density);
    const transport::LightingMedium& medium = media.lighting;
    const std::size_t nd = bases.directions().size(), cells = medium.density.size();
    const L2 l2{medium.density.data, cells};
    bake::PlanOptions po;
    po.estimate = false;
    const bake::Plan plan = bake::make_plan(s, density, po);

    const std::vector<std::uint64_t> seeds = {1, 2, 3, 4, 5};
    const bool decompose = !ctx.quick;
    study::Csv csv(ctx.file("runtime_accuracy.csv"),
                   {"seed", "sources", "active_lights", "dropped_active", "err_total", "err_single", "err_multiple",
                    "err_total_far", "err_side_view", "splat_V_vs_D", "basis_R_vs_V", "dropped_share",
                    "nonlinear_U_vs_V", "compression_R_vs_U", "multiple_share", "basis_frame_ms", "direct_solve_s"});
    nlohmann::json rows = nlohmann::json::array();
    for (const std::uint64_t seed : seeds) {
        runtime::FramePipeline p(s, density, bases);
        const std::size_t k = p.strike_at(0.0, seed);
        const double t = p.storm().strike(k).profile.stroke_onset.at(0) + 0.002;  // return stroke
        std::vector<double> frame_ms;
        for (int r = 0; r < 5; ++r) frame_ms.push_back(p.build(t, {}).times.total());
        const runtime::Frame& f = p.build(t, {});
        const std::vector<std::vector<float>> R = f.radiance.values;
        runtime::ReconstructOptions o;
        o.components = {true, false};
        const std::vector<std::vector<float>> R1 = p.build(t, {}, o).radiance.values;
        o.components = {false, true};
        const runtime::Frame& f2 = p.build(t, {}, o);
        const std::vector<std::vector<float>> R2 = f2.radiance.values;
        const std::vector<transport::PointSource> sources = f2.sources;
        const lightning::LightWeights w = f2.weights;

        double direct_s = 0.0;
        const Parts D = solve_parts(s, media, sources, &direct_s);
        auto d_total = [&](std::size_t m, std::size_t i) {
            return double(dir_ptr(D.single, m)[i]) + double(dir_ptr(D.multiple, m)[i]);
        };
        const double nD = l2(nd, d_total),
                     nD1 = l2(nd, [&](auto m, auto i) { return double(dir_ptr(D.single, m)[i]); }),
                     nD2 = l2(nd, [&](auto m, auto i) { return double(dir_ptr(D.multiple, m)[i]); });
        const double err = l2(nd, [&](auto m, auto i) { return double(R[m][i]) - d_total(m, i); }) / nD;
        const double err1 =
            l2(nd, [&](auto m, auto i) { return double(R1[m][i]) - double(dir_ptr(D.single, m)[i]); }) / nD1;
        const double err2 =
            l2(nd, [&](auto m, auto i) { return double(R2[m][i]) - double(dir_ptr(D.multiple, m)[i]); }) / nD2;
        // Away from the channel: voxels whose centre is more than 2 lighting voxels from every source.
        std::vector<float> far_mask(cells, 0.0f);
        const core::GridGeometry& g = medium.density.geom;
        const double r_far = 2.0 * g.voxel_size;
        for (int kz = 0; kz < g.dims.z; ++kz)
            for (int j = 0; j < g.dims.y; ++j)
                for (int i = 0; i < g.dims.x; ++i) {
                    const std::size_t c = g.index(i, j, kz);
                    if (!(medium.density.data[c] > 0.0f)) continue;
                    bool far = true;
                    for (const transport::PointSource& q : sources)
                        if (glm::length(q.position - g.centre(i, j, kz)) < r_far) {
                            far = false;
                            break;
                        }
                    far_mask[c] = far ? 1.0f : 0.0f;
                }
        const L2 l2_far{far_mask, cells};
        const double err_far =
            l2_far(nd, [&](auto m, auto i) { return double(R[m][i]) - d_total(m, i); }) / l2_far(nd, d_total);

        const std::size_t toward = study::toward_side_camera(bases.directions());
        const double err_image = core::relative_l2(
            study::side_view(medium, toward, [&](std::size_t m, std::size_t i) { return double(R[m][i]); }),
            study::side_view(medium, toward, d_total));

        // V: the active virtual lights solved directly; their dropped share.
        std::vector<transport::PointSource> vl, dropped;
        for (const std::uint32_t l : w.active) {
            vl.push_back({bases.lights().position(l), w.e[l]});
            if (reader.read_light(l).coefficient_count() == 0) dropped.push_back(vl.back());
        }
        const Parts V = solve_parts(s, media, vl);
        auto v_total = [&](std::size_t m, std::size_t i) {
            return double(dir_ptr(V.single, m)[i]) + double(dir_ptr(V.multiple, m)[i]);
        };
        const double nV = l2(nd, v_total);
        const double splat = l2(nd, [&](auto m, auto i) { return v_total(m, i) - d_total(m, i); }) / nD;
        const double basis_err = l2(nd, [&](auto m, auto i) { return double(R[m][i]) - v_total(m, i); }) / nV;
        double drop_share = 0.0;
        if (!dropped.empty()) {
            const Parts X = solve_parts(s, media, dropped);
            drop_share =
                l2(nd, [&](auto m,
                           auto i) { return double(dir_ptr(X.single, m)[i]) + double(dir_ptr(X.multiple, m)[i]); }) /
                nV;
        }
        // U: per-light solves summed (uncompressed bases), when decomposing.
        double nonlinear = std::nan(""), compression = std::nan("");
        if (decompose) {
            transport::SourceField U(medium.density.geom, bases.directions());
            for (const std::uint32_t l : w.active) {
                const transport::SourceField b = bake::solve_light(s, media, plan, l);  // [single dirs][multiple dirs]
                const std::size_t parts = b.directions.size() / nd;
                for (std::size_t c = 0; c < parts; ++c)
                    for (std::size_t x = 0; x < nd * cells; ++x)
                        U.data[x] += float(w.e[l] * double(b.data[c * nd * cells + x]));
            }
            const double nU = l2(nd, [&](auto m, auto i) { return double(dir_ptr(U, m)[i]); });
            nonlinear = l2(nd, [&](auto m, auto i) { return double(dir_ptr(U, m)[i]) - v_total(m, i); }) / nV;
            compression = l2(nd, [&](auto m, auto i) { return double(R[m][i]) - double(dir_ptr(U, m)[i]); }) / nU;
        }
        const double dropped_count = double(dropped.size());
        std::sort(frame_ms.begin(), frame_ms.end());
        const double frame = frame_ms[frame_ms.size() / 2];
        const double mult_share = nD2 / nD;
        csv << double(seed) << double(sources.size()) << double(w.active.size()) << dropped_count << err << err1 << err2
            << err_far << err_image << splat << basis_err << drop_share << nonlinear << compression << mult_share
            << frame << direct_s;
        csv.end_row();
        nlohmann::json row = {{"seed", seed},
                              {"sources", sources.size()},
                              {"active_lights", w.active.size()},
                              {"dropped_active_lights", dropped.size()},
                              {"rel_l2_total", err},
                              {"rel_l2_single", err1},
                              {"rel_l2_multiple", err2},
                              {"rel_l2_total_beyond_2_voxels", err_far},
                              {"rel_l2_side_view_image", err_image},
                              {"splat_V_vs_D", splat},
                              {"basis_R_vs_V", basis_err},
                              {"dropped_share_of_V", drop_share},
                              {"multiple_share_of_D", mult_share},
                              {"basis_frame_ms", frame},
                              {"direct_solve_s", direct_s}};
        if (decompose) {
            row["nonlinear_U_vs_V"] = nonlinear;
            row["compression_R_vs_U"] = compression;
        }
        rows.push_back(row);
        std::fprintf(stderr,
                     "seed %llu: %zu sources, %zu lights: error total %.4f single %.4f multiple %.4f (far %.4f, side "
                     "view %.4f); "
                     "splat %.4f, basis %.4f (nonlinear %.4f, compression %.4f); frame %.3f ms, direct %.2f s\n",
                     static_cast<unsigned long long>(seed), sources.size(), w.active.size(), err, err1, err2, err_far,
                     err_image, splat, basis_err, nonlinear, compression, frame, direct_s);
    }
    // Splat error against the virtual-light spacing h, no bake needed: the frame's lit
    // stretches sampled at h/2 (as the pipeline would) and splatted onto the scene's grid
    // rebuilt with h_usr = h, the lights solved directly (V_h), against the same stretches
    // sampled every 50 m and solved directly (D_fine, the reference line source). Also the
    // direct solve of the h/2 sources (D_h): what the point-source spacing alone costs.
    const std::vector<double> spacings =
        ctx.quick ? std::vector<double>{1500.0, 750.0} : std::vector<double>{3000.0, 1500.0, 750.0, 375.0};
    const std::vector<std::uint64_t> sweep_seeds =
        ctx.quick ? std::vector<std::uint64_t>{1} : std::vector<std::uint64_t>{1, 3};
    study::Csv sweep(
        ctx.file("runtime_accuracy_spacing.csv"),
        {"seed", "h_usr", "virtual_lights", "active_lights", "sources", "splat_total", "splat_single", "splat_multiple",
         "sources_only_total", "V_solve_s", "bake_estimate_s", "file_estimate_MB", "scene_h_usr", "lighting_voxel_m"});
    // What each spacing costs to bake: the plan's estimate (16 sample lights solved and
    // encoded as the bake would, ~1-2 s each), so the sweep shows accuracy against cost.
    std::vector<std::pair<double, double>> bake_cost;  // (seconds, MB) per spacing
    for (const double h : spacings) {
        scene::Scene sh = s;
        sh.virtual_lights.h_usr = h;
        const bake::Plan hp = bake::make_plan(sh, density);
        bake_cost.emplace_back(hp.expected_seconds, double(hp.expected_bytes) / 1e6);
    }
    nlohmann::json sweep_rows = nlohmann::json::array();
    for (const std::uint64_t seed : sweep_seeds) {
        runtime::FramePipeline p(s, density, bases);
        const std::size_t k = p.strike_at(0.0, seed);
        const double t = p.storm().strike(k).profile.stroke_onset.at(0) + 0.002;
        const std::vector<lightning::LitSegment> lit = p.build(t, std::vector<int>{0}).segments;
        std::vector<transport::PointSource> fine;
        lightning::append_point_sources(lit, 50.0, fine);
        const Parts F = solve_parts(s, media, fine);
        auto f_total = [&](std::size_t m, std::size_t i) {
            return double(dir_ptr(F.single, m)[i]) + double(dir_ptr(F.multiple, m)[i]);
        };
        const double nF = l2(nd, f_total),
                     nF1 = l2(nd, [&](auto m, auto i) { return double(dir_ptr(F.single, m)[i]); }),
                     nF2 = l2(nd, [&](auto m, auto i) { return double(dir_ptr(F.multiple, m)[i]); });
        for (std::size_t hi = 0; hi < spacings.size(); ++hi) {
            const double h = spacings[hi];
            basis::VirtualLightParams vp = s.virtual_lights;
            vp.h_usr = h;
            const basis::VirtualLightGrid grid = basis::build_virtual_light_grid(density, vp);
            const lightning::Splatter sp(grid);
            std::vector<transport::PointSource> q;
            lightning::append_point_sources(lit, sp.source_spacing(), q);
            lightning::LightWeights w;
            sp.splat(q, w);
            std::vector<transport::PointSource> vl;
            for (const std::uint32_t l : w.active) vl.push_back({grid.position(l), w.e[l]});
            double v_s = 0.0;
            const Parts V = solve_parts(s, media, vl, &v_s);
            const Parts Dh = solve_parts(s, media, q);
            const double e =
                l2(nd,
                   [&](auto m, auto i) {
                       return double(dir_ptr(V.single, m)[i]) + double(dir_ptr(V.multiple, m)[i]) - f_total(m, i);
                   }) /
                nF;
            const double e1 =
                l2(nd,
                   [&](auto m, auto i) { return double(dir_ptr(V.single, m)[i]) - double(dir_ptr(F.single, m)[i]); }) /
                nF1;
            const double e2 =
                l2(nd, [&](auto m,
                           auto i) { return double(dir_ptr(V.multiple, m)[i]) - double(dir_ptr(F.multiple, m)[i]); }) /
                nF2;
            const double eq =
                l2(nd,
                   [&](auto m, auto i) {
                       return double(dir_ptr(Dh.single, m)[i]) + double(dir_ptr(Dh.multiple, m)[i]) - f_total(m, i);
                   }) /
                nF;
            sweep << double(seed) << h << double(grid.count()) << double(w.active.size()) << double(q.size()) << e << e1
                  << e2 << eq << v_s << bake_cost[hi].first << bake_cost[hi].second << s.virtual_lights.h_usr
                  << medium.density.geom.voxel_size;
            sweep.end_row();
            sweep_rows.push_back({{"seed", seed},
                                  {"h_usr", h},
                                  {"virtual_lights", grid.count()},
                                  {"active_lights", w.active.size()},
                                  {"sources", q.size()},
                                  {"splat_rel_l2_total", e},
                                  {"splat_rel_l2_single", e1},
                                  {"splat_rel_l2_multiple", e2},
                                  {"sources_only_rel_l2", eq},
                                  {"bake_estimate_s", bake_cost[hi].first},
                                  {"file_estimate_MB", bake_cost[hi].second}});
            std::fprintf(stderr,
                         "spacing sweep, seed %llu, h %.0f m: %zu lights (%zu active), %zu sources: splat error total "
                         "%.4f single %.4f multiple %.4f; sources at h/2 alone %.4f; bake ~%.0f s, ~%.0f MB\n",
                         static_cast<unsigned long long>(seed), h, grid.count(), w.active.size(), q.size(), e, e1, e2,
                         eq, bake_cost[hi].first, bake_cost[hi].second);
        }
    }
    ctx.summary(
        "runtime-accuracy",
        {{"scene", scene_path.string()},
         {"lighting_grid", {medium.density.geom.dims.x, medium.density.geom.dims.y, medium.density.geom.dims.z}},
         {"lighting_voxel_m", medium.density.geom.voxel_size},
         {"virtual_lights", bases.lights().count()},
         {"h_usr_m", s.virtual_lights.h_usr},
         {"xi", s.compression.xi},
         {"bake_seconds", bake_s},
         {"seeds", rows},
         {"spacing_sweep", sweep_rows}});
}
