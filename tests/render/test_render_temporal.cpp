// The temporal history (Settings::temporal): a still camera through a whole flash gives every
// frame a fresh render gives (the history rescaled by the flash's intensity, marching nothing
// while the flash only dims), a light that changes in shape marches every pixel
// (TemporalReshape::Full) or a quarter, upsampled, then settles exact (Quarter), and a moving
// camera's reprojected frames stay within a pinned bound of a fresh render.
#include "gl_fixture.h"

#include "cloud/rain.h"
#include "support/synthetic_storm.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

using namespace fulgur;
using test::gl_renderer;
using test::render_at;

namespace {

constexpr int W = 320, H = 180;

// Relative L2 difference of two march outputs (rgb radiance and transmittance apart).
struct MarchDiff {
    double radiance = 0.0, transmittance = 0.0;
};
MarchDiff march_diff(const std::vector<float>& a, const std::vector<float>& b) {
    double dr = 0.0, nr = 0.0, dt = 0.0, nt = 0.0;
    for (std::size_t i = 0; i < a.size(); i += 4) {
        for (std::size_t c = 0; c < 3; ++c) {
            dr += (double(a[i + c]) - double(b[i + c])) * (double(a[i + c]) - double(b[i + c]));
            nr += double(b[i + c]) * double(b[i + c]);
        }
        dt += (double(a[i + 3]) - double(b[i + 3])) * (double(a[i + 3]) - double(b[i + 3]));
        nt += double(b[i + 3]) * double(b[i + 3]);
    }
    return {std::sqrt(dr / std::max(nr, 1e-300)), std::sqrt(dt / std::max(nt, 1e-300))};
}

// Relative L2 difference of two images, every value alike.
double rel_l2(const std::vector<float>& a, const std::vector<float>& b) {
    double d = 0.0, n = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        d += (double(a[k]) - double(b[k])) * (double(a[k]) - double(b[k]));
        n += double(b[k]) * double(b[k]);
    }
    return std::sqrt(d / std::max(n, 1e-300));
}

// The flash of one frame: S and the channel at intensity g (the return stroke's decay), the
// channel cut to its first `lit` segments (a leader's front; all: -1).
struct FlashFrame {
    double g = 1.0;
    int lit = -1;
};

// The flash's S of frame `f` (without its channel): `shape`'s at intensity g, and for a
// leader the stroke's at the lit share of the channel, in another shape: here
// S^(1 + lit / 100), which no factor turns into the stroke's. With `rain_scale`, the flash's
// light at the rain too (Renderer::upload_rain_source): that S x rain_scale.
void upload_flash_source(render::Renderer& r, const render::SourceUpload& shape, const FlashFrame& f,
                         std::optional<double> rain_scale = std::nullopt) {
    std::vector<std::vector<float>> values;
    render::SourceUpload up = shape;
    up.values.clear();
    for (const std::span<const float> v : shape.values) {
        std::vector<float>& s = values.emplace_back(v.begin(), v.end());
        for (float& x : s) x = float(f.lit >= 0 ? std::pow(double(x), 1.0 + f.lit / 100.0) * f.g : double(x) * f.g);
    }
    for (const std::vector<float>& s : values) up.values.emplace_back(s);
    r.upload_source(up);
    if (!rain_scale) {
        r.clear_rain_source();
        return;
    }
    for (std::vector<float>& v : values)
        for (float& x : v) x = float(double(x) * *rain_scale);
    r.upload_rain_source(up);  // up's spans see `values`, rescaled
}

void show_flash(render::Renderer& r, const synthetic::Storm& storm, const render::SourceUpload& shape,
                const FlashFrame& f, std::optional<double> rain_scale = std::nullopt) {
    render::LitChannel ch = storm.bolt;
    if (f.lit >= 0) ch.segments.resize(std::size_t(f.lit));
    for (render::ChannelSegment& s : ch.segments) s.intensity = float(s.intensity * f.g);
    r.set_channel(ch);
    if (f.g <= 0.0)
        r.clear_source();
    else
        upload_flash_source(r, shape, f, rain_scale);
}

// The synthetic storm at 200 m voxels, made once.
const synthetic::Storm& small_storm() {
    static const synthetic::Storm storm = synthetic::storm({64, 64, 48}, 200.0);
    return storm;
}

// Frame `index` with the temporal history (what it did, its march) and the same frame marched
// afresh.
struct Frame {
    render::FrameStats stats;
    std::vector<float> kept, fresh;
};
Frame with_and_without_history(render::Renderer& r, const render::Camera& cam, render::Settings st,
                               std::uint32_t index) {
    st.frame_index = index;
    render::Settings temporal = st;
    temporal.temporal = true;
    Frame f;
    f.stats = render_at(r, cam, temporal, W, H);
    int w = 0, h = 0;
    f.kept = r.read_march(w, h);
    render_at(r, cam, st, W, H);
    f.fresh = r.read_march(w, h);
    return f;
}

// Every direction of the storm's S (a moving camera needs others than the first view's).
render::SourceUpload every_direction(const synthetic::Storm& storm) {
    render::SourceUpload all;
    all.geometry = storm.lighting;
    all.direction_count = storm.directions;
    const std::size_t cells = storm.lighting.cell_count();
    for (int m = 0; m < storm.directions; ++m) {
        all.directions.push_back(m);
        all.values.emplace_back(storm.source.data() + std::size_t(m) * cells, cells);
    }
    return all;
}

// The storm's volume, its channel and the directions of S its camera needs.
void show_storm(render::Renderer& r, const synthetic::Storm& storm) {
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    r.set_channel(storm.bolt);
    r.upload_source(synthetic::needed_upload(r, storm));
}

// Between flashes: the storm's S as a grey static light on its lighting grid (its values
// kept by the renderer's upload), no flash S, no channel.
void show_between_flashes(render::Renderer& r, const synthetic::Storm& storm) {
    const std::size_t cells = storm.lighting.cell_count();
    std::vector<std::vector<float>> grey(std::size_t(storm.directions), std::vector<float>(3 * cells));
    for (int m = 0; m < storm.directions; ++m)
        for (std::size_t c = 0; c < cells; ++c)
            for (int ch = 0; ch < 3; ++ch)
                grey[std::size_t(m)][3 * c + std::size_t(ch)] = storm.source[std::size_t(m) * cells + c];
    render::StaticUpload up;
    up.geometry = storm.lighting;
    up.direction_count = storm.directions;
    for (const std::vector<float>& v : grey) up.rgb.emplace_back(v.data(), v.size());
    r.upload_static(up);
    r.clear_source();
    r.set_channel({});
}

// The storm's volume between flashes (show_between_flashes), and its settings without dither.
render::Settings between_flashes(render::Renderer& r, const synthetic::Storm& storm) {
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    show_between_flashes(r, storm);
    render::Settings st = storm.settings;
    st.dither = false;
    return st;
}

// The storm's volume for an orbit through a flash: `all` its S in every direction (an orbit needs
// others than the first view's), and its settings without dither.
render::Settings orbiting_storm(render::Renderer& r, const synthetic::Storm& storm, render::SourceUpload& all) {
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    all = every_direction(storm);
    render::Settings st = storm.settings;
    st.dither = false;
    return st;
}

// A whole flash of a channel of `segments` segments, frame by frame: the leader (its front
// creeping down: frames 0, 1), the return stroke's peak and decay (2-8), a dark gap (9, 10), a
// restrike and its decay (11-17).
std::vector<FlashFrame> whole_flash(int segments) {
    return {{0.1, segments / 4},
            {0.1, segments / 2},
            {1.0},
            {0.7},
            {0.45},
            {0.3},
            {0.2},
            {0.12},
            {0.08},
            {0.0},
            {0.0},
            {0.6},
            {0.4},
            {0.25},
            {0.15},
            {0.1},
            {0.07},
            {0.05}};
}

// The small storm with rain in the renderer, the directions of S its camera needs (`shape`), and
// its settings for a still camera's history: no jitter (the history's pixels were marched in
// other frames), no dither.
render::Settings still_rainy_storm(render::Renderer& r, render::SourceUpload& shape) {
    const synthetic::Storm& storm = small_storm();
    static const cloud::RainField rain = cloud::make_rain(storm.density, cloud::RainParams{});
    r.set_volume({.density = &storm.density, .extinction = storm.extinction, .rain = &rain});
    shape = synthetic::needed_upload(r, storm);
    render::Settings st = storm.settings;
    st.jitter = false;
    st.dither = false;
    return st;
}

}  // namespace

TEST_CASE("temporal history: a still camera through a whole flash gives each frame a fresh render's") {
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload shape;
    render::Settings st = still_rainy_storm(r, shape);
    st.temporal_reshape = render::TemporalReshape::Full;  // a light's new shape marched at every pixel
    const int segments = int(storm.bolt.segments.size());
    const std::vector<FlashFrame> flash = whole_flash(segments);
    using Step = render::TemporalStep;
    // Every new shape marched at every pixel (the leader's two frames, the return stroke, the
    // restrike after the dark gap), every other frame reused.
    std::vector<Step> expected(flash.size(), Step::Reused);
    for (const std::size_t k : {0, 1, 2, 11}) expected[k] = Step::Full;
    double worst = 0.0, worst_t = 0.0;
    for (std::size_t i = 0; i < flash.size(); ++i) {
        show_flash(r, storm, shape, flash[i], 0.5);  // the flash's light at the rain with its S
        const Frame f = with_and_without_history(r, storm.camera, st, std::uint32_t(i));
        const render::FrameStats& stats = f.stats;
        const MarchDiff d = march_diff(f.kept, f.fresh);
        CAPTURE(i);
        CHECK(stats.temporal == expected[i]);
        CHECK(stats.marched_share == (stats.temporal == render::TemporalStep::Reused ? 0.0 : 1.0));
        worst = std::max(worst, d.radiance);
        worst_t = std::max(worst_t, d.transmittance);
    }
    // The history holds each group's light at the intensity it was marched with; a frame
    // rescales it by the group's factor, which differs from a fresh march of the rescaled S
    // only by float rounding of the products and of the groups' sum (measured: ~1e-7; a
    // history left unscaled errs by the flash's whole change, 30% or more per frame).
    MESSAGE("still camera through a flash: worst relative L2 radiance ", worst, ", transmittance ", worst_t);
    CHECK(worst < 1e-5);
    CHECK(worst_t < 1e-6);
    r.clear_volume();
}

TEST_CASE("temporal history: the flash's light at the rain rescales with its S; by another factor, it marches") {
    // The rain's share of the flash's light (Renderer::upload_rain_source) is part of the
    // flash's light group: changed by the S's factor the history is rescaled, by another the
    // group changed in shape and is marched again. Either way the frame is a fresh render's.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload shape;
    render::Settings st = still_rainy_storm(r, shape);
    st.temporal_reshape = render::TemporalReshape::Full;
    using Step = render::TemporalStep;
    struct Case {
        double g, rain;  // the flash's intensity; its light at the rain over its S
        Step step;
    };
    double worst = 0.0;
    std::uint32_t index = 0;
    for (const Case c : {Case{1.0, 0.5, Step::Full}, Case{0.7, 0.5, Step::Reused}, Case{0.5, 0.25, Step::Full},
                         Case{0.4, 0.25, Step::Reused}}) {
        show_flash(r, storm, shape, {c.g}, c.rain);
        const Frame f = with_and_without_history(r, storm.camera, st, index++);
        CAPTURE(c.g);
        CAPTURE(c.rain);
        CHECK(f.stats.temporal == c.step);
        worst = std::max(worst, march_diff(f.kept, f.fresh).radiance);
    }
    // As the whole flash above: float rounding (a history whose rain light were rescaled by
    // the S's factor would err by half the rain's share of the light in the third frame).
    MESSAGE("worst relative L2 radiance " << worst);
    CHECK(worst < 1e-5);
    r.clear_rain_source();
    r.clear_volume();
}

TEST_CASE("temporal history: the rain's share on the ground's way changed alone is marched a quarter at a time") {
    // Renderer::set_rain_solved_share changes what the ground's flash light crosses (a preset
    // switched in the demo, an unscheduled strike's first estimate) and nothing the history's
    // trackers follow. A still camera keeps the history and marches its pixels a quarter a
    // frame at their own place, as after a move: exact again once each quarter is marched.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload shape;
    render::Settings st = still_rainy_storm(r, shape);
    REQUIRE(st.ground);
    using Step = render::TemporalStep;
    show_flash(r, storm, shape, {1.0}, 0.5);
    const Frame before = with_and_without_history(r, storm.camera, st, 0);
    r.set_rain_solved_share(0.39);
    std::vector<double> error;
    std::vector<Step> steps;
    std::vector<float> fresh_after;
    for (std::uint32_t i = 1; i <= 6; ++i) {
        const Frame f = with_and_without_history(r, storm.camera, st, i);
        if (i == 1) fresh_after = f.fresh;
        steps.push_back(f.stats.temporal);
        error.push_back(march_diff(f.kept, f.fresh).radiance);
        CAPTURE(i);
        if (i <= 4) CHECK(f.stats.marched_share == doctest::Approx(0.25).epsilon(0.05));
    }
    std::string line;
    for (std::size_t i = 0; i < error.size(); ++i)
        line.append(" ")
            .append(std::to_string(error[i]))
            .append(" (")
            .append(std::to_string(int(steps[i])))
            .append(")");
    MESSAGE("after the share changed, still camera: relative L2 radiance (step) per frame:" << line);
    const std::vector<Step> expected = {Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Quarter, Step::Reused,  Step::Reused};
    CHECK(steps == expected);
    // What the share changes in the frame (measured 3.8e-3): a history left as it was errs by
    // that much. The frames marching it a quarter at a time keep fewer of those pixels each
    // (measured 3.3e-3, 2.7e-3, 1.9e-3): below it, and falling. The setter leaving the history
    // as it was reuses it at 3.8e-3 for as long as the camera stays.
    const double stale = march_diff(before.fresh, fresh_after).radiance;
    MESSAGE("the share's change to the frame: " << stale);
    CHECK(stale > 1e-3);
    for (const std::size_t i : {0, 1, 2}) CHECK(error[i] < stale);
    for (const std::size_t i : {1, 2}) CHECK(error[i] < error[i - 1]);
    // Every quarter marched at the new share: float rounding, as the whole flash above.
    for (const std::size_t i : {3, 4, 5}) CHECK(error[i] < 1e-5);
    // The same share again changes nothing: the history is reused.
    r.set_rain_solved_share(0.39);
    CHECK(with_and_without_history(r, storm.camera, st, 7).stats.temporal == Step::Reused);
    r.set_rain_solved_share(1.0);
    CHECK(with_and_without_history(r, storm.camera, st, 8).stats.temporal == Step::Quarter);
    r.clear_rain_source();
    r.clear_volume();
}

TEST_CASE("temporal history: a light that changes in shape marches a quarter, then a still camera settles exact") {
    // TemporalReshape::Quarter (the default): a leader's front or a new stroke marches one pixel
    // of each 2x2 block, the flash's and the channel's groups upsampled from them and the cloud's
    // kept in place; once the shapes hold, the four quarters are marched in turn, after which
    // the history is exact again.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload shape;
    render::Settings st = still_rainy_storm(r, shape);
    REQUIRE(st.temporal_reshape == render::TemporalReshape::Quarter);
    const int segments = int(storm.bolt.segments.size());
    using Step = render::TemporalStep;
    const std::vector<FlashFrame> flash = whole_flash(segments);
    // The frames a new shape marks (1, 2 the leader growing, 11 the restrike after the dark gap),
    // then the quarters a fresh render at this view would march otherwise, one a frame: after
    // the return stroke (2) all four, its ground lights having moved since the leader's frame
    // (the ground integrated its rain per pixel, not from the map: 3-6); after the restrike, on
    // the stroke's channel again, the three others (12-14).
    const std::vector<Step> expected = {Step::Full,    Step::Quarter, Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Quarter, Step::Quarter, Step::Reused,  Step::Reused,  Step::Reused,
                                        Step::Reused,  Step::Quarter, Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Reused,  Step::Reused,  Step::Reused};
    std::vector<double> error;
    for (std::size_t i = 0; i < flash.size(); ++i) {
        show_flash(r, storm, shape, flash[i]);
        const Frame f = with_and_without_history(r, storm.camera, st, std::uint32_t(i));
        error.push_back(march_diff(f.kept, f.fresh).radiance);
        CAPTURE(i);
        CHECK(f.stats.temporal == expected[i]);
        if (expected[i] == Step::Quarter) CHECK(f.stats.marched_share == doctest::Approx(0.25).epsilon(0.05));
    }
    std::string line;
    for (const double e : error) line.append(" ").append(std::to_string(e));
    MESSAGE("still camera, light changing shape: relative L2 radiance per frame:" << line);
    // The new shapes' frames: the light groups upsampled from 80x45 marched pixels (this test's
    // 160x90 march), measured 46-58% (frames 1, 2, 11: 58%, 48%, 46%), bound 60% (at 1280x720,
    // 640x360 marched a quarter at a time, the median frame of a leader is 1.2% off, 2.0% with
    // detail and rain: docs/render.md). The light groups kept from the history instead of
    // upsampled (temporal.frag's still-cloud branch reading the history, rescaled) err by 65%,
    // 89% and 74%, all above the bound. Most of this frame's light is the rain's around the
    // channel, which 80x45 pixels resolve worst: before the channel's lights were attenuated by
    // the rain on their way, the frame held 9 times the light, spread wider, and erred by 17-22%
    // (4-8 times the absolute error of now).
    for (const std::size_t i : {1, 2, 11}) CHECK(error[i] < 0.6);
    // Settling, the new shape marched at two and three of the four pixels of each block (frames
    // 3, 4, 12, 13): 45%, 44%, 45%, 9%, bound 50%; kept instead 60%, 45%, 62%, 41% (frames 4 and
    // 13 pass either way). Frame 5 has one quarter left whose ground was integrated per pixel
    // (1.4e-4).
    for (const std::size_t i : {3, 4, 5, 12, 13}) CHECK(error[i] < 0.5);
    // Settled (every quarter marched at this view as a fresh render marches it): float rounding
    // of the rescaled groups, as with every pixel marched (the test above, ~1e-7).
    for (const std::size_t i : {6, 7, 8, 9, 10, 14, 15, 16, 17}) CHECK(error[i] < 1e-5);
    r.clear_volume();
}

TEST_CASE("temporal history: a flash's new shape lit by its S alone is upsampled through the cloud's opacity") {
    // No channel drawn, no rain, no static light: the frame is the flash's S and the cloud. A
    // still camera's new shape of S marches one pixel of each 2x2 block; the others take the
    // marched pixels' S / (1 - T) times their own 1 - T (temporal.frag, upsampled_flash), the
    // cloud's transmittance kept in place; then the three other quarters are marched in turn.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    r.set_channel({});
    const render::SourceUpload shape = synthetic::needed_upload(r, storm);
    render::Settings st = storm.settings;
    st.jitter = false;
    st.dither = false;
    REQUIRE(st.temporal_reshape == render::TemporalReshape::Quarter);
    using Step = render::TemporalStep;
    // S^(1 + lit / 100): new shapes at frames 1 and 6, settling in 2-4, settled at 5; each
    // started at every one of the four quarters' phases (the phases count from the frame that
    // marched every pixel, and a still frame that reuses the history advances them: `phase`
    // reused frames before the first new shape).
    const std::vector<int> lit = {10, 40, 40, 40, 40, 40, 80};
    const std::vector<Step> expected = {Step::Full,    Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Quarter, Step::Reused,  Step::Quarter};
    double worst_shape = 0.0, worst_first = 0.0, worst_settling = 0.0, worst_second = 0.0, worst_settled = 0.0;
    for (int phase = 0; phase < 4; ++phase) {
        r.reset_history();
        std::vector<double> error, total;
        std::uint32_t index = 700;
        for (std::size_t i = 0; i < lit.size(); ++i) {
            for (int reuse = 0; reuse < (i == 1 ? phase : 0); ++reuse) {
                const Frame again = with_and_without_history(r, storm.camera, st, index++);
                CHECK(again.stats.temporal == Step::Reused);
            }
            upload_flash_source(r, shape, {.g = 1.0, .lit = lit[i]});
            const Frame f = with_and_without_history(r, storm.camera, st, index++);
            error.push_back(march_diff(f.kept, f.fresh).radiance);
            double kept = 0.0, fresh = 0.0;
            for (std::size_t k = 0; k < f.kept.size(); k += 4)
                for (std::size_t c = 0; c < 3; ++c) kept += double(f.kept[k + c]), fresh += double(f.fresh[k + c]);
            total.push_back(kept / fresh);
            CAPTURE(phase);
            CAPTURE(i);
            CHECK(f.stats.temporal == expected[i]);
        }
        std::string line;
        for (std::size_t i = 0; i < error.size(); ++i)
            line.append(" ").append(std::to_string(error[i])).append(" (").append(std::to_string(total[i])).append(")");
        MESSAGE("still camera, the flash's S alone changing shape, phase "
                << phase << ": relative L2 radiance (ratio of totals) per frame:" << line);
        worst_shape = std::max({worst_shape, error[1], error[6]});
        worst_first = std::max(worst_first, std::abs(total[1] - 1.0));
        worst_settling = std::max({worst_settling, std::abs(total[2] - 1.0), std::abs(total[3] - 1.0)});
        worst_second = std::max(worst_second, std::abs(total[6] - 1.0));
        worst_settled = std::max({worst_settled, error[4], error[5]});
    }
    // Measured (llvmpipe, this test's 160x90, 80x45 marched; no jitter, so the same every run),
    // the worst of the four phases:
    // - the new shapes' frames 15.4-19.6% in relative L2 (S^1.1 -> S^1.4 and S^1.4 -> S^1.8), the
    //   marched pixels' structure at this size (at 1280x720 a leader's frame is 1.2% off:
    //   docs/render.md); S upsampled without the opacity (the marched pixels' plain mean)
    //   34% and 26% at one phase. Bound 25%.
    CHECK(worst_shape < 0.25);
    // - the frame's light in total: at the first new shape 0.978-1.003 by the phase, while it
    //   settles 0.989-1.002, at the sharper second 0.986-0.999 (at one phase the plain mean gave
    //   1.036 / 1.018 / 1.018 and 0.977). Bounds: 1.5 times the worst phase's deviation (0.0216,
    //   0.0107, 0.0137). Before the phases counted from the last full frame, this case saw
    //   whichever phase the cases before it left, and its bounds (0.6%) held at one of four.
    CHECK(worst_first < 0.033);
    CHECK(worst_settling < 0.017);
    CHECK(worst_second < 0.021);
    // Every quarter marched again (frame 4) and then reused: a fresh render's, to float rounding.
    CHECK(worst_settled < 1e-5);
    r.clear_source();
    r.clear_volume();
}

TEST_CASE("temporal history: a still camera's glare from the groups' glares is a fresh render's") {
    // While a still camera reuses the history, the glare is summed from each light group's glare
    // (made once from the history) with the groups' factors (pass_glare.cpp, glare_sum.frag),
    // the core in the channel's group, and the core itself is the one drawn for it times the
    // channel's factor (pass_bolt.cpp). Each frame of a flash's decay and restrike, tone map
    // aside (read_hdr: the radiance with the glare and the core), must be a fresh render's to
    // float rounding: the groups summed in another order than the light. The frames run in a
    // row with the history, then again afresh. A factor left out (the glare kept as it was
    // made) errs by the flash's change, 30% or more a frame.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    const render::SourceUpload shape = synthetic::needed_upload(r, storm);
    render::Settings st = storm.settings;
    st.jitter = false;
    st.dither = false;
    st.glare = true;
    st.auto_exposure = false;
    // Every frame exact, the restrike's new shape marched at every pixel: the glare's sums are tested.
    st.temporal_reshape = render::TemporalReshape::Full;
    const std::vector<FlashFrame> flash = {{1.0}, {0.7}, {0.45}, {0.3}, {0.2}, {0.0}, {0.6}, {0.4}, {0.25}};
    std::vector<std::vector<float>> kept;
    int summed = 0;
    for (std::size_t i = 0; i < flash.size(); ++i) {
        show_flash(r, storm, shape, flash[i]);
        render::Settings temporal = st;
        temporal.temporal = true;
        temporal.frame_index = std::uint32_t(i);
        const render::FrameStats s = render_at(r, storm.camera, temporal, W, H);
        summed += s.temporal == render::TemporalStep::Reused && s.glare_keep < 1.0;
        kept.push_back(r.read_hdr());
    }
    // A frame drawn without the history from elsewhere between two still ones whose light did
    // not change (nothing summed again): the next still frame must not show that frame's glare.
    {
        render::Settings temporal = st;
        temporal.temporal = true;
        temporal.frame_index = std::uint32_t(flash.size() - 1);
        render::Camera elsewhere = storm.camera;
        elsewhere.position.x += 300.0;
        render_at(r, elsewhere, st, W, H);
        const render::FrameStats s = render_at(r, storm.camera, temporal, W, H);
        CHECK(s.temporal == render::TemporalStep::Reused);
        CHECK(rel_l2(r.read_hdr(), kept.back()) < 1e-6);  // the same frame as before, to rounding
    }
    double worst = 0.0;
    for (std::size_t i = 0; i < flash.size(); ++i) {
        show_flash(r, storm, shape, flash[i]);
        st.frame_index = std::uint32_t(i);
        render_at(r, storm.camera, st, W, H);
        const double e = rel_l2(kept[i], r.read_hdr());
        CAPTURE(i);
        CAPTURE(e);
        CHECK(e < 1e-5);
        worst = std::max(worst, e);
    }
    MESSAGE("still camera's glare from the groups: worst relative L2 ", worst, " over ", summed, " summed frames");
    // The march itself is within ~1e-7 of a fresh one (above); the glare's sums and the core's
    // factor add rounding of the same order.
    CHECK(summed >= 5);  // the decay's frames and the restrike's but its first
    r.clear_volume();
}

TEST_CASE("the glare's finest level writes the display values the display pass would") {
    // With the glare on and the march smaller than the output, the glare's finest sum also writes
    // the display values the composite upsamples (glare_up.frag's DISPLAY). A still camera that
    // reuses its history sums its glare from the groups' instead and runs the display pass
    // (display.frag) on that sum. The two frames' radiance agree to float rounding (the test
    // above), so their 8-bit frames, the dither included, must be the same but for a value at a
    // rounding edge. Tried: the glare's display values without the dither differ in 29% of the
    // lit values, with the exposure 1% off in 21%, each by a level.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    const render::SourceUpload shape = synthetic::needed_upload(r, storm);
    show_flash(r, storm, shape, {.g = 1.0});
    render::Settings st = storm.settings;
    st.jitter = false;
    st.glare = true;
    st.dither = true;
    st.auto_exposure = true;
    st.exposure = render_at(r, storm.camera, st, W, H).exposure;
    st.auto_exposure = false;
    REQUIRE(st.internal_scale < 1.0);
    render::Settings temporal = st;
    temporal.temporal = true;
    render_at(r, storm.camera, temporal, W, H);  // the history, marched (the glare's own display values)
    const render::FrameStats reused = render_at(r, storm.camera, temporal, W, H);
    REQUIRE(reused.temporal == render::TemporalStep::Reused);
    const std::vector<std::uint8_t> from_groups = test::gl_context().read_rgba8();
    render_at(r, storm.camera, st, W, H);
    const std::vector<std::uint8_t> fresh = test::gl_context().read_rgba8();
    REQUIRE(fresh.size() == from_groups.size());
    std::size_t differ = 0, lit = 0;
    int worst = 0;
    for (std::size_t i = 0; i < fresh.size(); i += 4)
        for (std::size_t c = 0; c < 3; ++c) {
            const int d = std::abs(int(fresh[i + c]) - int(from_groups[i + c]));
            differ += d != 0;
            lit += fresh[i + c] > 0;
            worst = std::max(worst, d);
        }
    MESSAGE("the glare's display values against the display pass's: ", differ, " of ", lit,
            " lit values differ, by at most ", worst);
    // Measured: none differ. Bound: a value in a thousand one level off (the radiance's rounding).
    CHECK(worst <= 1);
    CHECK(double(differ) <= 1e-3 * double(lit));
    r.clear_source();
    r.set_channel({});
    r.clear_volume();
}

TEST_CASE("temporal history: a moving camera marches a quarter and stays near a fresh render") {
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload all;
    render::Settings st = orbiting_storm(r, storm, all);
    double worst = 0.0, sum = 0.0, jitter_noise = 0.0;
    int quarter = 0;
    const int frames = 12;
    for (int i = 0; i < frames; ++i) {
        const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + i, 8.0, 55.0);
        show_flash(r, storm, all, {.g = std::exp(-i / 8.0)});  // a return stroke's decay
        const Frame f = with_and_without_history(r, cam, st, std::uint32_t(i));
        const render::FrameStats& stats = f.stats;
        const std::vector<float>&kept = f.kept, &fresh = f.fresh;
        int w = 0, h = 0;
        render::Settings other = st;
        other.frame_index = std::uint32_t(i) + 7;
        render_at(r, cam, other, W, H);
        jitter_noise = std::max(jitter_noise, march_diff(r.read_march(w, h), fresh).radiance);
        CAPTURE(i);
        CHECK(stats.temporal == (i == 0 ? render::TemporalStep::Full : render::TemporalStep::Quarter));
        if (i == 0) continue;
        CHECK(stats.marched_share == doctest::Approx(0.25).epsilon(0.05));
        ++quarter;
        const double e = march_diff(kept, fresh).radiance;
        worst = std::max(worst, e);
        sum += e;
    }
    MESSAGE("orbit 1 degree a frame: relative L2 radiance against a fresh render, worst ", worst, ", mean ",
            sum / quarter, " (two fresh jitters differ by ", jitter_noise, ")");
    // Measured here (llvmpipe, 160x90 marched): mean 5.5-5.9%, worst 7.4-7.9% (as the renderer's
    // earlier frames leave its state), of which the jitter's own noise is 1.7% (the history's
    // pixels were marched with other frames' jitter); the rest is the bilinear resampling of the
    // reprojected history, sharpest at the channel's light (the lights' depths taken from the
    // four marched pixels around each pixel gave 4.4% / 4.8-5.3%, at a cost: temporal.frag).
    // Without reprojection (the history at the same pixel) the frames err by 8.4% on average
    // and 9.8% at worst, unrescaled by the flash's decay by 27%: the bounds sit between.
    CHECK(sum / quarter < 0.07);
    CHECK(worst < 0.09);

    // The same orbit with the light groups upsampled from the marched pixels instead of
    // reprojected (TemporalLight::Upsample; Auto reprojects here): at this size the marched quarter
    // (80x45) is too sparse for the channel's light, measured 15.6% mean, 19.6% worst (at the
    // demo's 1280x720 it is the more accurate: render.md); bounded so that a broken resolve
    // (garbage or a missing group, tens of percent and more) fails.
    {
        render::Settings up = st;
        up.temporal_light = render::TemporalLight::Upsample;
        double up_sum = 0.0, up_worst = 0.0;
        int up_quarter = 0;
        for (int i = 0; i < frames; ++i) {
            const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + i, 8.0, 55.0);
            show_flash(r, storm, all, {.g = std::exp(-i / 8.0)});
            const Frame f = with_and_without_history(r, cam, up, std::uint32_t(100 + i));
            CAPTURE(i);
            CHECK(f.stats.temporal == (i == 0 ? render::TemporalStep::Full : render::TemporalStep::Quarter));
            if (i == 0) continue;
            const double e = march_diff(f.kept, f.fresh).radiance;
            up_sum += e;
            up_worst = std::max(up_worst, e);
            ++up_quarter;
        }
        MESSAGE("the same orbit, the light upsampled: mean ", up_sum / up_quarter, ", worst ", up_worst);
        CHECK(up_sum / up_quarter < 0.2);
        CHECK(up_worst < 0.25);
    }

    // TemporalLight::Auto is the mode its rule names, pixel for pixel: the second frame of an
    // orbit (its first quarter) under Auto against the same frame under each explicit mode, at
    // this test's 55 degrees (marched pixels 1.2 degrees apart: reprojected) and at 19 degrees
    // (0.42: upsampled). Each sequence starts from full marches (a changed step restarts it).
    for (const double fov : {55.0, 19.0}) {
        CAPTURE(fov);
        const auto quarter_frame = [&](render::TemporalLight mode) {
            render::Settings s = st;
            s.temporal = true;
            s.temporal_light = mode;
            s.frame_index = 7;
            // Four frames a sequence: the quarter's phase follows the history's frame count.
            for (const double step : {0.99, 0.98, st.step_voxels}) {
                s.step_voxels = step;
                CHECK(render_at(r, synthetic::orbit_camera(storm, -60.0, 8.0, fov), s, W, H).temporal ==
                      render::TemporalStep::Full);
            }
            s.frame_index = 8;
            CHECK(render_at(r, synthetic::orbit_camera(storm, -59.0, 8.0, fov), s, W, H).temporal ==
                  render::TemporalStep::Quarter);
            int w = 0, h = 0;
            return r.read_march(w, h);
        };
        show_flash(r, storm, all, {.g = 1.0});
        const std::vector<float> automatic = quarter_frame(render::TemporalLight::Auto);
        const std::vector<float> reprojected = quarter_frame(render::TemporalLight::Reproject);
        const std::vector<float> upsampled = quarter_frame(render::TemporalLight::Upsample);
        const bool upsamples = render::temporal_upsamples(render::TemporalLight::Auto, fov, H);
        CHECK(upsamples == (fov < 30.0));
        CHECK(automatic == (upsamples ? upsampled : reprojected));
        CHECK(reprojected != upsampled);  // the two modes differ here, so the check above can fail
    }

    // A cut (the view turned by 30 degrees) and a changed setting start the history again.
    st.frame_index = 99;
    render::Settings temporal = st;
    temporal.temporal = true;
    const render::Camera cut = synthetic::orbit_camera(storm, -60.0 + frames + 30.0, 8.0, 55.0);
    CHECK(render_at(r, cut, temporal, W, H).temporal == render::TemporalStep::Full);
    CHECK(render_at(r, cut, temporal, W, H).temporal == render::TemporalStep::Reused);
    temporal.step_voxels = 0.5;
    CHECK(render_at(r, cut, temporal, W, H).temporal == render::TemporalStep::Full);
    r.clear_volume();
}

TEST_CASE("temporal history: a moving camera's glow, drawn at its marched pixels only, is the glow there") {
    // The glow alone (no S, no background, no jitter): the march is the glow times the
    // transmittance to its depth. A moving camera draws the glow into a target of the marched
    // pixels; at those pixels its frame must be a fresh render's to float rounding.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    r.set_channel(storm.bolt);
    r.clear_source();
    render::Settings st = storm.settings;
    st.dither = st.jitter = false;
    st.cloud_lighting = st.sky = st.ground = st.bolt = st.glare = false;
    REQUIRE(st.glow);
    std::vector<float> kept, fresh;
    int w = 0, h = 0;
    for (int i = 0; i < 2; ++i) {
        const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + i, 8.0, 55.0);
        const Frame f = with_and_without_history(r, cam, st, std::uint32_t(i));
        CHECK(f.stats.temporal == (i == 0 ? render::TemporalStep::Full : render::TemporalStep::Quarter));
        kept = f.kept;
        fresh = f.fresh;
        w = f.stats.internal_width;
        h = f.stats.internal_height;
    }
    // The marched quarter is one of the four classes of pixels by the parity of x and y: the
    // class nearest the fresh render.
    double best = 1e300, other = 1e300;
    int glowing = 0;
    for (int c = 0; c < 4; ++c) {
        double worst = 0.0;
        int n = 0;
        for (int y = c / 2; y < h; y += 2)
            for (int x = c % 2; x < w; x += 2) {
                const std::size_t at = (std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4;
                const double g = double(fresh[at]) + double(fresh[at + 1]) + double(fresh[at + 2]);
                if (!(g > 0.0)) continue;
                ++n;
                for (int k = 0; k < 3; ++k)
                    worst = std::max(
                        worst, std::abs(double(kept[at + std::size_t(k)]) - double(fresh[at + std::size_t(k)])) / g);
            }
        if (worst < best) {
            other = std::min(other, best);
            best = worst;
            glowing = n;
        } else {
            other = std::min(other, worst);
        }
    }
    MESSAGE("the marched quarter's glow against a fresh render's: worst ", best, " relative over ", glowing,
            " glowing pixels (the next class: ", other, ")");
    CHECK(glowing > 60);  // measured 123 at 160x90 marched
    // Measured 1.1e-4: float rounding of the quads' coordinates mapped onto the marched
    // pixels, through the glow profile's steep core (its bilinear texture). A glow read at
    // another pixel errs by its change over a pixel or two: the next class 2.1.
    CHECK(best < 1e-3);
    CHECK(other > 0.1);
    r.set_channel({});
}

TEST_CASE("temporal history: a camera that stops marches the four quarters in turn, then its history is exact") {
    // While the camera moves, three pixels of each 2x2 block are reprojected; once it stops,
    // the next four frames march one phase each in place, so every pixel of the history is
    // then this camera's own march, and a flash that only dims is exact again (the still
    // camera's case above).
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload all;
    render::Settings st = orbiting_storm(r, storm, all);
    st.jitter = false;  // the history's pixels were marched in other frames: no per-frame jitter
    using Step = render::TemporalStep;
    // Frames 0-3 orbit 1 degree a frame, then the camera stays at frame 3's view.
    const std::vector<Step> expected = {Step::Full,    Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Quarter, Step::Quarter, Step::Quarter, Step::Quarter,
                                        Step::Reused,  Step::Reused,  Step::Reused};
    std::vector<double> error;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + std::min<double>(i, 3), 8.0, 55.0);
        show_flash(r, storm, all, {.g = std::exp(-double(i) / 8.0)});  // a return stroke's decay
        const Frame f = with_and_without_history(r, cam, st, std::uint32_t(i));
        error.push_back(march_diff(f.kept, f.fresh).radiance);
        CAPTURE(i);
        CHECK(f.stats.temporal == expected[i]);
    }
    MESSAGE("a camera that stops: relative L2 radiance against a fresh render per frame: moving "
            << error[1] << " " << error[2] << " " << error[3] << ", settling " << error[4] << " " << error[5] << " "
            << error[6] << " " << error[7] << ", settled " << error[8] << " " << error[9] << " " << error[10]);
    // Settled: float rounding of the rescaled groups, as the still camera's (measured ~1.2e-7,
    // from the third settling frame on: the last moving frame marched one phase at this view).
    // A history left as the moving camera reprojected it stays 4.8% off for as long as the
    // camera stays (measured with the settling taken out).
    for (std::size_t i = 8; i < error.size(); ++i) CHECK(error[i] < 1e-5);
    r.clear_volume();
}

TEST_CASE(
    "temporal history: between flashes a moving camera marches a sixteenth (temporal_moving_block 4), then settles") {
    // The static light alone, the orbit of the quarter's test with one pixel of each 4x4 block
    // marched per frame; then the camera stays: four settling frames march the 2x2 quarters in
    // place, after which the history is the still camera's own march. A flash in the frame
    // marches quarters again.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::Settings st = between_flashes(r, storm);
    st.jitter = false;  // settled frames exact: no per-frame jitter
    st.temporal_moving_block = 4;
    using Step = render::TemporalStep;
    const int moving = 12, frames = moving + 7;
    double sum = 0.0, worst = 0.0;
    std::vector<double> settled;
    for (int i = 0; i < frames; ++i) {
        const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + std::min(i, moving - 1), 8.0, 55.0);
        const Frame f = with_and_without_history(r, cam, st, std::uint32_t(400 + i));
        const double e = march_diff(f.kept, f.fresh).radiance;
        CAPTURE(i);
        if (i == 0) {
            CHECK(f.stats.temporal == Step::Full);
        } else if (i < moving) {
            CHECK(f.stats.temporal == Step::Quarter);
            CHECK(f.stats.marched_share == doctest::Approx(1.0 / 16.0).epsilon(0.15));
            sum += e;
            worst = std::max(worst, e);
        } else if (i < moving + 4) {
            CHECK(f.stats.temporal == Step::Quarter);  // settling: a 2x2 quarter in place
            CHECK(f.stats.marched_share == doctest::Approx(0.25).epsilon(0.05));
        } else {
            CHECK(f.stats.temporal == Step::Reused);
            settled.push_back(e);
        }
    }
    const double mean = sum / (moving - 1);
    MESSAGE("between flashes, orbit marching a sixteenth: mean ", mean, ", worst ", worst, "; settled ", settled[0],
            " ", settled[1], " ", settled[2]);
    // Measured (llvmpipe, 160x90 marched, 40x23 a frame): mean 11.9-13.4%, worst 17.3-19.2%
    // (as the renderer's earlier frames leave its state), against the quarter's 6.3% / 7.6% on
    // the same light (the test below); with depths from the pixel's own block alone 20.8% /
    // 32.8%, which fails both bounds. At 1280x720 it is 5.7% (docs/render.md). Settled: exact
    // (no jitter, the static light unchanged).
    CHECK(mean < 0.16);
    CHECK(worst < 0.24);
    for (const double e : settled) CHECK(e < 1e-5);

    // A flash lights the frame: the next moving frame marches a quarter.
    show_flash(r, storm, every_direction(storm), {.g = 1.0});
    render::Settings flash = st;
    flash.temporal = true;
    flash.frame_index = 500;
    const render::FrameStats s = render_at(r, synthetic::orbit_camera(storm, -60.0 + moving, 8.0, 55.0), flash, W, H);
    // The flash's S is a new shape: its groups upsampled from a quarter (2x2 blocks: the sixteenth
    // is for a frame without flash light), the static light reprojected.
    CHECK(s.temporal == Step::Quarter);
    CHECK(s.marched_share == doctest::Approx(0.25).epsilon(0.05));
    flash.frame_index = 501;
    const render::FrameStats q = render_at(r, synthetic::orbit_camera(storm, -59.0 + moving, 8.0, 55.0), flash, W, H);
    CHECK(q.temporal == Step::Quarter);
    CHECK(q.marched_share == doctest::Approx(0.25).epsilon(0.05));
    r.clear_static();
    r.clear_volume();
}

TEST_CASE("temporal history: temporal_flash_block 4 marches a sixteenth during a flash too, a new shape a quarter") {
    // The quarter's orbit through a return stroke's decay (the test above), one pixel of each
    // 4x4 block marched a frame (temporal_moving_block 4 picks the sixteenth, temporal_flash_block
    // 4 keeps it while the flash lights the frame); a flash in a new shape still marches a quarter.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::SourceUpload all;
    render::Settings st = orbiting_storm(r, storm, all);
    st.temporal_moving_block = 4;
    st.temporal_flash_block = 4;
    double sum = 0.0, worst = 0.0;
    const int frames = 12;
    for (int i = 0; i < frames; ++i) {
        const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + i, 8.0, 55.0);
        show_flash(r, storm, all, {.g = std::exp(-i / 8.0)});
        const Frame f = with_and_without_history(r, cam, st, std::uint32_t(700 + i));
        CAPTURE(i);
        CHECK(f.stats.temporal == (i == 0 ? render::TemporalStep::Full : render::TemporalStep::Quarter));
        if (i == 0) continue;
        CHECK(f.stats.marched_share == doctest::Approx(1.0 / 16.0).epsilon(0.15));
        const double e = march_diff(f.kept, f.fresh).radiance;
        sum += e;
        worst = std::max(worst, e);
    }
    const double mean = sum / (frames - 1);
    MESSAGE("orbit through a return stroke marching a sixteenth: mean ", mean, ", worst ", worst);
    // Measured (llvmpipe, 160x90 marched, 40x23 a frame, reprojected as Auto picks at this
    // size): mean 23.5%, worst 30.5%, against the quarter's 4.1-5.9% / 4.6-7.9% on the same frames
    // (the test above; at the demo's 1280x720 the sixteenth is 13% against 7.4%, docs/render.md).
    // Bounded at 1.3x the measured: the same sixteenth upsampled from its marched pixels alone,
    // without the history (TemporalLight::Upsample), measured 36.5% / 41% and fails the mean.
    CHECK(mean < 0.30);
    CHECK(worst < 0.40);

    // The flash in a new shape (a leader's: half the channel lit, its S in another shape): a
    // quarter marched, as without the setting.
    show_flash(r, storm, all, {.g = 1.0, .lit = int(storm.bolt.segments.size()) / 2});
    render::Settings moving = st;
    moving.temporal = true;
    moving.frame_index = 799;
    const render::FrameStats s = render_at(r, synthetic::orbit_camera(storm, -60.0 + frames, 8.0, 55.0), moving, W, H);
    CHECK(s.temporal == render::TemporalStep::Quarter);
    CHECK(s.marched_share == doctest::Approx(0.25).epsilon(0.05));
    r.clear_volume();
}

TEST_CASE(
    "temporal history: temporal_moving_block 0 marches a sixteenth between flashes where its pixels are close "
    "together on screen") {
    // The rule on every fourth internal pixel's angle: a 55 degree field over 360 rows (the
    // bench's 1280x720) is 0.61 degrees, a sixteenth; over 180 rows 1.22, a quarter.
    CHECK(render::temporal_block(0, 55.0, 360) == 4);
    CHECK(render::temporal_block(0, 55.0, 180) == 2);
    CHECK(render::temporal_block(0, 55.0, 0) == 2);
    CHECK(render::temporal_block(2, 10.0, 360) == 2);
    CHECK(render::temporal_block(4, 90.0, 10) == 4);
    // The renderer follows it: this test's 90 rows at 55 degrees (2.4 degrees) march a quarter,
    // at 12 degrees (0.53) a sixteenth; a flash a quarter at either.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::Settings st = between_flashes(r, storm);
    st.temporal = true;
    REQUIRE(st.temporal_moving_block == 0);
    for (const double fov : {55.0, 12.0}) {
        CAPTURE(fov);
        const double share = fov > 30.0 ? 0.25 : 1.0 / 16.0;
        for (int i = 0; i < 3; ++i) {
            st.frame_index = std::uint32_t(600 + i);
            const render::FrameStats s = render_at(r, synthetic::orbit_camera(storm, -60.0 + i, 8.0, fov), st, W, H);
            CHECK(s.temporal == (i == 0 ? render::TemporalStep::Full : render::TemporalStep::Quarter));
            if (i > 0) CHECK(s.marched_share == doctest::Approx(share).epsilon(0.15));
        }
    }
    show_flash(r, storm, every_direction(storm), {.g = 1.0});
    for (int i = 3; i < 5; ++i) {
        st.frame_index = std::uint32_t(600 + i);
        const render::FrameStats s = render_at(r, synthetic::orbit_camera(storm, -60.0 + i, 8.0, 12.0), st, W, H);
        CHECK(s.temporal == render::TemporalStep::Quarter);
        CHECK(s.marched_share == doctest::Approx(0.25).epsilon(0.05));
    }
    r.clear_static();
    r.clear_volume();
}

TEST_CASE("temporal history: tiny and changing sizes march what they must, without errors") {
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    show_storm(r, storm);
    render::Settings st = storm.settings;
    st.temporal = true;
    render::Camera cam = storm.camera;
    // 1x1 and 3x1 outputs (one internal pixel high: no 2x2 block), a moving camera; then a
    // size that changes every frame. Every frame is finite.
    for (const int w : {1, 3, 5, 2, 7}) {
        for (int i = 0; i < 3; ++i) {
            cam.position.x += 10.0;
            st.frame_index = std::uint32_t(i);
            const render::FrameStats s = render_at(r, cam, st, w, 1);
            CAPTURE(w);
            CHECK(s.temporal == render::TemporalStep::Full);
            int mw = 0, mh = 0;
            for (const float v : r.read_march(mw, mh)) CHECK(std::isfinite(v));
        }
    }
    for (int i = 0; i < 4; ++i) {
        cam.position.x += 10.0;
        const render::FrameStats s = render_at(r, cam, st, 8 + 2 * i, 6);
        CHECK(s.temporal == render::TemporalStep::Full);  // a new size: no history for it
    }
    r.clear_volume();
}

TEST_CASE("the stars drawn as points are the stars computed at every pixel, moving or still") {
    // The composite draws the stars as points over the frame without them (star_points.vert,
    // Settings::composite_overlays), from a list of the cells that may hold a star
    // (pass_composite.cpp); with the overlays off every pixel computes its own. Both must give the
    // same frame to the bit: a point too small for its star's spot, a star left out of the list,
    // or one dropped at the frame's edge or the horizon, leaves pixels without their star.
    // Views: the storm's, one looking up at 80 degrees with a lens shift (spots stretched
    // toward the corners), a narrow one, one with the horizon across the frame, and one at 130
    // degrees, wider than points can draw (it computes every pixel's either way). Each view is
    // drawn right after another (a moving camera) and again (a still one).
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    show_storm(r, storm);
    render::Settings st = storm.settings;
    st.star_radiance = 1e-3;  // bright enough to show in 8 bits through the storm's exposure
    st.sky = true;
    std::vector<render::Camera> views(5, storm.camera);
    views[1].target = storm.camera.position + glm::dvec3(1000.0, 300.0, 900.0);
    views[1].vertical_fov_deg = 80.0;
    views[1].lens_shift = {0.3, -0.2};
    views[2].vertical_fov_deg = 12.0;
    views[2].target = storm.camera.position + glm::dvec3(-400.0, 1000.0, 500.0);
    views[3].target = storm.camera.position + glm::dvec3(0.0, 1000.0, 20.0);
    views[4].target = storm.camera.position + glm::dvec3(300.0, 1000.0, 600.0);
    views[4].vertical_fov_deg = 130.0;
    render::Settings every = st;
    every.composite_overlays = false;
    for (std::size_t v = 0; v < views.size(); ++v) {
        CAPTURE(v);
        for (const int width : {W, 960}) {
            const int height = width * 9 / 16;
            CAPTURE(width);
            render::Camera moved = views[v];
            moved.position.z += 50.0;
            render_at(r, moved, every, width, height);
            render_at(r, views[v], every, width, height);
            const std::vector<std::uint8_t> every_rgba = test::gl_context().read_rgba8();
            const std::vector<float> every_pixel = r.read_hdr();
            render_at(r, moved, st, width, height);
            render_at(r, views[v], st, width, height);  // moved: the stars as points
            CHECK(test::gl_context().read_rgba8() == every_rgba);
            const std::vector<float> moving = r.read_hdr();
            render_at(r, views[v], st, width, height);  // still
            CHECK(test::gl_context().read_rgba8() == every_rgba);
            // And they are there: the pixels the stars change.
            render::Settings dark = st;
            dark.star_radiance = 0.0;
            render_at(r, views[v], dark, width, height);
            const std::vector<float> none = r.read_hdr();
            std::size_t starred = 0, differ = 0;
            for (std::size_t i = 0; i < none.size(); ++i) {
                starred += every_pixel[i] != none[i];
                differ += every_pixel[i] != moving[i];
            }
            MESSAGE("view ", v, " at ", width, ": ", starred, " star values, ", differ, " differ");
            CHECK(differ == 0);
            CHECK(starred > 0);
        }
    }
    r.clear_volume();
}

TEST_CASE("the channel's core drawn as an overlay is the core read at every pixel") {
    // With the overlays the composite reads the core only under the bolt's ribbons widened by 2
    // pixels (bolt.vert's u_margin_px, pass_composite.cpp) and writes no core elsewhere; without
    // them every pixel reads it. Both must give the same frame to the bit: a ribbon drawn
    // narrower than the bolt pass drew it, or a segment dropped, leaves pixels without their
    // core. Views: the storm's; one a few hundred metres from the channel (ribbons tens of
    // pixels wide, segments clipped at the near plane); one looking down its length; a narrow
    // one whose ribbons fall below the minimum width (widened and dimmed); each with and
    // without the glare (the core's share kept in place), moving and still.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    show_storm(r, storm);
    render::Settings st = storm.settings;
    st.sky = true;
    std::vector<render::Camera> views(4, storm.camera);
    const std::vector<render::ChannelSegment>& segs = storm.bolt.segments;
    REQUIRE(segs.size() > 2);
    const glm::dvec3 mid(segs[segs.size() / 2].a), top(segs.front().a), foot(segs.back().b);
    views[1].position = mid + glm::dvec3(300.0, -200.0, 50.0);
    views[1].target = mid;
    views[1].vertical_fov_deg = 70.0;
    views[2].position = top + 1.3 * (top - foot) + glm::dvec3(30.0, 20.0, 0.0);
    views[2].target = foot;
    views[3].vertical_fov_deg = 3.0;
    views[3].target = mid;
    render::Settings every = st;
    every.composite_overlays = false;
    for (std::size_t v = 0; v < views.size(); ++v) {
        CAPTURE(v);
        for (const bool glare : {false, true}) {
            CAPTURE(glare);
            st.glare = every.glare = glare;
            render::Camera moved = views[v];
            moved.position.z += 20.0;
            render_at(r, moved, every, W, 180);
            render_at(r, views[v], every, W, 180);
            const std::vector<std::uint8_t> every_rgba = test::gl_context().read_rgba8();
            const std::vector<float> every_pixel = r.read_hdr();
            render_at(r, moved, st, W, 180);
            render_at(r, views[v], st, W, 180);  // moved
            CHECK(test::gl_context().read_rgba8() == every_rgba);
            const std::vector<float> moving = r.read_hdr();
            render_at(r, views[v], st, W, 180);  // still
            CHECK(test::gl_context().read_rgba8() == every_rgba);
            // And the core is there: the pixels it changes.
            render::Settings no_bolt = every;
            no_bolt.bolt = false;
            render_at(r, views[v], no_bolt, W, 180);
            const std::vector<float> none = r.read_hdr();
            std::size_t cored = 0, differ = 0;
            for (std::size_t i = 0; i < none.size(); ++i) {
                cored += every_pixel[i] != none[i];
                differ += every_pixel[i] != moving[i];
            }
            MESSAGE("view ", v, std::string(glare ? " with" : " without"), " glare: ", cored,
                    " values the core changes, ", differ, " differ");
            CHECK(differ == 0);
            CHECK(cored > 0);
        }
    }
    r.clear_volume();
}

TEST_CASE("temporal history: TemporalLight::Auto upsamples where the marched pixels are close together") {
    // The demo's sizes at internal scale 0.5 and a 55 degree field: 640x360 marches 180 rows
    // (every other one 0.61 degrees apart: reprojecting measured the nearer), 1280x720 360
    // rows (0.31 degrees: upsampling the nearer), 1920x1080 540 rows.
    using render::TemporalLight;
    CHECK_FALSE(render::temporal_upsamples(TemporalLight::Auto, 55.0, 180));
    CHECK(render::temporal_upsamples(TemporalLight::Auto, 55.0, 360));
    CHECK(render::temporal_upsamples(TemporalLight::Auto, 55.0, 540));
    CHECK_FALSE(render::temporal_upsamples(TemporalLight::Auto, 55.0, 0));  // no march: nothing to upsample
    // the bound itself upsamples: every other of 2 rows over kTemporalUpsampleDeg
    CHECK(render::temporal_upsamples(TemporalLight::Auto, render::kTemporalUpsampleDeg, 2));
    for (const int rows : {1, 90, 180, 360, 4096}) {
        CHECK(render::temporal_upsamples(TemporalLight::Upsample, 55.0, rows));
        CHECK_FALSE(render::temporal_upsamples(TemporalLight::Reproject, 55.0, rows));
    }
}

TEST_CASE("temporal history: between flashes, a moving camera's static light stays near a fresh render") {
    // The static light alone (the storm's S as a grey field on its lighting grid, no flash S,
    // no channel): what a storm's frames draw between flashes, all of it the cloud's group.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    const render::Settings base = between_flashes(r, storm);
    for (const bool background : {false, true}) {
        CAPTURE(background);
        render::Settings st = base;
        st.sky = st.ground = background;
        double worst = 0.0, sum = 0.0;
        int quarter = 0;
        const int frames = 8;
        for (int i = 0; i < frames; ++i) {
            const render::Camera cam = synthetic::orbit_camera(storm, -60.0 + i, 8.0, 55.0);
            const Frame f = with_and_without_history(r, cam, st, std::uint32_t(200 + i));
            if (f.stats.temporal != render::TemporalStep::Quarter) continue;
            const double e = march_diff(f.kept, f.fresh).radiance;
            sum += e;
            worst = std::max(worst, e);
            ++quarter;
        }
        MESSAGE("between flashes, orbit: mean ", sum / quarter, ", worst ", worst);
        CHECK(quarter == frames - 1);
        // Measured (llvmpipe, 160x90 marched): mean 6.3% / 4.9%, worst 7.6% / 5.7% (without /
        // with sky and ground), most of it at the cloud's base, where this field (the flash's S
        // used as a static light) peaks over a few pixels. With the cloud's depth from the
        // pixel's own block's marched pixel alone: 11.4% / 9.1-9.8% mean, 13.2-13.3% /
        // 11.4-11.5% worst, which fails both bounds; with, besides, the pixel's own background
        // tried before the cloud's depth (a sky the history saw beside the cloud's edge took the
        // edge's pixels): 20% / 15% and 22% / 17.5%.
        CHECK(sum / quarter < 0.085);
        CHECK(worst < 0.10);
    }
    r.clear_static();
    r.clear_volume();
}

TEST_CASE(
    "temporal history: a still camera between flashes runs no march, resolve or meter, and draws the same frame") {
    // The static light alone and a still camera: every group keeps its intensity, so the
    // history's march is each frame's as it stands. A frame rendered without the history in
    // between (another camera) leaves the history's march and its histogram as they were.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    render::Settings st = between_flashes(r, storm);
    st.auto_exposure = true;
    st.temporal = true;
    st.timing = render::Timing::Finish;
    std::vector<float> first;
    double first_exposure = 0.0;
    for (int i = 0; i < 6; ++i) {
        CAPTURE(i);
        st.frame_index = std::uint32_t(300 + i);
        if (i == 3) {  // a frame without the history, elsewhere
            render::Settings other = st;
            other.temporal = false;
            const render::Camera away = render::Camera::orbit(synthetic::orbit_target(storm), 15000.0, 40.0, 20.0,
                                                              storm.camera.vertical_fov_deg);
            render_at(r, away, other, W, H);
            CHECK(r.read_hdr() != first);
        }
        const render::FrameStats s = render_at(r, storm.camera, st, W, H);
        const std::vector<float> hdr = r.read_hdr();
        if (i == 0) {
            CHECK(s.temporal == render::TemporalStep::Full);
            CHECK(s.wall.march > 0.0);
            CHECK(s.wall.meter > 0.0);
            first = hdr;
            first_exposure = s.exposure;
            continue;
        }
        CHECK(s.temporal == render::TemporalStep::Reused);
        CHECK(s.wall.march == 0.0);
        CHECK(s.wall.meter == 0.0);
        CHECK(s.exposure == first_exposure);
        CHECK(hdr == first);
    }
    r.clear_static();
    r.clear_volume();
}

TEST_CASE("the meter counting one pixel in four chooses the exposure that counting every pixel does") {
    // Settings::meter_stride 2 (the default) against 1, through a return stroke's decay seen by
    // an orbiting camera and a still one, and between flashes. The exposure is the lower of a
    // key from the lit pixels' log-average and the level at the highlights' percentile: a
    // quarter of the pixels moves both by their sampling noise.
    render::Renderer& r = gl_renderer();
    const synthetic::Storm& storm = small_storm();
    r.set_volume({.density = &storm.density, .extinction = storm.extinction});
    const render::SourceUpload all = every_direction(storm);
    render::Settings st = storm.settings;
    st.auto_exposure = true;
    st.glare = true;
    std::vector<double> stops;  // |log2(exposure at stride 2 / at stride 1)| per frame
    const auto compare = [&](const render::Camera& cam, std::uint32_t index) {
        render::Settings every = st;
        every.meter_stride = 1;
        every.frame_index = index;
        render::Settings quarter = every;
        quarter.meter_stride = 2;
        const double e1 = render_at(r, cam, every, W, H).metered_exposure;
        const double e2 = render_at(r, cam, quarter, W, H).metered_exposure;
        REQUIRE(e1 > 0.0);
        REQUIRE(e2 > 0.0);
        stops.push_back(std::abs(std::log2(e2 / e1)));
    };
    for (int i = 0; i < 12; ++i) {
        show_flash(r, storm, all, {.g = std::exp(-i / 4.0)});
        compare(synthetic::orbit_camera(storm, -60.0 + 4.0 * i, 8.0, 55.0), std::uint32_t(i));
        compare(storm.camera, std::uint32_t(i));
    }
    show_between_flashes(r, storm);
    for (int i = 0; i < 6; ++i)
        compare(synthetic::orbit_camera(storm, -60.0 + 10.0 * i, 8.0, 55.0), std::uint32_t(100 + i));
    std::vector<double> sorted = stops;
    std::sort(sorted.begin(), sorted.end());
    MESSAGE("meter stride 2 against 1: median ", sorted[sorted.size() / 2], " stops, worst ", sorted.back(), " over ",
            sorted.size(), " frames");
    // Measured (llvmpipe, 160x90 marched, 3,600 pixels counted of 14,400): median 0.006 stops,
    // worst 0.023, the sampling noise of the log-average and of the highlights' level (the
    // exposure is continuous in the counts: detail::choose_exposure). Before it was, with the
    // lit pixels starting at a whole bin and the highlights at a bin's edge, the worst was
    // 0.078 here, and at 1280x720 one frame in 72 was 0.40 stops off where the exposure
    // itself jumped between frames. The bounds: five times the median, three times the worst.
    // A meter that counts only the lower left 80% of each axis: median 0.22, worst 0.96 stops.
    CHECK(sorted[sorted.size() / 2] < 0.03);
    CHECK(sorted.back() < 0.07);
    r.clear_static();
    r.clear_volume();
}
