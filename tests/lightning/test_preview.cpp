// The side-view preview (draw_side_view): bolts drawn over the cloud's projection. Besides
// writing the pictures for a human (tests/.../output/lightning_*/; docs/images/lightning-bolts.png
// is one of them), each case checks what the preview must show, from its documented model:
//   background  sky (0.015, 0.018, 0.035) plus the cloud's look a * (0.16, 0.17, 0.21) with
//               a = 1 - exp(-column / 3000 m) <= 1, so no background pixel exceeds
//               255 * sqrt(0.175, 0.188, 0.245) = (107, 111, 126);
//   bolt        additive glow, Gaussian across the stretch (sigma = 0.35 + 0.85 sqrt(rel) px,
//               peak amp = rel^0.6 on the line, rel = intensity / reference), shown as
//               255 * sqrt(background + (1 - exp(-1.6 glow)) * (0.88, 0.9, 1.0)); a footprint
//               reaches at most ceil(3 sigma) <= 4 px from the stretch.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <utility>

using namespace fulgur;
using namespace fulgur::lightning;

namespace {

// The brightest red any background pixel can have (see above): a red above it is bolt glow.
constexpr int kBackgroundMaxRed = 107;

// An RGB image as draw_side_view returns it, with the projection it used (x right, z up).
struct Picture {
    std::vector<std::uint8_t> px;
    int width = 0, height = 0;
    Box view;
    glm::dvec2 to_px(const glm::dvec3& p) const {
        return {(p.x - view.lo.x) * width / (view.hi.x - view.lo.x),
                (view.hi.z - p.z) * height / (view.hi.z - view.lo.z)};
    }
    int red(int x, int y) const { return px[3 * (std::size_t(y) * std::size_t(width) + std::size_t(x))]; }
};

Picture draw(std::span<const LitSegment> lit, const core::Grid3<float>& cloud, const Box& view, int width,
             double reference = 0.0) {
    Picture p;
    p.view = view;
    p.width = width;
    p.px = draw_side_view(lit, &cloud, view, width, p.height, reference);
    return p;
}

// Pixels no footprint of `lit` can reach: farther than 5 px (4 px of footprint radius, 1 px
// for where the preview's own steps along a stretch fall between ours) from every stretch.
std::vector<bool> out_of_reach(const Picture& pic, std::span<const LitSegment> lit) {
    std::vector<bool> far(std::size_t(pic.width) * std::size_t(pic.height), true);
    for (const LitSegment& l : lit) {
        const glm::dvec2 a = pic.to_px(l.a), b = pic.to_px(l.b);
        const int steps = std::max(1, int(std::ceil(glm::length(b - a) / 0.3)));
        for (int s = 0; s <= steps; ++s) {
            const glm::dvec2 q = a + (b - a) * (double(s) / steps);
            const int cx = int(std::floor(q.x)), cy = int(std::floor(q.y));
            for (int y = std::max(0, cy - 5); y <= std::min(pic.height - 1, cy + 5); ++y)
                for (int x = std::max(0, cx - 5); x <= std::min(pic.width - 1, cx + 5); ++x)
                    far[std::size_t(y) * std::size_t(pic.width) + std::size_t(x)] = false;
        }
    }
    return far;
}

// The glow is additive and local: no pixel is darker than the cloud-only background, and a
// pixel out of every footprint's reach is exactly the background. Returns the summed excess
// over the background of all channels (how much light the bolt adds to the picture).
long long check_glow_is_local(const Picture& pic, const Picture& background, std::span<const LitSegment> lit) {
    REQUIRE(pic.px.size() == background.px.size());
    const std::vector<bool> far = out_of_reach(pic, lit);
    long long excess = 0;
    std::size_t darker = 0, changed_far = 0;
    for (std::size_t i = 0; i < pic.px.size(); ++i) {
        darker += pic.px[i] < background.px[i];
        changed_far += far[i / 3] && pic.px[i] != background.px[i];
        excess += int(pic.px[i]) - int(background.px[i]);
    }
    CHECK(darker == 0);
    CHECK(changed_far == 0);
    return excess;
}

// Every background pixel lies between the bare sky, 255 * sqrt(0.015, 0.018, 0.035) =
// (31, 34, 48), and the opaque cloud's (107, 111, 126); the storm's tower (x = 0, z = 5 km,
// ~4 km of dense cloud along y: a > 0.5) is brighter than the empty sky in the top corner.
void check_background(const Picture& bg) {
    REQUIRE(bg.px.size() == std::size_t(bg.width) * std::size_t(bg.height) * 3);
    const int lo[3] = {31, 34, 48}, hi[3] = {107, 111, 126};
    std::size_t outside = 0;
    for (std::size_t i = 0; i < bg.px.size(); ++i) outside += bg.px[i] < lo[i % 3] || bg.px[i] > hi[i % 3];
    CHECK(outside == 0);
    const glm::dvec2 tower = bg.to_px({0.0, 0.0, 5000.0});
    CHECK(bg.red(0, 0) == 31);
    // a > 0.5: red >= 255 * sqrt(0.015 + 0.16 * 0.5) = 78.
    CHECK(bg.red(int(tower.x), int(tower.y)) >= 78);
}

// Along the main channel (every stretch at the reference intensity, rel = 1: sigma = 1.2 px,
// amp = 1), the pixel holding the midpoint of a stretch whose projection is at least 6 px long
// is lit by that stretch alone with glow >= exp(-0.707^2 / (2 * 1.2^2)) * erf(2.29 / (1.2 *
// sqrt 2)) = 0.84 * 0.944 = 0.79 (the pixel centre is at most 0.707 px off the line and the
// stretch runs >= 3 - 0.707 px past it either way), so its red is >= 255 * sqrt(0.015 + 0.88 *
// (1 - exp(-1.6 * 0.79))) = 205; 200 leaves 5 levels for the preview's 0.3 px steps (a sum,
// not the integral) and rounding. Well above any background (107). (ox, oy): the picture's
// place in a mosaic. Returns how many stretches were checked.
int check_main_channel(const Picture& pic, std::span<const LitSegment> lit, int mosaic_width, int ox, int oy,
                       const std::vector<std::uint8_t>& mosaic) {
    int checked = 0, dim = 0;
    for (const LitSegment& l : lit) {
        if (l.depth != 0) continue;
        const glm::dvec2 a = pic.to_px(l.a), b = pic.to_px(l.b);
        if (glm::length(b - a) < 6.0) continue;
        const glm::dvec2 m = 0.5 * (a + b);
        const int x = std::clamp(int(std::floor(m.x)), 0, pic.width - 1);
        const int y = std::clamp(int(std::floor(m.y)), 0, pic.height - 1);
        ++checked;
        dim += mosaic[3 * (std::size_t(oy + y) * std::size_t(mosaic_width) + std::size_t(ox + x))] < 200;
    }
    CHECK(dim == 0);
    return checked;
}

}  // namespace

TEST_CASE("preview: a flash over time - leader, return stroke, decay, dart leader, restrike") {
    const auto cloud = fixture::synthetic_storm(200.0);
    LightningParams p;
    p.schedule.strike_rate = 0.0;
    p.timing.restrikes = 2.0;
    Storm storm(p, cloud);
    // The first on-demand seed whose flash has a restrike.
    std::size_t i = 0;
    for (std::uint64_t seed = 1;; ++seed) {
        i = storm.strike_at(10.0 * double(seed), seed);
        if (storm.strike(i).profile.stroke_onset.size() > 1) break;
        REQUIRE(seed < 100);
    }
    const Strike& s = storm.strike(i);
    const FlashProfile& f = s.profile;
    const double times[5] = {0.6 * f.leader_duration, f.stroke_onset[0] + p.timing.rise_time,
                             f.stroke_onset[0] + p.timing.rise_time + 0.02, f.stroke_onset[1] - 0.4 * f.dart_duration,
                             f.stroke_onset[1] + p.timing.rise_time};
    const Box view{cloud.geom.origin, cloud.geom.upper()};
    const int w = 320;
    const Picture background = draw({}, cloud, view, w);
    REQUIRE(background.height == 240);  // 12.8 km x 9.6 km at 320 px wide
    check_background(background);
    std::vector<Picture> panels;
    long long excess[5] = {};
    for (int k = 0; k < 5; ++k) {
        std::vector<LitSegment> lit;
        storm.lit(s.time + times[k], lit);
        REQUIRE_FALSE(lit.empty());  // every instant chosen lies inside the flash
        // One fixed reference (the return stroke's peak intensity): the panels compare.
        panels.push_back(draw(lit, cloud, view, w, p.bolt.intensity));
        CAPTURE(k);
        excess[k] = check_glow_is_local(panels.back(), background, lit);
    }
    // The flash timing's glow at the five instants (relative to the first stroke's peak):
    // the leader at 0.03 over the part of the channel its front has reached; the return
    // stroke's peak at 1; 20 ms later exp(-0.02 / 0.012) = 0.19; the dart leader at 0.03 over
    // the upper main channel plus what is left of the first stroke (exp(-t / 12 ms) after the
    // ~60 ms between strokes: < 0.01); the restrike's peak at its own stroke_peak (0.3-0.7).
    FlashState st[5];
    for (int k = 0; k < 5; ++k) st[k] = flash_state(f, p.timing, times[k]);
    REQUIRE(st[0].main_glow == 0.0);
    REQUIRE(st[1].main_glow >= 5.0 * st[2].main_glow);
    REQUIRE(st[2].main_glow >= 5.0 * st[0].leader_glow);
    REQUIRE(st[4].main_glow >= 5.0 * (st[3].main_glow + st[3].leader_glow));
    // The light a stretch adds to the picture, integrated over its footprint, is
    // amp * sigma * sqrt(2 pi) per px of length, growing with rel through both amp and sigma.
    // Each pair compared is >= 5x apart in rel (the REQUIREs above), more than the display's
    // saturation (1 - exp(-1.6 glow), then the square root) can undo: the brighter instant
    // adds more light to the picture.
    CHECK(excess[0] > 0);
    CHECK(excess[3] > 0);
    CHECK(excess[1] > excess[2]);
    CHECK(excess[2] > excess[0]);
    CHECK(excess[4] > excess[3]);
    std::vector<std::uint8_t> strip(std::size_t(5 * w * background.height * 3));
    for (int k = 0; k < 5; ++k)
        for (int y = 0; y < background.height; ++y)
            std::copy_n(&panels[std::size_t(k)].px[std::size_t(y * w * 3)], w * 3,
                        &strip[std::size_t((y * 5 * w + k * w) * 3)]);
    core::write_png(fulgur::test::scratch_dir("lightning_sequence") / "flash_sequence.png", 5 * w, background.height, 3,
                    strip);
}

TEST_CASE("preview: bolts of each kind drawn over the cloud") {
    const auto cloud = fixture::synthetic_storm(200.0);
    const Box view{cloud.geom.origin, cloud.geom.upper()};
    const auto dir = fulgur::test::scratch_dir("lightning_preview");
    const Picture background = draw({}, cloud, view, 800);
    REQUIRE(background.height == 600);  // 12.8 km x 9.6 km at 800 px wide
    check_background(background);
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;  // the first return stroke's peak
    for (Kind kind : {Kind::CloudToGround, Kind::IntraCloud, Kind::CloudToCloud}) {
        BoltParams p;
        p.kind = kind;
        const BoltGenerator gen(p, cloud);
        for (std::uint64_t seed : {1, 2, 3}) {
            CAPTURE(kind_name(kind));
            CAPTURE(seed);
            std::vector<LitSegment> lit;
            lit_segments(gen.generate(seed), peak, lit);
            REQUIRE_FALSE(lit.empty());
            const Picture pic = draw(lit, cloud, view, 800);  // reference: the brightest, the main channel
            REQUIRE(pic.height == 600);
            REQUIRE(pic.px.size() == 800u * 600u * 3u);
            CHECK(check_glow_is_local(pic, background, lit) > 0);
            // At least one stretch checked: a main channel of kilometres in 200 m steps with
            // spread directions has stretches that project >= 6 px (96 m) onto the view.
            CHECK(check_main_channel(pic, lit, 800, 0, 0, pic.px) > 0);
            core::write_png(dir / (std::string(kind_name(kind)) + "_" + std::to_string(seed) + ".png"), 800, 600, 3,
                            pic.px);
        }
    }
}

TEST_CASE("preview: the documentation mosaic (two cloud-to-ground, one intra-cloud, one cloud-to-cloud)") {
    // docs/images/lightning-bolts.png is a copy of this output. Intra- and cloud-to-cloud
    // bolts are turned about the vertical axis so their start-to-target line runs along x
    // (a side view would otherwise look at them end-on).
    const auto cloud = fixture::synthetic_storm(200.0);
    const Box view{cloud.geom.origin, cloud.geom.upper()};
    const int w = 640, h = 480;  // 12.8 km x 9.6 km at 640 px wide
    const std::pair<Kind, std::uint64_t> cases[4] = {
        {Kind::CloudToGround, 1}, {Kind::CloudToGround, 3}, {Kind::IntraCloud, 2}, {Kind::CloudToCloud, 2}};
    std::vector<std::uint8_t> mosaic(std::size_t(4 * w * h * 3));
    std::vector<std::vector<LitSegment>> lits;
    std::vector<Picture> pics;
    for (int c = 0; c < 4; ++c) {
        BoltParams p;
        p.kind = cases[c].first;
        const Bolt b = BoltGenerator(p, cloud).generate(cases[c].second);
        FlashState peak;
        peak.main_glow = peak.branch_glow = 1.0;
        std::vector<LitSegment> lit;
        lit_segments(b, peak, lit);
        if (p.kind != Kind::CloudToGround) {
            const double a = -std::atan2(b.target.y - b.start.y, b.target.x - b.start.x);
            for (LitSegment& l : lit)
                for (glm::dvec3* q : {&l.a, &l.b})
                    *q = glm::dvec3(std::cos(a) * q->x - std::sin(a) * q->y, std::sin(a) * q->x + std::cos(a) * q->y,
                                    q->z);
        }
        Picture pic = draw(lit, cloud, view, w, p.intensity);
        REQUIRE(pic.height == h);
        const int ox = (c % 2) * w, oy = (c / 2) * h;
        for (int y = 0; y < h; ++y)
            std::copy_n(&pic.px[std::size_t(y * w * 3)], w * 3, &mosaic[std::size_t(((oy + y) * 2 * w + ox) * 3)]);
        lits.push_back(std::move(lit));
        pics.push_back(std::move(pic));
    }
    const Picture background = draw({}, cloud, view, w);
    check_background(background);
    // Each quadrant shows its own bolt, in its place: its main channel is bright in the mosaic
    // (nothing of another quadrant overwrote it), and it adds light only near its channel.
    for (int c = 0; c < 4; ++c) {
        CAPTURE(c);
        const int ox = (c % 2) * w, oy = (c / 2) * h;
        CHECK(check_main_channel(pics[std::size_t(c)], lits[std::size_t(c)], 2 * w, ox, oy, mosaic) > 0);
        CHECK(check_glow_is_local(pics[std::size_t(c)], background, lits[std::size_t(c)]) > 0);
        int bright = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                bright += mosaic[3 * (std::size_t(oy + y) * 2 * w + std::size_t(ox + x))] > kBackgroundMaxRed;
        CHECK(bright > 0);
    }
    core::write_png(fulgur::test::scratch_dir("lightning_docs") / "lightning-bolts.png", 2 * w, 2 * h, 3, mosaic);
}
