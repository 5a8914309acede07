// Golden images of whole storm frames through fulgur-shot's code path (view::StormView):
// tiny scenes baked at test time (tests/apps/scenes), rendered headless at 160x90.
// Goldens: tests/render/golden/storm_*.png, regenerated only with FULGUR_UPDATE_GOLDENS=1.
#include "golden.h"
#include "platform/platform.h"
#include "view/linear_frame.h"
#include "view/view.h"

#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

using namespace fulgur;

namespace {

constexpr int W = 160, H = 90;
const std::filesystem::path kScenes = std::filesystem::path(FULGUR_SOURCE_DIR) / "tests/apps/scenes";
const std::filesystem::path kGoldens = std::filesystem::path(FULGUR_SOURCE_DIR) / "tests/render/golden";
const std::filesystem::path kOut = std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / "storm_golden";

// One headless context for all cases (OSMesa context creation is slow-ish).
platform::Context& context() {
    static std::unique_ptr<platform::Context> ctx = platform::create_headless({.width = W, .height = H});
    ctx->make_current();
    return *ctx;
}

// The scene's bases, baked fresh once per test run into the test output directory (never
// next to the scene). Not reused across runs: the file's key covers the scene, not the bake
// code, so a file left by an older build would hide a change in the solvers (an incremental
// build once passed with the multiple scattering doubled). The tiny scenes bake in < 1 s.
std::filesystem::path baked(const std::string& name, const scene::Scene& s, const core::Grid3<float>& d) {
    static std::map<std::string, std::filesystem::path> done;
    if (auto it = done.find(name); it != done.end()) return it->second;
    std::filesystem::create_directories(kOut);
    const std::filesystem::path fgb = kOut / (name + ".fgb");
    bake::bake(s, d, fgb);
    return done[name] = fgb;
}

// A view of a tiny test scene, baked fresh for this run (baked()).
std::unique_ptr<view::StormView> storm_view(const std::string& name) {
    scene::Scene s = scene::load_scene(kScenes / (name + ".json"));
    core::Grid3<float> d = scene::make_density(s);
    const auto fgb = baked(name, s, d);
    return std::make_unique<view::StormView>(std::move(s), std::move(d), fgb, context().get_proc_address());
}

// 2 ms after the first return stroke's onset of a strike with `seed` at t = 0.
double return_stroke(view::StormView& view, std::uint64_t seed) {
    const std::size_t i = view.pipeline().strike_at(0.0, seed);
    return view.pipeline().storm().strike(i).profile.stroke_onset.at(0) + 0.002;
}

struct Shot {
    std::vector<std::uint8_t> rgba;
    double cloud_mean = 0.0;  ///< mean in-scattered luminance of the march (cloud only, no bolt/glow)
    std::size_t segments = 0;
    double first_x = 0.0;      ///< first lit segment's start (bolt identity)
    double truth_noise = 0.0;  ///< lit by the truth: its relative L2 noise (the components asked for)
};

// How a shot's cloud is lit besides its components.
struct Lighting {
    /// > 0: the cloud lit by the frame's truth (runtime::truth of this many paths, the
    /// components asked for) instead of the scene's preset.
    std::uint64_t truth_paths = 0;
    /// Only the cloud's in-scattered light in the march: no glow, ground or sky behind it
    /// (terms that do not depend on the components).
    bool in_scattered_only = false;
};

// The frame 2 ms after the first return stroke's onset of a strike with `seed` at t = 0.
Shot shoot(const std::string& name, std::uint64_t seed, runtime::Components comp = {}, const Lighting& lit = {}) {
    std::unique_ptr<view::StormView> owned = storm_view(name);
    view::StormView& view = *owned;
    platform::Context& ctx = context();
    const double t = return_stroke(view, seed);
    view::ViewOptions opt;
    opt.components = comp;
    opt.settings.timing = render::Timing::Off;
    opt.settings.glare = false;  // how the frame composes its terms (the glare has its own golden)
    if (lit.in_scattered_only) opt.settings.glow = opt.settings.ground = opt.settings.sky = false;
    std::optional<view::StormView::TruthSolve> truth;
    if (lit.truth_paths > 0) {
        runtime::TruthOptions to;
        to.paths = lit.truth_paths;
        truth = view.solve_truth(t, comp, to);
    }
    const view::FrameReport r = view.render(view::scene_camera(view.scene().camera, view.density()), t, W, H, opt,
                                            truth ? &truth->field : nullptr);
    REQUIRE(r.lit);
    ctx.present();
    Shot out;
    out.rgba = ctx.read_rgba8();
    int mw = 0, mh = 0;
    const std::vector<float> m = view.renderer().read_march(mw, mh);
    double sum = 0.0;  // double: sum over ~3600 pixels
    for (std::size_t p = 0; p < m.size(); p += 4) sum += 0.2126 * m[p] + 0.7152 * m[p + 1] + 0.0722 * m[p + 2];
    out.cloud_mean = sum / double(std::max<std::size_t>(1, m.size() / 4));
    const runtime::Frame* f = view.last_frame();
    out.segments = f->segments.size();
    out.first_x = f->segments.empty() ? 0.0 : f->segments.front().a.x;
    if (truth)
        out.truth_noise =
            comp.single ? (comp.multiple ? truth->noise.total : truth->noise.single) : truth->noise.multiple;
    return out;
}

// Same metric and tolerances as the renderer's golden test (tests/render/golden.h):
// llvmpipe differs slightly between CPUs; a regression moves many pixels or moves them far.
void check_golden(const std::string& name, const Shot& s) {
    const test::GoldenResult r =
        test::compare_golden(kGoldens / ("storm_" + name + ".png"), W, H, s.rgba, test::GoldenTolerance{}, kOut);
    MESSAGE(r.message);
    CHECK(r.passed);
}

}  // namespace

TEST_CASE("storm golden: isotropic, multiple scattering, cloud-to-ground") {
    const Shot s = shoot("test_iso_ms_cg", 11);
    check_golden("iso_ms_cg", s);
    // The 8-bit golden alone passed with the multiple-scattering part scaled by 1.1 (a 5.8%
    // brighter cloud moves few pixels past 8 levels). So the march's mean in-scattered
    // luminance of the multiple scattering alone is compared with the same frame's cloud lit
    // by the truth's multiple scattering: their ratio is the preset's error in the picture
    // (paper: the splat onto 4 km virtual lights, which puts the multiple scattering where
    // the camera sees more of it), measured 1.9043. Tolerance: 4 x the truth's relative L2 noise
    // of the part (0.4% at 1M paths: a bound on the noise of a mean over the cloud) + 1% for
    // the lattice's steady-state tolerance (1e-4 per step) and llvmpipe's differences between
    // CPUs (~1e-4 of a mean); the part 5% off moves the ratio by 5% and fails.
    const runtime::Components multiple_only{.single = false, .multiple = true};
    const Shot ms = shoot("test_iso_ms_cg", 11, multiple_only, {.in_scattered_only = true});
    const Shot truth =
        shoot("test_iso_ms_cg", 11, multiple_only, {.truth_paths = 1'000'000, .in_scattered_only = true});
    const double ratio = ms.cloud_mean / truth.cloud_mean;
    std::printf("iso_ms_cg multiple scattering: march mean %.9g, lit by the truth %.9g (noise %.4f): ratio %.5f\n",
                ms.cloud_mean, truth.cloud_mean, truth.truth_noise, ratio);
    CHECK(std::fabs(ratio / 1.9043 - 1.0) <= 4.0 * truth.truth_noise + 0.01);
}
TEST_CASE("storm golden: anisotropic, multiple scattering, cloud-to-ground") {
    check_golden("aniso_ms_cg", shoot("test_aniso_ms_cg", 12));
}
TEST_CASE("storm golden: anisotropic, single scattering only, intra-cloud") {
    check_golden("aniso_ss_ic", shoot("test_aniso_ss_ic", 13));
}
TEST_CASE("storm golden: isotropic, single scattering only, intra-cloud") {
    check_golden("iso_ss_ic", shoot("test_iso_ss_ic", 14));
}

TEST_CASE("storm: same seed and time give identical images; different seeds different bolts") {
    const Shot a = shoot("test_aniso_ms_cg", 21), b = shoot("test_aniso_ms_cg", 21), c = shoot("test_aniso_ms_cg", 22);
    CHECK(a.rgba == b.rgba);
    CHECK((a.segments != c.segments || a.first_x != c.first_x));
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.rgba.size(); ++i) differing += a.rgba[i] != c.rgba[i];
    // Another bolt lights the cloud elsewhere: far more than a few pixels change.
    CHECK(differing > a.rgba.size() / 50);
}

TEST_CASE("storm: multiple scattering on vs off is visibly different") {
    const Shot on = shoot("test_aniso_ms_cg", 31, {.single = true, .multiple = true});
    const Shot off = shoot("test_aniso_ms_cg", 31, {.single = true, .multiple = false});
    REQUIRE(off.cloud_mean > 0.0);
    const double ratio = on.cloud_mean / off.cloud_mean;
    std::printf("cloud mean in-scattered luminance, multiple+single / single only: %.4f\n", ratio);
    // Multiple scattering only adds light (albedo 0.99): at least 5% more is a visible change;
    // a ratio of 1 would mean the toggle does nothing.
    CHECK(ratio > 1.05);
}

TEST_CASE("storm: a render lit by a given field; the direct-solve reference of the frame") {
    std::unique_ptr<view::StormView> owned = storm_view("test_aniso_ms_cg");
    view::StormView& view = *owned;
    platform::Context& ctx = context();
    const double t = return_stroke(view, 41);
    const render::Camera cam = view::scene_camera(view.scene().camera, view.density());
    view::ViewOptions opt;
    opt.settings.timing = render::Timing::Off;
    opt.settings.glare = false;
    auto shot = [&](const transport::SourceField* field) {
        REQUIRE(view.render(cam, t, W, H, opt, field).lit);
        ctx.present();
        return ctx.read_rgba8();
    };
    const std::vector<std::uint8_t> own = shot(nullptr);

    // The frame's own reconstruction (all directions) handed back as a field: the same image,
    // bit for bit (the override path uploads exactly what the pipeline would).
    const runtime::Frame& f = view.pipeline().build(t, {}, {});
    REQUIRE(f.lit);
    const transport::SourceField field = runtime::every_direction(f.radiance);
    CHECK(shot(&field) == own);

    // The direct solve: finite, non-negative energy, and a visibly different image on this
    // coarse test grid (virtual lights 4 km apart: the splat moves light by kilometres).
    const view::StormView::DirectSolve solved = view.solve_direct(t, {});
    const transport::SourceField& direct = solved.field;
    CHECK(solved.seconds > 0.0);
    CHECK(solved.basis_ms > 0.0);
    // The error is measured against the frame's own reconstruction: exactly 0 for the field
    // built from it above, and far from 0 for the direct solve on this coarse grid.
    CHECK(view.reconstruction_error(field) == 0.0);
    CHECK(view.reconstruction_error(direct) > 0.05);
    REQUIRE(direct.data.size() == field.data.size());
    double sum = 0.0;  // double: ~10^4 values
    for (float v : direct.data) {
        REQUIRE(std::isfinite(v));
        sum += v;
    }
    CHECK(sum > 0.0);
    const std::vector<std::uint8_t> ref = shot(&direct);
    std::size_t differing = 0;
    for (std::size_t p = 0; p < ref.size(); ++p) differing += ref[p] != own[p];
    CHECK(differing > 0);

    // A field on another grid is refused with a reason, not uploaded.
    transport::SourceField wrong(view.bases().lighting(), {glm::dvec3(0, 0, 1)});
    CHECK_THROWS_AS(view.render(cam, t, W, H, opt, &wrong), core::Error);
}

namespace {

// render_linear's frame of `view` at t: its passes sum to it (each re-composites the same frame
// with one term on), within 1e-6 of the brightest pixel and `pixel_bound` of each pixel's
// largest term; none negative, each lit unless named in `dark`, and the transmittance in [0, 1],
// reaching below 0.01 in the cloud. Returns the frame.
view::LinearFrame check_linear_passes(view::StormView& view, double t, const std::string& dark, view::ViewOptions& opt,
                                      double pixel_bound) {
    const render::Camera cam = view::scene_camera(view.scene().camera, view.density());
    opt.settings.timing = render::Timing::Off;
    opt.settings.internal_scale = 1.0;
    view::LinearFrame f = view::render_linear(view, cam, t, W, H, opt, nullptr, true);
    const std::size_t n = std::size_t(W) * std::size_t(H);
    REQUIRE(f.radiance.size() == 3 * n);
    REQUIRE(f.passes.size() == std::size(view::kLinearPasses));
    REQUIRE(f.transmittance.size() == n);
    // The sum differs from the frame by float rounding of five terms (a few ulp of the brightest
    // pixel, the core).
    // Per pixel too, against its own largest term: a term drawn in two passes (a light the
    // switches do not reach) stands out there long before it does against the core.
    double peak = 0.0, worst = 0.0, worst_pixel = 0.0;
    for (float v : f.radiance) peak = std::max(peak, double(v));
    for (std::size_t k = 0; k < f.radiance.size(); ++k) {
        double sum = 0.0, largest = double(f.radiance[k]);
        for (const view::LinearPass& p : f.passes) {
            sum += double(p.rgb[k]);
            largest = std::max(largest, double(p.rgb[k]));
        }
        worst = std::max(worst, std::abs(sum - double(f.radiance[k])));
        if (largest > 1e-30) worst_pixel = std::max(worst_pixel, std::abs(sum - double(f.radiance[k])) / largest);
    }
    MESSAGE("passes against the frame: worst " << worst << " of a peak " << peak << "; per pixel " << worst_pixel);
    CHECK(peak > 0.0);
    CHECK(worst <= 1e-6 * peak);
    CHECK(worst_pixel <= pixel_bound);
    for (const view::LinearPass& p : f.passes) {
        double sum = 0.0;
        std::size_t negative = 0;
        for (float v : p.rgb) {
            negative += v < 0.0f;
            sum += v;
        }
        CAPTURE(p.name);
        CHECK(negative == 0);
        CHECK((sum > 0.0) == (p.name != dark));
    }
    const auto [tmin, tmax] = std::minmax_element(f.transmittance.begin(), f.transmittance.end());
    CHECK(*tmin >= 0.0f);
    CHECK(*tmin < 0.01f);
    CHECK(*tmax == doctest::Approx(1.0f).epsilon(1e-6));
    return f;
}

}  // namespace

namespace {

// The anisotropic test scene with a moon, a sky and rain (25 mm/h), baked for this run.
std::unique_ptr<view::StormView> rain_view() {
    std::ifstream in(kScenes / "test_aniso_ms_cg.json");
    nlohmann::json j = nlohmann::json::parse(in);
    j.merge_patch(nlohmann::json::parse(R"({
        "lights": [{"type": "point", "position": [0, 0, 1000], "intensity": 1},
                   {"type": "sun", "name": "moon", "elevation": 30, "azimuth": -60, "irradiance": 0.01}],
        "sky": {"zenith": {"radiance": 1e-3}, "horizon": {"radiance": 3e-3}},
        "effects": {"sun": true, "sky": true},
        "rain": {"rate": 25, "threshold": 0.3}})"));
    std::filesystem::create_directories(kOut);
    const std::filesystem::path path = kOut / "test_aniso_rain.json";
    std::ofstream(path) << j.dump(1);
    scene::Scene s = scene::load_scene(path);
    REQUIRE(s.rain);
    core::Grid3<float> d = scene::make_density(s);
    const auto fgb = baked("test_aniso_rain", s, d);
    return std::make_unique<view::StormView>(std::move(s), std::move(d), fgb, context().get_proc_address());
}

}  // namespace

TEST_CASE("storm with rain, moon and sky: the linear passes sum to the frame, the rain's light in its own") {
    // The rain takes light from the flash (the channel), the moon's first scattering and the
    // static light's S: each belongs to one pass (lightning, static), none to the background's
    // or the transmittance's, which draw the volume unlit.
    std::unique_ptr<view::StormView> owned = rain_view();
    view::StormView& view = *owned;
    // The ground's flash lights cross the rain at the share of its extinction the flash's solves
    // carry: the lattice's presets (this scene's paper) the drops as cloud of equal transport
    // coefficient, the presets that trace the strikes' paths the drops at their own extinction;
    // set_quality switches it.
    const scene::Scene& s = view.scene();
    REQUIRE(s.quality.preset == scene::Quality::Preset::Paper);
    const double similarity = sky::rain_media_density(s.medium, *s.rain) * s.medium.extinction;
    CHECK(view.renderer().rain_solved_share() == doctest::Approx(similarity).epsilon(1e-12));
    CHECK(view.renderer().rain_solved_share() < 0.5);  // g 0.85 drops against the cloud's 0.6: 0.39
    for (const char* traced : {"per_strike_mc", "instant", "reference"}) {
        view.set_quality(scene::quality_preset(traced));
        CHECK_MESSAGE(view.renderer().rain_solved_share() == 1.0, traced);
    }
    for (const char* lattice : {"per_strike", "hybrid", "paper"}) {
        view.set_quality(scene::quality_preset(lattice));
        CHECK_MESSAGE(view.renderer().rain_solved_share() == doctest::Approx(similarity).epsilon(1e-12), lattice);
    }
    {
        // Under per_strike an unscheduled strike is lit the instant way, by paths through the
        // drops: a frame its estimate lights takes the full share; a strike the lattice solved
        // ahead, the lattice's again. (Far from the strike the passes are checked at below.)
        view.set_quality(scene::quality_preset("per_strike"));
        view::ViewOptions wait;
        wait.wait_for_strikes = true;
        wait.settings.timing = render::Timing::Off;
        const render::Camera cam = view::scene_camera(s.camera, view.density());
        const auto stroke = [&](double start, std::uint64_t seed, bool known_ahead) {
            const std::size_t i = view.pipeline().strike_at(start, seed, known_ahead);
            return start + view.pipeline().storm().strike(i).profile.stroke_onset.at(0) + 0.002;
        };
        const view::FrameReport unscheduled = view.render(cam, stroke(100.0, 5, false), 80, 45, wait);
        CHECK(unscheduled.lit);
        CHECK(view.renderer().rain_solved_share() == 1.0);
        const view::FrameReport scheduled = view.render(cam, stroke(200.0, 6, true), 80, 45, wait);
        CHECK(scheduled.lit);
        CHECK(view.renderer().rain_solved_share() == doctest::Approx(similarity).epsilon(1e-12));
        view.set_quality(scene::quality_preset("paper"));
    }
    view::ViewOptions opt;
    // Float rounding leaves 5e-6 of a pixel at worst; the moon's first scattering in the rain
    // drawn in the background's pass as well as the static one made it 4.8e-4.
    (void)check_linear_passes(view, return_stroke(view, 11), "", opt, 5e-5);
}

TEST_CASE("storm: the linear frame (fulgur-shot --exr) is the tone map's input and its passes sum to it") {
    std::unique_ptr<view::StormView> owned = storm_view("test_aniso_ms_cg");
    view::StormView& view = *owned;
    const double t = return_stroke(view, 11);
    const render::Camera cam = view::scene_camera(view.scene().camera, view.density());
    view::ViewOptions opt;
    // Every term is lit in this frame (a flash with glow, channel and a sky behind the cloud)
    // but the static light, which the scene has none of; the transmittance spans the clear
    // sky (1) to the thick cloud (well under the march's early exit, 1e-3, plus its rest).
    // Per pixel 2.3e-4 at worst: night sky at the cloud's thin edge (radiance ~4e-7, T ~1),
    // where the frame and the passes' sum differ by ~1e-10 absolute, more than float rounding
    // (cause not found; far below the bound on the peak).
    const view::LinearFrame f = check_linear_passes(view, t, "static", opt, 1e-3);

    // The radiance is what the tone map receives: the same frame through render() with the
    // glare off reads back the same values.
    opt.settings.glare = false;
    opt.settings.auto_exposure = false;
    view.render(cam, t, W, H, opt);
    CHECK(view.renderer().read_hdr() == f.radiance);
}

TEST_CASE("StormView::warm_up: a storm's frames after it compile nothing and show what they show without it") {
    // A strike's leader, return stroke and decay with the camera still, then orbiting, and
    // orbiting 3 s later (no flash), in the rain scene with the demo's settings (the temporal
    // history, glare), once after warm_up and once without: after it no frame builds a program,
    // and the last frame is the same image (warm_up clears its channel and S; what the renderer
    // keeps is keyed by what it was made from). Without it the first flash builds ~20 programs.
    // A 6 degree field, so that this test's 45 rows marched are spaced as the demo's 360 at
    // 1280x720: the pixels not marched upsampled (every other pixel 0.27 degrees apart), and
    // between flashes a sixteenth marched (every fourth 0.53: render::temporal_block), which
    // warm_up, run at a quarter of the size, must pick as the full size does (left to pick
    // at its own size, it leaves one program to the frames).
    std::vector<std::uint8_t> last[2];
    int built[2] = {0, 0};
    for (const bool warm : {true, false}) {
        std::unique_ptr<view::StormView> owned = rain_view();
        view::StormView& view = *owned;
        view::ViewOptions opt;
        opt.settings.temporal = true;
        opt.settings.timing = render::Timing::Off;
        opt.settings.dither = false;
        scene::CameraSpec spec = view::explicit_orbit(view.scene().camera, view.density());
        spec.vertical_fov_deg = 6.0;
        const double onset = return_stroke(view, 11) - 0.002;
        if (warm) CHECK(view.warm_up(view::scene_camera(spec, view.density()), W, H, opt) > 0.0);
        const std::vector<std::pair<double, double>> frames = {
            {0.3 * onset, 0.0},  {0.8 * onset, 0.0},  {onset + 2e-4, 0.0}, {onset + 1e-3, 0.0}, {onset + 2e-3, 0.0},
            {onset + 3e-3, 0.0}, {onset + 4e-3, 0.0}, {onset + 5e-3, 0.0}, {onset + 6e-3, 1.0}, {onset + 7e-3, 2.0},
            {onset + 8e-3, 3.0}, {onset + 3.0, 4.0},  {onset + 3.0, 5.0},  {onset + 3.0, 6.0}};
        int sixteenths = 0;
        for (std::size_t i = 0; i < frames.size(); ++i) {
            scene::CameraSpec c = spec;
            c.azimuth_deg += frames[i].second;
            opt.settings.frame_index = std::uint32_t(i);
            const view::FrameReport r = view.render(view::scene_camera(c, view.density()), frames[i].first, W, H, opt);
            CAPTURE(warm);
            CAPTURE(i);
            if (warm) CHECK(r.gpu.programs_built == 0);
            built[warm ? 0 : 1] += r.gpu.programs_built;
            sixteenths += r.gpu.temporal == render::TemporalStep::Quarter && r.gpu.marched_share < 0.1;
            if (i == 2) CHECK(r.lit);
        }
        CHECK(sixteenths == 3);  // the frames orbiting after the flash
        context().present();
        last[warm ? 0 : 1] = context().read_rgba8();
    }
    MESSAGE("programs built by the frames: after warm_up ", built[0], ", without it ", built[1]);
    CHECK(built[1] > 0);
    CHECK(last[0] == last[1]);
}
