// Scenes baked once per test program for the tests against the truth, and what those tests
// compare with: the tiny anisotropic test scene with a refined transport grid
// (transport.refine 4: the solvers run on the density grid itself, 500 m, hop optical depth
// <= 2) and the default storm cut small (its central tower on 375 m voxels, its virtual lights,
// lighting voxels and lightning).
#pragma once

#include "runtime/runtime.h"

#include "bake/bake.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
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

/// The scene file `json` (under the source tree), with `edit` applied, baked on first use into
/// the cache folder `scratch` (the calling test program's own: test programs run in parallel,
/// and two bakes into one folder would collide). The folder is keyed by the engine's source
/// (test::code_cache_dir) and the file by the scene (bake::up_to_date: its hash and header), so
/// a run of the same build reuses the bake and a changed engine or scene bakes afresh. A bake
/// that throws leaves nothing half-built behind: the next call tries again.
inline const TruthScene& baked_scene(const std::string& json, const std::string& scratch,
                                     const std::function<void(scene::Scene&)>& edit = {}) {
    static std::map<std::string, std::unique_ptr<TruthScene>> cache;
    std::unique_ptr<TruthScene>& cached = cache[scratch];
    if (!cached) {
        auto s = std::make_unique<TruthScene>();
        s->scene = scene::load_scene(source_dir() / json);
        if (edit) edit(s->scene);
        s->density = scene::make_density(s->scene);
        s->media = solve::make_media(s->scene, s->density);
        bake::PlanOptions po;
        po.estimate = false;
        s->plan = bake::make_plan(s->scene, s->density, po);
        const std::filesystem::path fgb = code_cache_dir(scratch) / "scene.fgb";
        if (!bake::up_to_date(s->scene, s->density, fgb)) bake::bake(s->scene, s->density, s->plan, fgb);
        s->bases = std::make_unique<runtime::BakedBases>(
            runtime::BakedBases::load(fgb, bake::scene_key(s->scene, s->density)));
        cached = std::move(s);
    }
    return *cached;
}

/// The tiny anisotropic scene with transport.refine 4 (~1 s to bake).
inline const TruthScene& truth_scene(const std::string& scratch) {
    return baked_scene("tests/apps/scenes/test_aniso_ms_cg.json", scratch,
                       [](scene::Scene& s) { s.transport.refine = 4; });
}

/// The default storm cut small (tests/apps/scenes/test_storm_small.json; ~25 s to bake on 2
/// cores): the storm's medium, lightning, 1500 m virtual lights and 750 m lighting voxels, on
/// its central tower alone at 375 m voxels, without the moon and the sky.
inline const TruthScene& storm_small_scene(const std::string& scratch) {
    return baked_scene("tests/apps/scenes/test_storm_small.json", scratch);
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

/// The frame at time t with its strikes' solves waited for, single and multiple scattering
/// built apart; `frame` is the pipeline's last frame (the multiple part's: segments, counts).
struct FrameParts {
    std::vector<float> single, multiple;
    const runtime::Frame* frame = nullptr;
};
inline FrameParts frame_parts(runtime::FramePipeline& p, double t) {
    runtime::ReconstructOptions o;
    o.wait_for_strikes = true;
    o.components = {true, false};
    FrameParts out;
    out.single = flat(p.build(t, {}, o).radiance);
    o.components = {false, true};
    out.frame = &p.build(t, {}, o);
    out.multiple = flat(out.frame->radiance);
    return out;
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

/// A quality preset's measured error on one strike against the truth: relative L2 and sum
/// ratio of the single and the multiple part over the cloud.
struct PresetFigures {
    std::uint64_t seed;
    scene::Quality::Preset preset;
    double single_l2, single_ratio, multiple_l2, multiple_ratio;
};

/// How check_presets_against_truth runs and what noise it allows besides the truth's own.
struct PresetCheck {
    std::uint64_t truth_paths = 1'000'000;
    /// Presets other than per_strike_mc: their per-strike single-scattering paths (hybrid and
    /// per_strike), fewer than the preset's default to keep the test short.
    std::uint64_t single_paths = 100'000;
    /// instant: the path caps it is traced to (its converged estimate).
    std::uint64_t instant_single_paths = 100'000, instant_multiple_paths = 400'000;
    /// per_strike_mc and instant: their own Monte Carlo noise on the relative L2 and on the
    /// sum ratios.
    double mc_l2 = 0.01, mc_ratio = 0.005;
};

/// Each row's preset on its strike (at its first return stroke + 2 ms, the solve waited for),
/// single and multiple part apart, against runtime::truth of the same frame. Every preset but
/// instant is deterministic per seed (instant's rounds split paths between threads as they
/// run: its figures move in the 4th digit), so what moves the figures while the physics stays
/// is the truth's noise and the per-strike Monte Carlo's own. Each part's relative L2 must be at most the
/// measured figure + 4 x the truth's L2 noise of that part; its ratio of whole-cloud totals
/// within the measured ratio +- 4 standard errors of the truth's total (Truth::sums: ~0.1-0.3%,
/// where the L2 noise is 0.5-1%), so a part 5% off fails on its ratio whatever its L2 error.
/// per_strike_mc and instant add their own noise (`c.mc_*`). Also: no NaN or Inf, and negative S (the
/// lattice's over-relaxed sites) at most 0.5% of the field's maximum.
inline void check_presets_against_truth(const TruthScene& s, const std::vector<PresetFigures>& measured,
                                        const PresetCheck& c = {}) {
    using P = scene::Quality::Preset;
    const std::vector<float>& rho = s.media.lighting.density.data;
    runtime::TruthOptions to;
    to.paths = c.truth_paths;
    std::uint64_t truth_seed = 0;
    std::optional<runtime::Truth> truth;
    for (const PresetFigures& m : measured) {
        CAPTURE(m.seed);
        CAPTURE(scene::to_string(m.preset));
        scene::Quality q = scene::quality_preset(scene::to_string(m.preset));
        const bool monte_carlo = m.preset == P::PerStrikeMc || m.preset == P::Instant;
        if (m.preset == P::Instant) {
            // Nobody scheduled the strike; traced to the path caps (not the noise target, where
            // it stops depends on the machine's load), so the converged estimate is compared.
            q.lookahead = 0.0;
            q.target_noise = 1e-4;
            q.single_paths = c.instant_single_paths;
            q.multiple_paths = c.instant_multiple_paths;
        } else if (m.preset != P::PerStrikeMc) {
            q.single_paths = c.single_paths;
        }
        runtime::FramePipeline p(s.scene, s.density, *s.bases, {}, q);
        const double t = peak_time(p, m.seed);
        const FrameParts parts = frame_parts(p, t);
        const runtime::Frame& f = *parts.frame;
        REQUIRE(f.lit);
        CHECK(f.strikes_fallback == 0);
        const std::vector<float>&single = parts.single, &multiple = parts.multiple;
        if (truth_seed != m.seed) {
            truth = runtime::truth(s.scene, s.density, f.segments, {}, to);
            truth_seed = m.seed;
            MESSAGE("strike " << m.seed << ": truth noise single " << truth->noise.single << ", multiple "
                              << truth->noise.multiple << "; totals' SE "
                              << truth->sums.single.se / truth->sums.single.mean << ", "
                              << truth->sums.multiple.se / truth->sums.multiple.mean << " (" << truth->seconds
                              << " s)");
        }
        const FieldError e1 = compare_fields(single, truth->single.data, rho),
                         e2 = compare_fields(multiple, truth->multiple.data, rho);
        MESSAGE("strike " << m.seed << ", " << scene::to_string(m.preset) << ": single " << e1.l2 << " (ratio "
                          << e1.ratio << "), multiple " << e2.l2 << " (ratio " << e2.ratio << ")");
        const double own = monte_carlo ? 1.0 : 0.0;
        const double n1 = 4.0 * truth->noise.single, n2 = 4.0 * truth->noise.multiple;
        const double r1 = 4.0 * truth->sums.single.se / truth->sums.single.mean,
                     r2 = 4.0 * truth->sums.multiple.se / truth->sums.multiple.mean;
        CHECK(e1.l2 <= m.single_l2 + n1 + c.mc_l2 * own);
        CHECK(e2.l2 <= m.multiple_l2 + n2 + c.mc_l2 * own);
        CHECK(std::fabs(e1.ratio - m.single_ratio) <= m.single_ratio * r1 + c.mc_ratio * own);
        CHECK(std::fabs(e2.ratio - m.multiple_ratio) <= m.multiple_ratio * r2 + c.mc_ratio * own);
        const ValueRange r = finite_range({&single, &multiple});
        CHECK(r.lo >= -0.005f * r.hi);
    }
}

/// Two strikes 10 s apart (seeds 11, 12) under `q`, which must not solve them ahead: the first
/// is waited for; with the per-strike work paused (`pause(p, true)`) the second's frame must be
/// the paper frame bit for bit, nothing of the first strike's light; `while_paused` may check
/// more then; resumed, the second is lit by its own light.
// The bases' frame of strike k's strokes as an instant strike carries it before its first
// estimate: `frame` plus its near-field correction (InstantStrikes::near_field) at the glow of
// time t; `frame` unchanged when the pipeline makes none.
inline std::vector<float> with_near_field(runtime::FramePipeline& p, const lightning::Strike& k, double t,
                                          std::vector<float> frame) {
    const runtime::InstantStrikes* instant = p.instant_strikes();
    const auto near = instant ? instant->near_field(k.seed, k.time) : nullptr;
    if (!near) return frame;
    const lightning::FlashState st = lightning::flash_state(k.profile, p.storm().params().timing, t - k.time);
    const float glow[2] = {float(st.main_glow), float(st.branch_glow)};
    for (std::size_t q = 0; q < 2; ++q) {
        const runtime::NearFieldParts& part = (*near)[q];
        if (part.single.size() != frame.size()) continue;
        for (std::size_t i = 0; i < frame.size(); ++i) {
            frame[i] += glow[q] * part.single[i];
            frame[i] += glow[q] * part.multiple[i];
        }
    }
    return frame;
}

// Largest |a - b| over the largest |b|: 0 for equal fields (float rounding: ~1e-7).
inline double max_relative_difference(const std::vector<float>& a, const std::vector<float>& b) {
    double d = 0.0, m = 0.0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        d = std::max(d, std::fabs(double(a[i]) - double(b[i])));
        m = std::max(m, std::fabs(double(b[i])));
    }
    return a.size() == b.size() && m > 0.0 ? d / m : (a == b ? 0.0 : 1.0);
}

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
    // The paper frame, with strike b's own near-field correction where the preset makes one:
    // nothing of strike a's light (which is of the order of the whole field). Equal to float
    // rounding: the frame adds the correction in its own order.
    const std::vector<float> expected = with_near_field(p, p.storm().strike(b), tb, bases_only);
    if (expected == bases_only)
        CHECK(shown == bases_only);
    else
        CHECK(max_relative_difference(shown, expected) < 1e-5);
    if (while_paused) while_paused(p, p.storm().strike(b));
    pause(p, false);
    const runtime::Frame& fb2 = p.build(tb, {}, wait);
    CHECK(fb2.strikes_solved == 1);
    CHECK(flat(fb2.radiance) != bases_only);
}

}  // namespace fulgur::test
