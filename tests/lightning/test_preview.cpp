// Visual check: bolts drawn in a side view over the cloud (tests/.../output/lightning_preview/).
// The picture is for a human (docs/images/lightning-bolts.png is one of them); the checks
// here only make sure something bolt-like was drawn.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <utility>

using namespace fulgur;
using namespace fulgur::lightning;

namespace {
void draw(const std::filesystem::path& file, const core::Grid3<float>& cloud, const std::vector<Bolt>& bolts) {
    std::vector<LitSegment> lit;
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;  // the first return stroke's peak
    for (const Bolt& b : bolts) lit_segments(b, peak, lit);
    Box view{cloud.geom.origin, cloud.geom.upper()};
    int h = 0;
    const auto px = draw_side_view(lit, &cloud, view, 800, h);
    REQUIRE(h == 600);  // 12.8 km x 9.6 km at 800 px wide
    core::write_png(file, 800, h, 3, px);
    // Something bright was drawn: the bolt core saturates toward white.
    std::size_t bright = 0;
    for (std::size_t i = 0; i < px.size(); i += 3) bright += px[i] > 200 && px[i + 2] > 200;
    CHECK(bright > 500);  // a few km of channel, >= 1 px wide: well over 500 px
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
    int h = 0;
    std::vector<std::uint8_t> strip;
    std::vector<std::vector<std::uint8_t>> panels;
    double brightest = 0.0;
    std::vector<double> lit_energy;
    for (const double t : times) {
        std::vector<LitSegment> lit;
        storm.lit(s.time + t, lit);
        core::CompensatedSum e;
        for (const LitSegment& l : lit) e.add(l.intensity * glm::length(l.b - l.a));
        lit_energy.push_back(e.value());
        brightest = std::max(brightest, e.value());
        panels.push_back(draw_side_view(lit, &cloud, view, w, h, p.bolt.intensity));
    }
    // The return-stroke peak is the brightest panel; the leader and the decay are dimmer.
    CHECK(lit_energy[1] == brightest);
    CHECK(lit_energy[0] < 0.1 * lit_energy[1]);
    CHECK(lit_energy[2] < lit_energy[1]);
    CHECK(lit_energy[3] < lit_energy[4]);
    strip.resize(std::size_t(5 * w * h * 3));
    for (int k = 0; k < 5; ++k)
        for (int y = 0; y < h; ++y)
            std::copy_n(&panels[std::size_t(k)][std::size_t(y * w * 3)], w * 3,
                        &strip[std::size_t((y * 5 * w + k * w) * 3)]);
    core::write_png(fulgur::test::scratch_dir("lightning_sequence") / "flash_sequence.png", 5 * w, h, 3, strip);
}

TEST_CASE("preview: bolts of each kind drawn over the cloud") {
    const auto cloud = fixture::synthetic_storm(200.0);
    const auto dir = fulgur::test::scratch_dir("lightning_preview");
    for (Kind kind : {Kind::CloudToGround, Kind::IntraCloud, Kind::CloudToCloud}) {
        BoltParams p;
        p.kind = kind;
        const BoltGenerator gen(p, cloud);
        for (std::uint64_t seed : {1, 2, 3}) {
            draw(dir / (std::string(kind_name(kind)) + "_" + std::to_string(seed) + ".png"), cloud,
                 {gen.generate(seed)});
        }
    }
}

TEST_CASE("preview: the documentation mosaic (two cloud-to-ground, one intra-cloud, one cloud-to-cloud)") {
    // docs/images/lightning-bolts.png is a copy of this output. Intra- and cloud-to-cloud
    // bolts are turned about the vertical axis so their start-to-target line runs along x
    // (a side view would otherwise look at them end-on).
    const auto cloud = fixture::synthetic_storm(200.0);
    const Box view{cloud.geom.origin, cloud.geom.upper()};
    const int w = 640;
    int h = 0;
    const std::pair<Kind, std::uint64_t> cases[4] = {
        {Kind::CloudToGround, 1}, {Kind::CloudToGround, 3}, {Kind::IntraCloud, 2}, {Kind::CloudToCloud, 2}};
    std::vector<std::uint8_t> mosaic;
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
        const auto px = draw_side_view(lit, &cloud, view, w, h, p.intensity);
        if (mosaic.empty()) mosaic.resize(std::size_t(4 * w * h * 3));
        const int ox = (c % 2) * w, oy = (c / 2) * h;
        for (int y = 0; y < h; ++y)
            std::copy_n(&px[std::size_t(y * w * 3)], w * 3, &mosaic[std::size_t(((oy + y) * 2 * w + ox) * 3)]);
    }
    core::write_png(fulgur::test::scratch_dir("lightning_docs") / "lightning-bolts.png", 2 * w, 2 * h, 3, mosaic);
    CHECK(h == 480);
}
