// The tiny anisotropic test scene with a refined transport grid (transport.refine 4: the
// solvers run on the density grid itself, 500 m, hop optical depth <= 2), baked once per test
// program, and what the tests against the truth compare with.
#pragma once

#include "runtime/runtime.h"

#include "bake/bake.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <initializer_list>
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

/// The smallest (<= 0) and largest (>= 0) value of the fields; each value must be finite.
struct ValueRange {
    float lo = 0.0f, hi = 0.0f;
};
inline ValueRange finite_range(std::initializer_list<const std::vector<float>*> fields) {
    ValueRange r;
    for (const std::vector<float>* v : fields)
        for (const float x : *v) {
            REQUIRE(std::isfinite(x));
            r.lo = std::min(r.lo, x);
            r.hi = std::max(r.hi, x);
        }
    return r;
}

/// Two strikes 10 s apart (seeds 11, 12) under `q`, which must not solve them ahead: the first
/// is waited for; with the per-strike work paused (`pause(p, true)`) the second's frame must be
/// the paper frame bit for bit, nothing of the first strike's light; `while_paused` may check
/// more then; resumed, the second is lit by its own light.
inline void check_unsolved_strike_shows_the_bases(
    const TruthScene& s, const scene::Quality& q, const std::function<void(runtime::FramePipeline&, bool)>& pause,
    const std::function<void(runtime::FramePipeline&, const lightning::Strike&)>& while_paused = {}) {
    runtime::FramePipeline p(s.scene, s.density, *s.bases, {}, q);
    runtime::FramePipeline paper(s.scene, s.density, *s.bases, {}, scene::quality_preset("paper"));
    const std::size_t a = p.strike_at(0.0, 11), b = p.strike_at(10.0, 12);
    paper.strike_at(0.0, 11);
    paper.strike_at(10.0, 12);
    const double ta = p.storm().strike(a).profile.stroke_onset.at(0) + 0.002;
    const double tb = 10.0 + p.storm().strike(b).profile.stroke_onset.at(0) + 0.002;
    runtime::ReconstructOptions wait;
    wait.wait_for_strikes = true;
    const runtime::Frame& fa = p.build(ta, {}, wait);
    CHECK(fa.strikes_solved == 1);
    CHECK(fa.strikes_fallback == 0);
    pause(p, true);  // strike b cannot be solved before its frame
    const runtime::Frame& fb = p.build(tb, {});
    CHECK(fb.strikes_solved == 0);
    CHECK(fb.strikes_fallback == 1);
    const std::vector<float> shown = flat(fb.radiance);
    const std::vector<float> bases_only = flat(paper.build(tb, {}).radiance);
    CHECK(shown == bases_only);  // the paper frame, bit for bit: nothing of strike a's light
    if (while_paused) while_paused(p, p.storm().strike(b));
    pause(p, false);
    const runtime::Frame& fb2 = p.build(tb, {}, wait);
    CHECK(fb2.strikes_solved == 1);
    CHECK(flat(fb2.radiance) != bases_only);
}

}  // namespace fulgur::test
