// The ground tally (MonteCarloOptions::ground): the light a cloud scatters onto a ground plane,
// against an independent estimate from the same run's S, against the energy a mirror-symmetric
// cloud must send down, split by source group, the same from the progressive tracer; and bad
// ground tallies rejected with the field named.
#include "support/test_support.h"
#include "transport/ground_dome.h"
#include "transport/transport.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <numbers>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

// Relative L2 of a against b.
double rel_l2(const std::vector<double>& a, const std::vector<double>& b) {
    double d = 0.0, n = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        d += (a[i] - b[i]) * (a[i] - b[i]);
        n += b[i] * b[i];
    }
    return std::sqrt(d / n);
}

}  // namespace

TEST_CASE("ground tally: the scattered light on the ground is what the cloud's S sends there") {
    // With an isotropic phase (g = 0) S is the same in every direction, so S of one tally
    // direction gives the radiance toward any ground point, gathered along rays up from it
    // (ground_dome): an estimate of the same irradiance from the S tallies (the collision and
    // expected-value estimators), independent of the ground tally's crossing points. Voxels
    // are optically thin (sigma_t h <= 0.2), so S constant in a voxel is off by well under 1%.
    const LightingMedium m = test::synthetic_cloud({10, 10, 8}, 200.0, {0.001, 0.9, 0.0});
    const auto dirs = output_directions(1);
    MonteCarloOptions o;
    o.paths = 2'000'000;
    o.batches = 16;
    GroundTally ground;
    ground.height = -2000.0;
    ground.cell = 1000.0;
    ground.nx = ground.ny = 8;
    ground.origin = {-4000.0, -4000.0};
    o.ground = ground;
    const PointSource light{{100.0, -50.0, 900.0}, 1.0};
    const MonteCarloResult r = monte_carlo(m, light, dirs, o);
    REQUIRE(r.ground.data.size() == 64);

    // The S estimate, averaged over each ground cell by 4 x 4 points of 4096 rays (the cloud's
    // 200 m voxels take ~0.01 sr each from the ground: test_ground_dome).
    const std::vector<std::vector<const SourceField*>> parts = {{&r.single, &r.multiple}};
    const GroundIrradiance gathered =
        ground_dome(m, parts, {}, ground, {.rays = 4096, .points_per_side = 4}).groups.at(0);
    std::vector<double> from_s(64, 0.0), tallied(64, 0.0);
    for (std::size_t c = 0; c < 64; ++c) {
        from_s[c] = gathered.data[c];
        tallied[c] = r.ground.data[c];
    }
    double sum_s = 0.0, sum_t = 0.0;
    for (std::size_t c = 0; c < 64; ++c) {
        sum_s += from_s[c] * ground.cell * ground.cell;
        sum_t += tallied[c] * ground.cell * ground.cell;
    }
    const double err = rel_l2(tallied, from_s);
    MESSAGE("ground tally against the S estimate: relative L2 over 64 cells "
            << err << ", totals " << sum_t << " / " << sum_s << " W, power " << r.ground_power.mean << " +- "
            << r.ground_power.se);
    // The tally's own noise: 3.6% of the emitted power reaches the cells, ~70 000 of the 2M
    // paths, ~1100 crossings a cell (3%, less in the middle, more at the corners); measured
    // 3.0% (2.6% with each voxel summed as a point at its centre). The bound is the noise's
    // 3% + 2 points; S constant in a voxel is off by well under 1%.
    CHECK(err < 0.05);
    // The total over the cells: 0.3% noise (its SE), measured 1.0% apart (the rays' quadrature:
    // 0.3% with the voxels as points). The bound: 1.5%.
    CHECK(sum_t == test::rel(sum_s, 0.015));
    CHECK(r.ground.power() == test::rel(sum_t, 1e-6));
    CHECK(r.ground_power.mean == test::rel(sum_t, 1e-6));  // the power the cells received
}

TEST_CASE("ground tally: a cloud mirror-symmetric about its source sends half its scattered escape down") {
    // A slab symmetric under z -> 2 z0 - z about the source's height: every escaped scattered
    // path leaves going down or up with equal probability, and every one going down crosses the
    // plane below the cloud. Its sides send light out nearly level, which lands far: the cells
    // reach 20 000 km, so what lands beyond them (the paths within 1.5 km / 2e7 m of level,
    // ~5e-5 of them) is far below the check's noise.
    core::GridGeometry geo;
    geo.dims = {8, 8, 8};
    geo.voxel_size = 125.0;
    geo.origin = {-500.0, -500.0, 1000.0};
    LightingMedium m;
    m.density = core::Grid3<float>(geo, 1.0f);
    m.optics = {0.004, 0.95, 0.6};
    MonteCarloOptions o;
    o.paths = 400'000;
    o.groups = 2;
    o.ground = GroundTally{.height = 0.0, .origin = {-2e7, -2e7}, .cell = 1e5, .nx = 400, .ny = 400};
    // Two line sources through the centre, in two groups, each symmetric about z = 1500.
    const std::vector<LineSource> lines = {{{-200.0, 0.0, 1300.0}, {200.0, 0.0, 1700.0}, 1.0, 0},
                                           {{0.0, -100.0, 1400.0}, {0.0, 100.0, 1600.0}, 2.0, 1}};
    const MonteCarloResult r = monte_carlo(m, {}, lines, geo, output_directions(1), o);
    const double half = 0.5 * r.energy.escaped_scattered_mean();
    MESSAGE("ground power " << r.ground_power.mean << " +- " << r.ground_power.se << ", half the scattered escape "
                            << half);
    // Both are estimates from the same paths; the difference is the up/down coin's noise,
    // bounded by the ground power's own SE (4 SE) plus the lost tail.
    CHECK(std::fabs(r.ground_power.mean - half) <= 4.0 * r.ground_power.se);
    CHECK(r.ground_power.se < 0.01 * half);  // the run is precise enough for the check to mean something
    // The groups add up to the sum; the brighter group gives more.
    REQUIRE(r.groups.size() == 2);
    CHECK(r.groups[0].ground.power() + r.groups[1].ground.power() == test::rel(r.ground.power(), 1e-5));
    CHECK(r.groups[1].ground.power() > r.groups[0].ground.power());

    // The progressive tracer tallies the same ground (its own paths: within the two SEs).
    const MonteCarloMedium med(m, geo);
    ProgressiveMonteCarlo p(med, {}, lines, output_directions(1), o);
    p.advance(400'000);
    const MonteCarloResult q = p.result();
    MESSAGE("progressive: ground power " << q.ground_power.mean << " +- " << q.ground_power.se);
    CHECK(std::fabs(q.ground_power.mean - r.ground_power.mean) <=
          4.0 * std::hypot(q.ground_power.se, r.ground_power.se));
    REQUIRE(q.groups.size() == 2);
    CHECK(q.groups[0].ground.power() + q.groups[1].ground.power() == test::rel(q.ground.power(), 1e-5));
}

TEST_CASE("ground tally: no scattering, nothing on the ground; bad tallies are rejected with the field named") {
    const LightingMedium m = test::synthetic_cloud({6, 6, 6}, 200.0, {0.002, 0.9, 0.6});
    MonteCarloOptions o;
    o.paths = 20'000;
    o.ground = GroundTally{.height = 0.0, .origin = {-5000.0, -5000.0}, .cell = 500.0, .nx = 20, .ny = 20};
    o.max_scatterings = 0;  // the uncollided light only: the ground tally holds scattered light
    const MonteCarloResult r = monte_carlo(m, PointSource{{0, 0, 900}, 1.0}, output_directions(1), o);
    CHECK(r.ground.power() == 0.0);
    const auto bad = [&](auto mutate, const char* field) {
        MonteCarloOptions b = o;
        b.max_scatterings = 4;
        mutate(*b.ground);
        CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 900}, 1.0}, output_directions(1), b),
                             doctest::Contains(field), core::Error);
    };
    bad([](GroundTally& g) { g.height = std::nan(""); }, "monte_carlo.ground.height");
    bad([](GroundTally& g) { g.origin.x = INFINITY; }, "monte_carlo.ground.origin");
    bad([](GroundTally& g) { g.cell = 0.0; }, "monte_carlo.ground.cell");
    bad([](GroundTally& g) { g.cell = -1.0; }, "monte_carlo.ground.cell");
    bad([](GroundTally& g) { g.nx = 0; }, "monte_carlo.ground.nx");
    bad([](GroundTally& g) { g.ny = 5000; }, "monte_carlo.ground.ny");
    bad([](GroundTally& g) { g.nx = g.ny = 4096; }, "monte_carlo.ground");
    MonteCarloOptions u = o;
    u.tally_multiple = false;
    u.uncollided_only = true;
    CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 900}, 1.0}, output_directions(1), u),
                         doctest::Contains("monte_carlo.ground"), core::Error);
}
