// Direction interpolation of S between the baked output directions.
#include "render/render.h"
#include "support/test_support.h"
#include "transport/detail/directions.h"
#include "transport/transport.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <cmath>

using namespace fulgur;

namespace {
double weight_of(const render::DirectionWeights& w, int index) {
    for (int i = 0; i < w.count; ++i)
        if (w.index[std::size_t(i)] == index) return w.weight[std::size_t(i)];
    return 0.0;
}
glm::dvec3 random_unit(core::Rng& rng) {
    for (;;) {
        const glm::dvec3 v(2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1);
        const double l = glm::length(v);
        if (l > 0.1 && l <= 1.0) return v / l;
    }
}
}  // namespace

TEST_CASE("direction weights: partition of unity, non-negative, at most four") {
    core::Rng rng(11, 1);
    for (int count : {1, 6, 18, 26})
        for (int i = 0; i < 2000; ++i) {
            const render::DirectionWeights w = render::direction_weights(random_unit(rng), count);
            REQUIRE(w.count >= 1);
            REQUIRE(w.count <= 4);
            double sum = 0.0;
            for (int k = 0; k < w.count; ++k) {
                CHECK(w.weight[std::size_t(k)] >= 0.0);
                CHECK(w.index[std::size_t(k)] >= 0);
                CHECK(w.index[std::size_t(k)] < count);
                sum += w.weight[std::size_t(k)];
            }
            // Weights are products and sums of a handful of doubles: 1e-12 is rounding only.
            CHECK(sum == test::rel(1.0, 1e-12));
        }
}

TEST_CASE("direction weights reproduce every baked direction exactly") {
    for (int count : {6, 18, 26}) {
        const auto dirs = transport::output_directions(count);
        for (int m = 0; m < count; ++m) {
            const render::DirectionWeights w = render::direction_weights(dirs[std::size_t(m)], count);
            // At a node the smoothstep weights are exactly 0 and 1 up to the rounding of
            // normalize() (components like 1/sqrt(3) give |u| = 1 -+ 1 ulp).
            CHECK(weight_of(w, m) == test::rel(1.0, 1e-12));
        }
    }
    const render::DirectionWeights one = render::direction_weights({0.3, -0.2, 0.9}, 1);
    CHECK(one.count == 1);
    CHECK(one.weight[0] == 1.0);
}

TEST_CASE("direction weights vary continuously (C1 construction: small steps, small changes)") {
    core::Rng rng(5, 2);
    for (int count : {6, 18, 26})
        for (int i = 0; i < 500; ++i) {
            const glm::dvec3 d = random_unit(rng);
            const glm::dvec3 e = glm::normalize(d + 1e-6 * random_unit(rng));
            const auto a = render::direction_weights(d, count), b = render::direction_weights(e, count);
            for (int m = 0; m < count; ++m)
                // The weights' derivative is bounded (smoothstep slope <= 1.5, gnomonic map
                // slope <= 2 per radian): a 1e-6 rad move changes a weight by < 1e-5.
                CHECK(std::abs(weight_of(a, m) - weight_of(b, m)) < 1e-5);
        }
}

TEST_CASE("direction weights on a face centre-edge line interpolate the two") {
    // Halfway (in cube-face coordinates) between +x and the +x+y edge: u = 0.5, smoothstep 0.5.
    const auto w = render::direction_weights(glm::normalize(glm::dvec3(1.0, 0.5, 0.0)), 26);
    const auto dirs = transport::output_directions(26);
    int px = -1, pxy = -1;
    for (int m = 0; m < 26; ++m) {
        if (glm::length(dirs[std::size_t(m)] - glm::dvec3(1, 0, 0)) < 1e-9) px = m;
        if (glm::length(dirs[std::size_t(m)] - glm::normalize(glm::dvec3(1, 1, 0))) < 1e-9) pxy = m;
    }
    CHECK(weight_of(w, px) == doctest::Approx(0.5));
    CHECK(weight_of(w, pxy) == doctest::Approx(0.5));
}

TEST_CASE("fold tables hand all weight to present directions") {
    for (int count : {1, 6, 18, 26}) {
        const auto t = transport::detail::fold_table(count);
        for (int c = 0; c < 27; ++c) {
            if (c == 13) continue;  // (0,0,0) is not a direction
            double sum = 0.0;
            for (int k = 0; k < 3; ++k)
                if (t.index[std::size_t(c)][std::size_t(k)] >= 0) sum += t.fraction[std::size_t(c)][std::size_t(k)];
            CHECK(sum == test::rel(1.0, 1e-15));  // thirds and halves in double
        }
    }
    CHECK_THROWS_AS(transport::detail::fold_table(7), core::Error);
}

TEST_CASE("view_directions: a far camera needs few directions, a camera inside needs all") {
    core::GridGeometry g;
    g.dims = {8, 8, 6};
    g.voxel_size = 400.0;
    g.origin = {-1600.0, -1600.0, 0.0};
    const auto far = render::view_directions({1e6, 0.0, 1200.0}, g, 26);
    // Seen from far away along +x every node sees the camera within 0.2 degrees of +x: the
    // neighbours of +x get weights ~3 (0.0035)^2 < 1e-3, below the default threshold...
    REQUIRE(!far.empty());
    CHECK(far.size() == 1);
    // ...but they are not zero: without a threshold the four edges and corners around +x
    // (quadrants of the nodes' directions) appear.
    CHECK(render::view_directions({1e6, 0.0, 1200.0}, g, 26, {}, 0.0).size() == 9);
    double best = 0.0;
    for (const auto& u : far) best = std::max(best, u.max_weight);
    CHECK(best > 0.99);
    const auto inside = render::view_directions({0.0, 0.0, 1200.0}, g, 26);
    CHECK(inside.size() == 26);
    // An empty active mask excludes everything except the active node.
    std::vector<std::uint8_t> active(g.cell_count(), 0);
    active[g.index(0, 0, 0)] = 1;
    const auto one = render::view_directions({1e6, 0.0, 1200.0}, g, 26, active);
    CHECK(one.size() <= far.size());
    CHECK_THROWS_AS(render::view_directions({0, 0, 0}, g, 26, std::vector<std::uint8_t>(3, 1)), core::Error);
    CHECK_THROWS_AS(render::view_directions({0, 0, 0}, g, 5), core::Error);
}
