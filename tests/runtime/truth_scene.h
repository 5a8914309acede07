// The tiny anisotropic test scene with a refined transport grid (transport.refine 4: the
// solvers run on the density grid itself, 500 m, hop optical depth <= 2), baked once per test
// program, and what the tests against the truth compare with.
#pragma once

#include "runtime/runtime.h"

#include "bake/bake.h"
#include "support/test_support.h"

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace fulgur::test {

struct TruthScene {
    scene::Scene scene;
    core::Grid3<float> density;
    solve::Media media;
    bake::Plan plan;
    std::unique_ptr<runtime::BakedBases> bases;
};

/// The scene, baked on first use into `scratch` (a folder of the calling test program's own:
/// test programs run in parallel, and two bakes into one folder would collide). A bake that
/// throws leaves nothing half-built behind: the next call tries again.
inline const TruthScene& truth_scene(const std::string& scratch) {
    static std::unique_ptr<TruthScene> cached;
    if (!cached) {
        auto s = std::make_unique<TruthScene>();
        s->scene = scene::load_scene(source_dir() / "tests/apps/scenes/test_aniso_ms_cg.json");
        s->scene.transport.refine = 4;
        s->density = scene::make_density(s->scene);
        s->media = solve::make_media(s->scene, s->density);
        bake::PlanOptions po;
        po.estimate = false;
        s->plan = bake::make_plan(s->scene, s->density, po);
        const std::filesystem::path fgb = scratch_dir(scratch) / "scene.fgb";
        bake::bake(s->scene, s->density, s->plan, fgb);
        s->bases = std::make_unique<runtime::BakedBases>(
            runtime::BakedBases::load(fgb, bake::scene_key(s->scene, s->density)));
        cached = std::move(s);
    }
    return *cached;
}

/// Relative L2 of x against ref and the ratio of their sums, over cloud voxels (lighting-grid
/// density > 0), every direction.
struct FieldError {
    double l2 = 0.0, ratio = 0.0;
};
inline FieldError compare_fields(std::span<const float> x, std::span<const float> ref,
                                 const std::vector<float>& density) {
    core::RelativeL2 e;
    double sx = 0.0, sr = 0.0;
    const std::size_t cells = density.size();
    for (std::size_t i = 0; i < ref.size(); ++i)
        if (density[i % cells] > 0.0f) {
            e.add(x[i], ref[i]);
            sx += x[i];
            sr += ref[i];
        }
    return {e.value(), sx / sr};
}

/// The strike at t = 0 with `seed`: its first return stroke + 2 ms.
inline double peak_time(runtime::FramePipeline& p, std::uint64_t seed) {
    const std::size_t i = p.strike_at(0.0, seed);
    return p.storm().strike(i).profile.stroke_onset.at(0) + 0.002;
}

/// A frame's radiance for all directions as one array (direction-major).
inline std::vector<float> flat(const runtime::RadianceField& r) {
    std::vector<float> v;
    for (const auto& d : r.values) v.insert(v.end(), d.begin(), d.end());
    return v;
}

}  // namespace fulgur::test
