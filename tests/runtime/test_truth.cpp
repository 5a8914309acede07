// The bake and the run time against the truth (runtime::truth: Monte Carlo through the
// full-resolution density), on the tiny anisotropic test scene with a refined transport grid
// (truth_scene.h): a virtual light's bases and a frame of each quality preset for two strikes, per
// component, with bounds from each one's measured error and the truth's noise, tight enough that
// a 5% error in either component fails (test_truth_storm: the same presets on the default storm
// cut small). Also: a strike whose solve
// is not ready is shown by the bases, never by another strike's light; with rain, a solved
// strike's light at the rain against the truth's there, solved ahead and the instant way.
#include "runtime/runtime.h"

#include "truth_scene.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

using namespace fulgur;
using test::compare_fields;
using test::flat;
using test::peak_time;

namespace {

// The tiny scene with a rain shaft under its thickest columns, baked once.
const test::TruthScene& rain_scene() {
    return test::baked_scene("tests/apps/scenes/test_aniso_ms_cg.json", "truth_rain", [](scene::Scene& sc) {
        sc.transport.refine = 4;
        cloud::RainParams r;
        r.rate = 25.0;
        r.threshold = 0.3;
        sc.rain = r;
    });
}

// The lighting cells the rain reaches (with cloud or without: `wet`), and those of rain alone
// (no cloud in the lighting voxel), as 0/1 masks.
struct RainCells {
    std::vector<float> wet, only_rain;
    int cells = 0, alone = 0;
};
RainCells rain_cells(const test::TruthScene& s) {
    const cloud::RainField rain = cloud::make_rain(s.density, *s.scene.rain);
    const core::Grid3<float> lit = core::downsample(rain.extinction, s.scene.lighting_downsample);
    const std::vector<float>& cloud = s.media.lighting.density.data;
    RainCells r;
    r.wet.assign(cloud.size(), 0.0f);
    r.only_rain.assign(cloud.size(), 0.0f);
    for (std::size_t i = 0; i < cloud.size(); ++i)
        if (lit.data[i] > 0.0f) {
            r.wet[i] = 1.0f;
            ++r.cells;
            if (!(cloud[i] > 0.0f)) {
                r.only_rain[i] = 1.0f;
                ++r.alone;
            }
        }
    return r;
}

// Strike 5 at its peak under `p` (its solve waited for; `t` set to the time), a frame with
// light at the rain.
const runtime::Frame& rain_frame(runtime::FramePipeline& p, const test::TruthScene& s, double& t) {
    t = peak_time(p, 5);
    runtime::ReconstructOptions o;
    o.wait_for_strikes = true;
    const runtime::Frame& f = p.build(t, {}, o);
    REQUIRE(f.lit);
    REQUIRE(f.strikes_solved == 1);
    REQUIRE(f.rain.values.size() == f.radiance.values.size());
    CHECK(f.rain.directions == f.radiance.directions);
    CHECK(f.rain.geometry == s.media.lighting.density.geom);
    return f;
}

}  // namespace

TEST_CASE("truth: a virtual light's bases against the truth, per component") {
    const test::TruthScene& s = test::truth_scene("truth_refine4");
    // The virtual light nearest the cloud's density-weighted centre: inside the cloud.
    const core::GridGeometry& g = s.density.geom;
    glm::dvec3 centre(0.0);
    double mass = 0.0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                centre += double(s.density.at(i, j, k)) * g.centre(i, j, k);
                mass += s.density.at(i, j, k);
            }
    centre /= mass;
    std::uint32_t best = 0;
    for (std::uint32_t l = 1; l < s.plan.lights.count(); ++l)
        if (glm::length(s.plan.lights.position(l) - centre) < glm::length(s.plan.lights.position(best) - centre))
            best = l;
    const transport::SourceField bases = bake::solve_light(s.scene, s.media, s.plan, best);
    const std::size_t n = bases.cells() * 26;
    const std::span<const float> single(bases.data.data(), n), multiple(bases.data.data() + n, n);
    runtime::TruthOptions to;
    to.paths = 200'000;  // noise ~0.5% (printed): far below the bounds
    const transport::PointSource p{s.plan.lights.position(best), 1.0};
    const runtime::Truth t = runtime::truth(s.scene, s.density, {}, std::span(&p, 1), to);
    const std::vector<float>& rho = s.media.lighting.density.data;
    const test::FieldError e1 = compare_fields(single, t.single.data, rho),
                           e2 = compare_fields(multiple, t.multiple.data, rho);
    MESSAGE("light " << best << ": single " << e1.l2 << " (sum ratio " << e1.ratio << "), multiple " << e2.l2
                     << " (sum ratio " << e2.ratio << "); truth noise " << t.noise.single << " / " << t.noise.multiple
                     << ", " << t.seconds << " s");
    // Measured: single 0.57% relative L2, sum ratio 1.001 (exact single scattering up to the
    // coarse medium: the lighting grid's density is the density averaged over 4^3 voxels);
    // multiple 21.3%, ratio 0.976 (the lattice on the 500 m density grid: its angular and
    // spatial error, docs/lattice-boltzmann.md). Bounds: these figures plus 4 x the truth's L2
    // noise of the part (0.3% / 0.7%, printed; a bound on the noise of the sums too), so a 5%
    // error of either part moves its ratio beyond the band and fails.
    const double n1 = 4.0 * t.noise.single, n2 = 4.0 * t.noise.multiple;
    CHECK(e1.l2 <= 0.0057 + n1);
    CHECK(std::fabs(e1.ratio - 1.001) <= n1);
    CHECK(e2.l2 <= 0.213 + n2);
    CHECK(std::fabs(e2.ratio - 0.9755) <= n2);
}

TEST_CASE("truth: a frame of each preset against the truth, per component, two strikes") {
    // Each preset's own error, measured (4 km virtual lights on 2 km lighting voxels, so the
    // splat dominates the paper frame and the hybrid's multiple part; per_strike is the lattice
    // with order 2 exact; per_strike_mc 50k paths, ~1% L2 of its own on these voxels): relative
    // L2 and ratio of totals of single and multiple scattering against the truth (1M paths: L2
    // noise 0.3% single, 0.7% multiple; the totals' SE 0.06-0.08% and 0.18%). The ratio bands
    // (test::check_presets_against_truth: 4 SE of the truth's totals) are +-0.25% (single) and
    // +-0.74% (multiple): a 5% error in either part of any preset moves its ratio by 3.9-5% (5%
    // of 0.78-1.00) and fails.
    using P = scene::Quality::Preset;
    test::check_presets_against_truth(test::truth_scene("truth_refine4"),
                                      {{5, P::Paper, 0.7259, 0.7826, 0.5488, 0.8287},
                                       {5, P::Hybrid, 0.0100, 1.0017, 0.5488, 0.8287},
                                       {5, P::PerStrike, 0.0100, 1.0017, 0.1289, 0.9402},
                                       {5, P::PerStrikeMc, 0.0128, 1.0029, 0.0289, 0.9951},
                                       {11, P::Paper, 0.4848, 0.8605, 0.5181, 0.8023},
                                       {11, P::Hybrid, 0.0097, 1.0018, 0.5181, 0.8023},
                                       {11, P::PerStrike, 0.0097, 1.0018, 0.1342, 0.9475},
                                       {11, P::PerStrikeMc, 0.0129, 1.0031, 0.0283, 1.0016}});
}

TEST_CASE("truth: a strike whose solve is not ready is shown by the bases, never by another strike's light") {
    scene::Quality q = scene::quality_preset("per_strike");
    q.single_paths = 20'000;
    q.lookahead = 0.0;  // nothing is solved ahead: the second strike is requested by its frame
    test::check_unsolved_strike_shows_the_bases(test::truth_scene("truth_refine4"), q,
                                                [](runtime::FramePipeline& p, bool paused) {
                                                    REQUIRE(p.strike_solver() != nullptr);
                                                    p.strike_solver()->set_paused(paused);
                                                });
}

TEST_CASE("truth: solved strikes toward the camera (quality.directions) against a truth tallied toward it") {
    // The kept strike of the test above, tallied toward the scene's camera from every 500 m
    // voxel instead of at the 26 baked directions, against the truth tallied the same way.
    const test::TruthScene& s = test::truth_scene("truth_refine4");
    REQUIRE(s.scene.medium.g != 0.0);
    scene::Quality q = scene::quality_preset("per_strike_mc");
    q.keep_transport_grid = true;
    q.toward_camera = true;
    REQUIRE(scene::toward_camera_problem(q).empty());
    runtime::FramePipeline toward(s.scene, s.density, *s.bases, {}, q);
    const double t = peak_time(toward, 5);
    runtime::ReconstructOptions o;
    o.wait_for_strikes = true;
    const runtime::Frame& f = toward.build(t, {}, o);
    REQUIRE(f.lit);
    CHECK(f.strikes_solved == 1);
    // The kept light holds its one field (1/26 of the baked directions' memory); the frame
    // holds every direction.
    const lightning::Strike& k = toward.storm().strike(toward.strike_at(0.0, 5));
    const std::shared_ptr<const runtime::StrikeLight> kept = toward.strike_solver()->get(k.seed, k.time);
    REQUIRE(kept);
    for (const transport::SourceField* field :
         {&kept->single[0], &kept->multiple[1], &kept->fine_single[1], &kept->fine_multiple[0]})
        CHECK(field->directions.size() == 1);
    CHECK(f.fine.values.size() == 26);
    const core::GridGeometry& fine = s.media.transport.density.geom;
    REQUIRE(f.fine.geometry == fine);

    // The cloud's scattered light on the ground: each group's tally at unit glow, scaled in the
    // frame by the group's glow.
    const std::optional<transport::GroundTally> cells = runtime::strike_ground(s.scene, s.media.lighting.density.geom);
    REQUIRE(cells);
    const lightning::FlashState st = lightning::flash_state(k.profile, toward.storm().params().timing, t - k.time);
    REQUIRE(f.ground.data.size() == cells->cells());
    for (std::size_t g = 0; g < 2; ++g) REQUIRE(kept->ground[g].data.size() == cells->cells());
    double worst = 0.0;
    for (std::size_t i = 0; i < f.ground.data.size(); ++i) {
        const double want = st.main_glow * kept->ground[0].data[i] + st.branch_glow * kept->ground[1].data[i];
        worst = std::max(worst, std::abs(double(f.ground.data[i]) - want) / std::max(1e-30, std::abs(want)));
    }
    CHECK(worst < 1e-6);  // float products and sums

    scene::Scene fs = s.scene;
    fs.lighting_downsample /= s.media.refine;
    runtime::TruthOptions to;
    to.paths = 1'000'000;
    to.toward = scene::camera_position(s.scene.camera, s.density.geom);
    to.ground = cells;
    const runtime::Truth truth = runtime::truth(fs, s.density, f.segments, {}, to);
    REQUIRE(truth.single.geom == fine);
    REQUIRE(truth.single.directions.size() == 26);  // the one field in every direction
    const transport::SourceField ref = truth.sum();
    const std::vector<float>& fine_rho = s.media.transport.density.data;
    const test::FieldError e = compare_fields(flat(f.fine), ref.data, fine_rho);
    MESSAGE("toward the camera on the 500 m grid: " << e.l2 << " (sum ratio " << e.ratio << "); truth noise "
                                                    << truth.noise.total);
    // Measured: 4.67%, sum ratio 1.0016 (the kept baked-direction strike: 4.63%, 1.0012, in the
    // test below); the same bounds as that test: its figure + 4 x the truth's noise (1.2%), the
    // ratio within 4 standard errors + per_strike_mc's 0.5%, so the strike's light 5% off fails.
    const double se =
        std::hypot(truth.sums.single.se, truth.sums.multiple.se) / (truth.sums.single.mean + truth.sums.multiple.mean);
    CHECK(e.l2 <= 0.0467 + 4.0 * truth.noise.total);
    CHECK(std::fabs(e.ratio - 1.0016) <= 4.0 * se + 0.005);

    // The ground's scattered light against the truth's, on the same cells. The strike traced
    // 50k paths, the truth 1M: the strike's standard error is the truth's x sqrt(1M / 50k).
    const double frame_power = f.ground.power(), truth_power = truth.ground.power();
    const double rel_se =
        truth.ground_power.se / truth.ground_power.mean * std::sqrt(1.0 + double(to.paths) / double(q.multiple_paths));
    double d2 = 0.0, n2 = 0.0;
    for (std::size_t i = 0; i < f.ground.data.size(); ++i) {
        const double a = f.ground.data[i], b = truth.ground.data[i];
        d2 += (a - b) * (a - b);
        n2 += b * b;
    }
    MESSAGE("ground: frame " << frame_power << " W against the truth's " << truth_power << " W (ratio "
                             << frame_power / truth_power << ", SE " << rel_se << "); relative L2 over the cells "
                             << std::sqrt(d2 / n2));
    // Measured: ratio 0.978 (SE 1.3%), 3.0% over the cells (mostly the strike's 50k paths);
    // the cells' bound is twice that.
    CHECK(truth_power > 0.0);
    CHECK(std::fabs(frame_power / truth_power - 1.0) <= 4.0 * rel_se);
    CHECK(std::sqrt(d2 / n2) <= 0.06);
}

TEST_CASE("truth: solved strikes kept on the transport grid (quality.grid) against a truth tallied there") {
    // The tiny scene's lighting grid is 2 km, its transport grid (refine 4) the density's 500 m:
    // a strike's own light kept there must be closer to the truth tallied on 500 m voxels than
    // the lighting grid's S is where the renderer samples it (trilinear at the 500 m centres),
    // while the lighting grid's frame stays what it is without the knob.
    const test::TruthScene& s = test::truth_scene("truth_refine4");
    scene::Quality q = scene::quality_preset("per_strike_mc");
    runtime::FramePipeline coarse(s.scene, s.density, *s.bases, {}, q);
    q.keep_transport_grid = true;
    runtime::FramePipeline kept(s.scene, s.density, *s.bases, {}, q);
    const double t = peak_time(coarse, 5);
    REQUIRE(peak_time(kept, 5) == t);
    runtime::ReconstructOptions o;
    o.wait_for_strikes = true;
    const runtime::Frame& fc = coarse.build(t, {}, o);
    const runtime::Frame& fk = kept.build(t, {}, o);
    REQUIRE(fc.lit);
    REQUIRE(fk.lit);
    CHECK(fc.fine.values.empty());
    CHECK(fk.strikes_solved == 1);
    const core::GridGeometry& fine = s.media.transport.density.geom;
    REQUIRE(fk.fine.geometry == fine);
    REQUIRE(fk.fine.directions == fk.radiance.directions);

    // The lighting grid's frame: the same paths; the multiple part's tallies summed per 500 m
    // voxel, then averaged, instead of per 2 km voxel: equal up to float rounding (1e-7 per
    // value; 1e-5 leaves room and is 5000x below a 5% error).
    const std::vector<float>& rho = s.media.lighting.density.data;
    const test::FieldError same = compare_fields(flat(fk.radiance), flat(fc.radiance), rho);
    CHECK(same.l2 <= 1e-5);

    // The truth on the transport grid: the same scene with its lighting grid at the transport
    // grid's voxels.
    scene::Scene fs = s.scene;
    fs.lighting_downsample /= s.media.refine;
    runtime::TruthOptions to;
    to.paths = 1'000'000;
    const runtime::Truth truth = runtime::truth(fs, s.density, fk.segments, {}, to);
    REQUIRE(truth.single.geom == fine);
    const transport::SourceField ref = truth.sum();
    const std::vector<float>& fine_rho = s.media.transport.density.data;
    const test::FieldError e_kept = compare_fields(flat(fk.fine), ref.data, fine_rho);
    std::vector<float> sampled;
    for (const std::vector<float>& v : fc.radiance.values) {
        std::vector<float> up(fine.cell_count());
        core::resample_trilinear(fc.radiance.geometry, v, fine, up);
        sampled.insert(sampled.end(), up.begin(), up.end());
    }
    const test::FieldError e_coarse = compare_fields(sampled, ref.data, fine_rho);
    MESSAGE("on the 500 m grid: kept " << e_kept.l2 << " (sum ratio " << e_kept.ratio << "), lighting grid sampled "
                                       << e_coarse.l2 << " (" << e_coarse.ratio << "); truth noise "
                                       << truth.noise.total);
    // Measured (both deterministic per seed): kept 4.63%, sum ratio 1.0012; the lighting grid
    // sampled 75.7%, 1.054; the truth's L2 noise 1.04%. What the kept frame misses is
    // per_strike_mc's own noise per 500 m voxel (50k paths over 64x the voxels) and the
    // truth's; the lighting grid's error is its 2 km averaging of a field that falls off
    // steeply from the channel. Bounds as in check_presets_against_truth: the L2 within its
    // figure + 4 x the truth's L2 noise; the ratio within 4 standard errors of the truth's
    // total + per_strike_mc's own 0.5% (PresetCheck::mc_ratio), so the kept light 5% off fails.
    const double se =
        std::hypot(truth.sums.single.se, truth.sums.multiple.se) / (truth.sums.single.mean + truth.sums.multiple.mean);
    CHECK(e_kept.l2 <= 0.0463 + 4.0 * truth.noise.total);
    CHECK(std::fabs(e_kept.ratio - 1.0012) <= 4.0 * se + 0.005);
    CHECK(e_coarse.l2 >= 0.70);
}

TEST_CASE("truth: with rain, a solved strike's light at the rain (Frame::rain) against the truth's there") {
    // The tiny scene with a rain shaft under its thickest columns: per_strike_mc traces the
    // strike's paths with the drops at their own extinction, albedo and phase in its medium
    // (solve::Media::traced), and the frame carries the light of orders >= 2 at the rain's
    // points per unit albedo. The truth traces the same medium (runtime::truth with rain): its
    // multiple S at the cells of rain alone (no cloud in the lighting voxel) is what the
    // frame's must match, x the albedo.
    const test::TruthScene& s = rain_scene();
    scene::Quality q = scene::quality_preset("per_strike_mc");
    q.multiple_paths = 400'000;  // the preset's 50k: ~9% noise over the few rain cells
    runtime::FramePipeline p(s.scene, s.density, *s.bases, {}, q);
    double t = 0.0;
    const runtime::Frame& f = rain_frame(p, s, t);

    // The frame's field is the solved strike's multiple S x glow / albedo, group by group.
    const lightning::Strike& k = p.storm().strike(p.strike_at(0.0, 5));
    const std::shared_ptr<const runtime::StrikeLight> light = p.strike_solver()->get(k.seed, k.time);
    REQUIRE(light);
    const lightning::FlashState st = lightning::flash_state(k.profile, p.storm().params().timing, t - k.time);
    const double albedo = s.scene.medium.albedo;
    double worst = 0.0;
    for (std::size_t d = 0; d < f.rain.values.size(); ++d) {
        const std::size_t m = std::size_t(f.rain.directions[d]);
        for (std::size_t i = 0; i < f.rain.values[d].size(); ++i) {
            const double want = (st.main_glow * light->multiple[0].direction(m)[i] +
                                 st.branch_glow * light->multiple[1].direction(m)[i]) /
                                albedo;
            worst = std::max(worst, std::abs(double(f.rain.values[d][i]) - want) / std::max(1e-30, std::abs(want)));
        }
    }
    CHECK(worst < 1e-5);  // float products and sums, and the albedo's division

    // Against the truth, over the lighting cells the rain reaches (with cloud or without).
    const RainCells rc = rain_cells(s);
    MESSAGE(rc.cells << " lighting cells with rain, " << rc.alone << " of rain alone");
    REQUIRE(rc.alone >= 4);
    runtime::TruthOptions to;
    to.paths = 1'000'000;
    const runtime::Truth truth = runtime::truth(s.scene, s.density, f.segments, {}, to);
    std::vector<float> frame = flat(f.rain);
    for (float& v : frame) v *= float(albedo);
    const test::FieldError e = compare_fields(frame, truth.multiple.data, rc.wet),
                           a = compare_fields(frame, truth.multiple.data, rc.only_rain);
    MESSAGE("the rain's light: " << e.l2 << " relative L2 (sum ratio " << e.ratio << "); rain alone " << a.l2 << " ("
                                 << a.ratio << "); truth noise " << truth.noise.multiple);
    // Measured: 1.0% relative L2, sum ratio 1.001 over the 23 cells; 1.7% and 1.007 over the 5
    // of rain alone (the strike's 400k paths and the truth's 1M on few cells; with the drops as
    // cloud of equal transport coefficient in both, 1.6% and 4.1%). Tallied with the cloud's
    // phase function at the rain instead: 21% and 53%. Bounds: about twice the largest measured
    // L2s; the ratio within 2%, so the rain's light 5% off fails.
    CHECK(e.l2 <= 0.035);
    CHECK(a.l2 <= 0.08);
    CHECK(std::fabs(e.ratio - 1.0) <= 0.02);

    // The paper preset solves no strike: no light at the rain but the channel's own.
    runtime::FramePipeline paper(s.scene, s.density, *s.bases, {}, scene::quality_preset("paper"));
    CHECK(paper.build(t, {}).rain.values.empty());
}

TEST_CASE("truth: with rain, a strike lit the instant way lights the rain as the truth does") {
    // The same scene and strike under the instant preset, nobody scheduling it: its tracers
    // trace the rain (InstantStrikes::traces_rain). Over the cloud the frame shows the estimate
    // with weight w against the bases; at the rain, where the bases carry no light, the estimate
    // weighed against none (StrikeEstimate::rain_weight, 1 at noise under 10%). Run to the path
    // caps, the frame's light at the rain is the truth's.
    const test::TruthScene& s = rain_scene();
    scene::Quality q = scene::quality_preset("instant");
    q.lookahead = 0.0;
    q.target_noise = 1e-4;  // to the caps: 400k paths of orders >= 2, as the per_strike_mc case
    q.single_paths = 100'000;
    q.multiple_paths = 400'000;
    runtime::FramePipeline p(s.scene, s.density, *s.bases, {}, q);
    REQUIRE(p.instant_strikes() != nullptr);
    CHECK(p.instant_strikes()->traces_rain());
    double t = 0.0;
    const runtime::Frame& f = rain_frame(p, s, t);
    const lightning::Strike& k = p.storm().strike(p.strike_at(0.0, 5));
    const auto est = p.instant_strikes()->get(k.seed, k.time);
    REQUIRE(est);
    REQUIRE(est->final);
    const double w = est->weight();
    CHECK(est->rain_weight() == 1.0);
    const RainCells rc = rain_cells(s);
    runtime::TruthOptions to;
    to.paths = 1'000'000;
    const runtime::Truth truth = runtime::truth(s.scene, s.density, f.segments, {}, to);
    std::vector<float> frame = flat(f.rain);
    for (float& v : frame) v *= float(s.scene.medium.albedo);
    const test::FieldError e = compare_fields(frame, truth.multiple.data, rc.wet),
                           a = compare_fields(frame, truth.multiple.data, rc.only_rain);
    // The cloud's S: the shown light (w x the estimate + (1 - w) x the bases), whose channel
    // light reaches the cloud through the rain as the truth's does.
    const test::FieldError c = compare_fields(flat(f.radiance), truth.sum().data, s.media.lighting.density.data);
    MESSAGE("instant, w = " << w << ": the rain's light " << e.l2 << " relative L2 (sum ratio " << e.ratio
                            << "); rain alone " << a.l2 << " (" << a.ratio << "); the cloud's S " << c.l2 << " ("
                            << c.ratio << "); truth noise " << truth.noise.single << " / " << truth.noise.multiple);
    // Measured (w = 1): the rain's light 1.3% relative L2, sum ratio 0.999; rain alone 2.4%
    // (0.990); the cloud's S 0.84% (1.001), against the truth's noise of 0.6% / 0.7%. With the
    // strike traced through the cloud alone the cloud's S was 21% off (order 1 52% high: the
    // channel's light unattenuated by the rain) and the rain had no light of orders >= 2. Bounds:
    // the per_strike_mc case's for the rain (same paths); the cloud's S at 2%, ~3x the measured
    // (both runs' noise), so a cloud lit 5% off fails.
    CHECK(e.l2 <= 0.035);
    CHECK(a.l2 <= 0.08);
    CHECK(std::fabs(e.ratio - 1.0) <= 0.02);
    CHECK(c.l2 <= 0.02);
    CHECK(std::fabs(c.ratio - 1.0) <= 0.02);

    // An early estimate, which the bases still share the cloud with (a few thousand paths):
    // at the rain its light is not cut to its share w of the cloud's.
    scene::Quality early = q;
    early.single_paths = 400;
    early.multiple_paths = 400;
    runtime::FramePipeline pe(s.scene, s.density, *s.bases, {}, early);
    double te = 0.0;
    const runtime::Frame& fe = rain_frame(pe, s, te);
    const auto ee = pe.instant_strikes()->get(k.seed, k.time);
    REQUIRE(ee);
    std::vector<float> rain_e = flat(fe.rain);
    for (float& v : rain_e) v *= float(s.scene.medium.albedo);
    const test::FieldError r = compare_fields(rain_e, truth.multiple.data, rc.wet);
    const double we = ee->weight(), rw = ee->rain_weight();
    std::vector<float> cut = rain_e;  // the estimate at its share of the cloud's light
    for (float& v : cut) v *= float(we / rw);
    const test::FieldError rc_cut = compare_fields(cut, truth.multiple.data, rc.wet);
    MESSAGE("early estimate: noise " << ee->light.noise.total << ", w = " << we << ", rain weight " << rw
                                     << ": the rain's light " << r.l2 << " relative L2 (sum ratio " << r.ratio
                                     << "); cut to w: " << rc_cut.l2 << " (" << rc_cut.ratio << ")");
    // Measured (400 + 400 paths, seed 5's strike): noise 21%, w 0.47, rain weight 0.957; the
    // rain's light 27% relative L2 (its own noise), sum ratio 0.954, i.e. the estimate's sum
    // 0.3% from the truth's. Cut to w: 56%, ratio 0.47. Bounds: the
    // weight is the one asked for (w < 0.8, so the case is one the bases share); the sum ratio
    // over the rain weight within 10% of 1, several times the estimate's measured sum errors
    // and a fifth of the cut's 56%; and nearer the truth than the cut.
    REQUIRE(we < 0.8);
    CHECK(std::fabs(r.ratio / rw - 1.0) <= 0.1);
    CHECK(r.l2 < rc_cut.l2);
}
