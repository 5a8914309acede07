// What the truth leaves out of a cloud with sub-voxel detail.
//   detail-truth: the solvers and the truth integrate the detail's voxel means on the density
//   grid (cloud.md, "Sub-voxel detail"); structure finer than a voxel is only drawn. This
//   measures what that structure does to the light, one octave below the grid: on
//   content/scenes/storm-full.json's cloud resampled to 62.5 m voxels (the undetailed cloud's
//   trilinear field at the fine centres), the truth of the same strike through
//     fine:    the detail's means over each 62.5 m voxel (structure down to 62.5 m resolved);
//     coarse:  the same field averaged over each 125 m block and spread back over its eight
//              62.5 m voxels (the same extinction per 125 m voxel, nothing finer);
//   and, as a control, the same two without detail (the smooth cloud's own 62.5 m structure).
//   S on the same 750 m lighting grid (lighting downsample doubled). Outputs detail_truth.csv:
//   per strike, the relative L2 of coarse against fine (total, single, multiple), and the
//   truths' noise (the part of the difference noise alone explains).
#include "study/study.h"

#include "bake/bake.h"
#include "cloud/subvoxel.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <cmath>
#include <cstdio>

using namespace fulgur;

namespace {

// The 125 m grid's trilinear field sampled at the centres of a grid of half its voxel.
core::Grid3<float> halve_voxels(const core::Grid3<float>& d) {
    core::GridGeometry g = d.geom;
    g.dims = {2 * g.dims.x, 2 * g.dims.y, 2 * g.dims.z};
    g.voxel_size *= 0.5;
    core::Grid3<float> out(g);
    core::parallel_for(0, g.dims.z, [&](std::int64_t k) {
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) out.at(i, j, int(k)) = d.sample(g.centre(i, j, int(k)));
    });
    return out;
}

// Each 2x2x2 block replaced by its mean: the same extinction per coarse voxel, nothing finer.
core::Grid3<float> block_means(const core::Grid3<float>& f) {
    core::Grid3<float> out(f.geom);
    const core::Int3 n = f.geom.dims;
    for (int k = 0; k < n.z; k += 2)
        for (int j = 0; j < n.y; j += 2)
            for (int i = 0; i < n.x; i += 2) {
                double s = 0.0;
                for (int c = 0; c < 2; ++c)
                    for (int b = 0; b < 2; ++b)
                        for (int a = 0; a < 2; ++a) s += f.at(i + a, j + b, k + c);
                for (int c = 0; c < 2; ++c)
                    for (int b = 0; b < 2; ++b)
                        for (int a = 0; a < 2; ++a) out.at(i + a, j + b, k + c) = float(s / 8.0);
            }
    return out;
}

}  // namespace

FULGUR_STUDY(detail_truth, "detail-truth",
             "what the truth leaves out of a cloud with sub-voxel detail: on storm-full.json's cloud at 62.5 m "
             "voxels, the truth through the detail resolved at 62.5 m against the same field averaged over each "
             "125 m voxel (and, as a control, the same without detail), 2 strikes") {
    const scene::Scene full =
        scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes/storm-full.json");
    // The strikes: the detailed storm's own bolts (its bake, as the demo uses it).
    const core::Grid3<float> density = scene::make_density(full);
    bake::bake_if_stale(full, density, bake::default_fgb_path(full));
    const runtime::BakedBases bases =
        runtime::BakedBases::load(bake::default_fgb_path(full), bake::scene_key(full, density));
    scene::Scene s = full;
    s.lightning.schedule.strike_rate = 0.0;
    scene::Scene fine_scene = s;  // 62.5 m density voxels, the same 750 m lighting grid
    fine_scene.lighting_downsample = 2 * s.lighting_downsample;

    const core::Grid3<float> smooth = halve_voxels(scene::make_undetailed_density(full));
    const cloud::DetailNoise noise(*full.cloud.detail);
    struct Medium {
        const char* name;
        core::Grid3<float> fine, coarse;
    };
    std::vector<Medium> media;
    media.push_back({"detail", cloud::detailed_density(smooth, noise), {}});
    media.push_back({"no detail", smooth, {}});
    for (Medium& m : media) m.coarse = block_means(m.fine);

    const std::uint64_t paths = ctx.quick ? 200'000 : 2'000'000;
    const int strikes = ctx.quick ? 1 : 2;
    const std::vector<float> rho = solve::make_media(fine_scene, media[0].fine).lighting.density.data;
    study::Csv rows(ctx.file("detail_truth.csv"),
                    {"seed", "medium", "total_error", "single_error", "multiple_error", "noise_fine", "noise_coarse"});
    nlohmann::json summary = nlohmann::json::array();
    for (int k = 0; k < strikes; ++k) {
        const std::uint64_t seed = std::uint64_t(k + 1);
        runtime::FramePipeline p(s, density, bases, {}, scene::quality_preset("paper"));
        const std::size_t i = p.strike_at(0.0, seed);
        const double t = p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
        const runtime::Frame f = p.build(t, {});
        runtime::TruthOptions to;
        to.paths = paths;
        to.seed = seed;
        for (const Medium& m : media) {
            std::fprintf(stderr, "detail-truth: strike %llu, %s: fine and coarse truths (%llu paths each)\n",
                         static_cast<unsigned long long>(seed), m.name, static_cast<unsigned long long>(paths));
            const runtime::Truth a = runtime::truth(fine_scene, m.fine, f.segments, {}, to);
            const runtime::Truth b = runtime::truth(fine_scene, m.coarse, f.segments, {}, to);
            const double e = study::cloud_error(b.sum().data, a.sum().data, rho);
            const double e1 = study::cloud_error(b.single.data, a.single.data, rho);
            const double e2 = study::cloud_error(b.multiple.data, a.multiple.data, rho);
            rows << double(seed) << std::string(m.name) << e << e1 << e2 << a.noise.total << b.noise.total;
            rows.end_row();
            std::fprintf(stderr,
                         "detail-truth: strike %llu, %-9s coarse vs fine: total %.4f, single %.4f, multiple %.4f "
                         "(noise %.4f, %.4f)\n",
                         static_cast<unsigned long long>(seed), m.name, e, e1, e2, a.noise.total, b.noise.total);
            summary.push_back({{"seed", seed},
                               {"medium", m.name},
                               {"total_error", e},
                               {"single_error", e1},
                               {"multiple_error", e2},
                               {"noise", std::max(a.noise.total, b.noise.total)}});
        }
    }
    ctx.summary("detail-truth", {{"rows", summary}, {"paths", paths}});
}
