// Flash timing (leader, return stroke, decay, restrikes) and strike scheduling.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

using namespace fulgur;
using namespace fulgur::lightning;

namespace {

/// Finds a seed whose profile has exactly `n` restrikes.
FlashProfile profile_with(int n, const TimingParams& p, double main_length) {
    for (std::uint64_t seed = 1; seed < 10000; ++seed) {
        FlashProfile f = make_flash_profile(fixture::bolt_of_length(main_length), p, seed);
        if (int(f.stroke_onset.size()) == n + 1) return f;
    }
    FAIL("no seed with the requested restrike count");
    return {};
}

}  // namespace

TEST_CASE("timing: dark before the strike and after it, leader first, then the return-stroke peak") {
    const TimingParams p;
    const Bolt b = BoltGenerator(BoltParams{}, fixture::storm_200m()).generate(3);
    const FlashProfile f = make_flash_profile(b, p, 42);
    // A few km of channel at 2e5 m/s: tens of milliseconds of stepped leader.
    CHECK(f.leader_duration == doctest::Approx(b.main_length / p.leader_speed));
    CHECK(f.leader_duration > 0.01);
    CHECK(f.leader_duration < 0.2);
    CHECK_FALSE(flash_state(f, p, -1e-6).active());
    CHECK_FALSE(flash_state(f, p, f.duration).active());
    CHECK_FALSE(flash_state(f, p, f.duration + 10.0).active());
    CHECK_FALSE(flash_state(f, p, std::nan("")).active());

    // Stepped leader: the front moves at leader_speed; dim; only part of the channel is lit.
    const double tl = 0.5 * f.leader_duration;
    const FlashState s = flash_state(f, p, tl);
    CHECK(s.active());
    CHECK(s.leader_front == doctest::Approx(tl * p.leader_speed));
    CHECK(s.leader_glow == p.leader_brightness);
    CHECK(s.main_glow == 0.0);
    std::vector<LitSegment> lit;
    lit_segments(b, s, lit);
    core::CompensatedSum lit_len;
    for (const LitSegment& l : lit) lit_len.add(glm::length(l.b - l.a));
    CHECK(lit_len.value() > 0.0);
    CHECK(lit_len.value() < b.total_length());
    for (const LitSegment& l : lit) CHECK(l.intensity <= p.leader_brightness * b.segments[0].intensity * (1 + 1e-12));

    // Sample the whole flash every 20 us: the brightest instant is the first return stroke's
    // peak (onset + rise), of relative brightness 1.
    double best = -1.0, best_t = -1.0;
    for (double t = 0.0; t < f.duration; t += 2e-5) {
        const double g = flash_state(f, p, t).main_glow;
        if (g > best) best = g, best_t = t;
    }
    CHECK(best_t >= f.stroke_onset[0]);
    CHECK(best_t <= f.stroke_onset[0] + p.rise_time + 2e-5);  // the sampling step
    CHECK(flash_state(f, p, f.stroke_onset[0] + p.rise_time).main_glow == doctest::Approx(1.0));
    CHECK(flash_state(f, p, f.stroke_onset[0] + p.rise_time).branch_glow == doctest::Approx(1.0));
}

TEST_CASE("timing: the glow decays exponentially and restrikes relight the main channel where scheduled") {
    TimingParams p;
    p.restrikes = 3.0;
    const FlashProfile f = profile_with(3, p, 6000.0);
    REQUIRE(f.stroke_onset.size() == 4);
    for (std::size_t k = 1; k < 4; ++k) {
        const double on = f.stroke_onset[k];
        CHECK(on > f.stroke_onset[k - 1] + f.dart_duration);
        // Decay before the restrike: strictly decreasing.
        const double a = f.stroke_onset[k - 1] + p.rise_time + 0.001;
        CHECK(flash_state(f, p, on - f.dart_duration - 1e-6).main_glow < flash_state(f, p, a).main_glow);
        // The dart leader re-lights the main channel only, from the start point down.
        const FlashState dart = flash_state(f, p, on - 0.5 * f.dart_duration);
        CHECK(dart.leader_main_only);
        CHECK(dart.leader_front == doctest::Approx(0.5 * f.dart_duration * p.dart_leader_speed));
        // The restrike: brighter right after its rise than just before its dart leader.
        const double before = flash_state(f, p, on - f.dart_duration - 1e-6).main_glow;
        const FlashState peak = flash_state(f, p, on + p.rise_time);
        CHECK(peak.main_glow > before + 0.5 * f.stroke_peak[k]);
        CHECK(peak.branch_glow < peak.main_glow);  // branches glow with the first stroke only
    }
    // The first stroke alone (the branches' glow) decays by e per decay_time (1e-9: exp rounding).
    const double t0 = f.stroke_onset[0] + p.rise_time + 0.002;
    REQUIRE(t0 + p.decay_time < f.stroke_end[0]);
    CHECK(flash_state(f, p, t0 + p.decay_time).branch_glow ==
          test::rel(flash_state(f, p, t0).branch_glow / std::exp(1.0), 1e-9));
    // Zero after the last stroke has decayed below the threshold.
    CHECK(f.duration == doctest::Approx(f.stroke_end.back()));
    CHECK(flash_state(f, p, f.duration - 1e-9).main_glow < 2.0 * p.dark_threshold);
    // Tens of milliseconds between strokes, a few hundred in all.
    CHECK(f.duration > 0.05);
    CHECK(f.duration < 1.0);

    // No restrikes asked: one stroke.
    p.restrikes = 0.0;
    CHECK(make_flash_profile(fixture::bolt_of_length(6000.0), p, 5).stroke_onset.size() == 1);
}

TEST_CASE("storm: on-demand strikes, dark frames detectable, point sources carry the lit energy") {
    LightningParams p;
    p.schedule.strike_rate = 0.0;  // on demand only
    Storm storm(p, fixture::storm_200m());
    std::vector<transport::PointSource> q;
    CHECK_FALSE(storm.any_active(0.0));
    CHECK_FALSE(storm.point_sources(5.0, 200.0, q));
    CHECK(q.empty());
    const std::size_t i = storm.strike_at(2.0);
    const Strike& s = storm.strike(i);
    CHECK_FALSE(storm.any_active(1.999));
    CHECK(storm.any_active(2.0));
    CHECK(storm.any_active(s.end() - 1e-9));
    CHECK_FALSE(storm.any_active(s.end()));
    // At the return-stroke peak the sources carry intensity x length of the whole bolt.
    const double tp = 2.0 + s.profile.stroke_onset[0] + p.timing.rise_time;
    REQUIRE(storm.point_sources(tp, 200.0, q));
    core::CompensatedSum sq, expect;
    for (const transport::PointSource& x : q) sq.add(x.intensity);
    const FlashState st = flash_state(s.profile, p.timing, tp - 2.0);
    for (const Segment& g : storm.bolt(i).segments)
        expect.add(g.intensity * g.length() * (g.depth == 0 ? st.main_glow : st.branch_glow));
    CHECK(sq.value() == test::rel(expect.value(), 1e-12));  // a few roundings per source
    CHECK(st.main_glow == doctest::Approx(1.0));
    // Two overlapping strikes: both active.
    storm.strike_at(2.01);
    CHECK(storm.active(2.02).size() == 2);
    CHECK_THROWS_AS(storm.strike_at(std::nan("")), core::Error);
}
