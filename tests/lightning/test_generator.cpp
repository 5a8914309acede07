// Reed-Wyvill bolt generator: determinism, turn-angle statistics, kinds, branches, hard cases.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <limits>
#include <numbers>

using namespace fulgur;
using namespace fulgur::lightning;
using fulgur::core::Error;

TEST_CASE("generator: same seed gives a bit-identical bolt, different seeds differ") {
    const BoltParams p;
    const BoltGenerator g1(p, fixture::storm_200m()), g2(p, fixture::storm_200m());
    for (std::uint64_t seed : {1ULL, 7ULL, 123456789ULL}) {
        const Bolt a = g1.generate(seed), b = g2.generate(seed), c = g1.generate(seed);
        CHECK(fixture::identical(a, b));
        CHECK(fixture::identical(a, c));
        CHECK(a.segments.size() > 10);
    }
    const Bolt a = g1.generate(1), b = g1.generate(2);
    CHECK_FALSE(fixture::identical(a, b));
    CHECK(glm::length(a.start - b.start) > 0.0);
}

TEST_CASE("generator: cloud-to-ground bolts end exactly on the ground and stay in the domain") {
    for (double ground : {0.0, 350.0}) {
        BoltParams p;
        p.ground_height = ground;
        const BoltGenerator gen(p, fixture::storm_200m());
        CHECK(gen.domain().lo.z == ground);
        for (std::uint64_t seed = 1; seed <= 40; ++seed) {
            const Bolt b = gen.generate(seed);
            REQUIRE(b.main_count > 0);
            CHECK(b.reached_target);
            CHECK_FALSE(b.forced);
            CHECK(b.segments[b.main_count - 1].b.z == ground);  // exact: the last step is cut at the plane
            CHECK(b.start.z > ground);
            for (const Segment& s : b.segments) {
                CHECK(gen.domain().contains(s.a));
                CHECK(gen.domain().contains(s.b));
            }
        }
    }
}

TEST_CASE("generator: branches hang together, decay with depth and respect max_depth") {
    BoltParams p;
    p.branch_probability = 0.3;
    p.max_depth = 3;
    const BoltGenerator gen(p, fixture::storm_200m());
    int deepest = 0;
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        const Bolt b = gen.generate(seed);
        CHECK(b.segments.size() > b.main_count);
        for (std::size_t i = 0; i < b.segments.size(); ++i) {
            const Segment& s = b.segments[i];
            deepest = std::max(deepest, s.depth);
            CHECK(s.depth <= p.max_depth);
            CHECK((i < b.main_count) == (s.depth == 0));
            // Intensity per depth level: intensity * decay^depth (1e-12: a few roundings).
            CHECK(std::fabs(s.intensity - p.intensity * std::pow(p.branch_intensity_decay, s.depth)) <=
                  1e-12 * p.intensity);
            // Branches stop growing when the main leader attaches.
            CHECK(s.path_start + s.length() <= b.main_length * (1.0 + 1e-12));
            if (s.parent < 0) {
                CHECK(i == 0);
                continue;
            }
            const Segment& q = b.segments[std::size_t(s.parent)];
            CHECK(std::size_t(s.parent) < i);
            CHECK(s.a == q.b);  // connected: a branch starts where its parent segment ends
            CHECK(s.path_start == test::rel(q.path_start + q.length(), 1e-12));
            CHECK((s.depth == q.depth || s.depth == q.depth + 1));
        }
    }
    CHECK(deepest == 3);

    // No branches without depth or probability; the main channel does not depend on them.
    BoltParams none = p;
    none.max_depth = 0;
    BoltParams never = p;
    never.branch_probability = 0.0;
    const BoltGenerator g0(none, fixture::storm_200m()), gp(never, fixture::storm_200m());
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
        const Bolt full = gen.generate(seed), b0 = g0.generate(seed), bp = gp.generate(seed);
        CHECK(b0.segments.size() == b0.main_count);
        CHECK(bp.segments.size() == bp.main_count);
        REQUIRE(b0.main_count == full.main_count);
        for (std::size_t i = 0; i < full.main_count; ++i) CHECK(b0.segments[i].b == full.segments[i].b);
    }
}

TEST_CASE("generator: a small domain makes bolts hit its walls; they stay inside and still reach the ground") {
    BoltParams p;
    // A box 2.4 km wide around the tower: most bolts reach a wall.
    const Box small{glm::dvec3(-1200.0, -1200.0, 0.0), glm::dvec3(1200.0, 1200.0, 9600.0)};
    const BoltGenerator gen(p, fixture::storm_200m(), small);
    std::size_t reflections = 0, clipped = 0;
    for (std::uint64_t seed = 1; seed <= 40; ++seed) {
        const Bolt b = gen.generate(seed);
        reflections += b.reflections;
        clipped += b.clipped;
        CHECK(b.segments[b.main_count - 1].b.z == 0.0);
        for (const Segment& s : b.segments) {
            CHECK(small.contains(s.a));
            CHECK(small.contains(s.b));
            CHECK(std::isfinite(s.length()));
        }
    }
    CHECK(reflections > 0);
    CHECK(clipped > 0);
    // A start point exactly on the domain's corner.
    const Bolt corner = gen.generate_from(glm::dvec3(1200.0, 1200.0, 9600.0), 5);
    CHECK(corner.reached_target);
    for (const Segment& s : corner.segments) CHECK(small.contains(s.b));
}

TEST_CASE("generator: the segment cap holds and a capped cloud-to-ground bolt is closed to the ground") {
    BoltParams p;
    p.segment_length_mean = 1.0;  // ~8000 segments would be needed
    p.segment_length_spread = 0.0;
    p.max_segments = 300;
    const BoltGenerator gen(p, fixture::storm_200m());
    const Bolt b = gen.generate(3);
    CHECK(b.segments.size() <= 300);
    CHECK(b.forced);
    CHECK(b.segments[b.main_count - 1].b.z == 0.0);
}

TEST_CASE("generator: clouds without a start region and impossible grounds are rejected with a named error") {
    core::GridGeometry g;
    g.dims = {16, 16, 16};
    g.voxel_size = 100.0;
    const core::Grid3<float> empty(g, 0.0f);
    CHECK_THROWS_WITH_AS(BoltGenerator(BoltParams{}, empty), doctest::Contains("lightning.start_density_threshold"),
                         Error);
    CHECK_THROWS_WITH_AS(BoltGenerator(BoltParams{}, empty), doctest::Contains("maximum density there is 0"), Error);
    core::Grid3<float> thin(g, 0.2f);  // below the default threshold 0.3
    CHECK_THROWS_WITH_AS(BoltGenerator(BoltParams{}, thin), doctest::Contains("0.2"), Error);
    core::Grid3<float> nan(g, std::numeric_limits<float>::quiet_NaN());
    CHECK_THROWS_AS(BoltGenerator(BoltParams{}, nan), Error);

    BoltParams high;
    high.ground_height = 9600.0;  // the grid's top
    CHECK_THROWS_WITH_AS(BoltGenerator(high, fixture::storm_200m()), doctest::Contains("lightning.ground_height"),
                         Error);

    // A one-voxel cloud: every kind still produces a finite bolt.
    core::Grid3<float> one(g, 0.0f);
    one.at(8, 8, 12) = 1.0f;
    for (Kind k : {Kind::CloudToGround, Kind::IntraCloud, Kind::CloudToCloud}) {
        BoltParams p;
        p.kind = k;
        const BoltGenerator gen(p, one);
        const Bolt b = gen.generate(1);
        CHECK(b.main_count > 0);
        for (const Segment& s : b.segments) CHECK(gen.domain().contains(s.b));
    }
}

TEST_CASE("generator: absurd parameters are rejected naming the field") {
    auto rejects = [](auto mutate, const char* field) {
        LightningParams p;
        mutate(p);
        CHECK_THROWS_WITH_AS(validate(p), doctest::Contains(field), Error);
    };
    rejects([](LightningParams& p) { p.bolt.angle_mean_deg = std::numeric_limits<double>::quiet_NaN(); },
            "lightning.angle_mean");
    rejects([](LightningParams& p) { p.bolt.angle_spread_deg = -1.0; }, "lightning.angle_spread");
    rejects([](LightningParams& p) { p.bolt.segment_length_mean = 0.0; }, "lightning.segment_length_mean");
    rejects([](LightningParams& p) { p.bolt.branch_probability = 1.5; }, "lightning.branches.probability");
    rejects([](LightningParams& p) { p.bolt.max_depth = 9; }, "lightning.branches.max_depth");
    rejects([](LightningParams& p) { p.bolt.intensity = std::numeric_limits<double>::infinity(); },
            "lightning.intensity");
    rejects([](LightningParams& p) { p.bolt.start_density_threshold = 1.0; }, "lightning.start_density_threshold");
    rejects([](LightningParams& p) { p.timing.decay_time = 0.0; }, "lightning.timing.decay_time");
    rejects([](LightningParams& p) { p.timing.restrikes = -1.0; }, "lightning.timing.restrikes");
    rejects([](LightningParams& p) { p.schedule.strike_rate = -0.1; }, "lightning.strike_rate");
    CHECK_NOTHROW(validate(LightningParams{}));
    BoltParams bad;
    bad.target_bias = 2.0;
    CHECK_THROWS_WITH_AS(BoltGenerator(bad, fixture::storm_200m()), doctest::Contains("target_bias"), Error);
}
