// The ground cells the cloud's light is gathered on, at the limits of the lighting grids a
// scene can have: a strike's (runtime::strike_ground) and the static light's
// (sky::static_ground_cells), both from transport::ground_cells_around. Each covers the
// lighting grid and 20 km around it, with cells of at least two lighting voxels; the static
// light's stay within 128 a side and within transport::ground_dome's work bound (so the gather
// they feed is never refused); a strike's within 2048 a side (2^22 cells, what a tally holds).
// No ground (or, for a strike, no lightning): none.
#include "runtime/strike_solver.h"
#include "sky/ground.h"

#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <vector>

using namespace fulgur;

namespace {

// The lighting grids: one voxel of 1 m, the default storm's (750 m), a wide thin deck, a
// 4096 km continent, a 1 m grid 4 km across (two voxels would take 22000 cells a side).
std::vector<core::GridGeometry> lighting_grids() {
    return {{{1, 1, 1}, 1.0, {0.0, 0.0, 0.0}},
            {{24, 24, 14}, 750.0, {-9000.0, -9000.0, 0.0}},
            {{400, 400, 4}, 250.0, {-50000.0, -50000.0, 500.0}},
            {{4096, 4096, 16}, 1000.0, {-2048e3, -2048e3, 0.0}},
            {{4000, 4000, 100}, 1.0, {0.0, 0.0, 0.0}}};
}

// Whether `g`'s cells cover the lighting grid's footprint and 20 km around it, each cell at
// least two lighting voxels wide.
void check_covers(const transport::GroundTally& g, const core::GridGeometry& l, double height) {
    constexpr double kMargin = 20000.0;
    CHECK(g.height == height);
    CHECK(g.cell >= 2.0 * l.voxel_size);
    CHECK(g.origin.x <= l.origin.x - kMargin + 1e-9 * kMargin);
    CHECK(g.origin.y <= l.origin.y - kMargin + 1e-9 * kMargin);
    const glm::dvec3 hi = l.upper();
    CHECK(g.origin.x + g.nx * g.cell >= hi.x + kMargin - 1e-9 * (hi.x + kMargin + 1.0));
    CHECK(g.origin.y + g.ny * g.cell >= hi.y + kMargin - 1e-9 * (hi.y + kMargin + 1.0));
    CHECK_NOTHROW(transport::validate_ground_tally(g));
}

}  // namespace

TEST_CASE("the static light's ground cells: cover the grid, 128 a side at most, within the gather's work bound") {
    scene::Scene s;
    s.effects.ground = true;
    s.lightning.bolt.ground_height = 120.0;
    for (const core::GridGeometry& l : lighting_grids()) {
        CAPTURE(l.dims.x);
        CAPTURE(l.voxel_size);
        const auto g = sky::static_ground_cells(s, l);
        REQUIRE(g);
        check_covers(*g, l, 120.0);
        CHECK(g->nx <= 128);
        CHECK(g->ny <= 128);
        // ground_dome's bound at its default rays, with the whole lighting grid as the cloud's
        // box (the most a ray can cross): the gather these cells feed is never refused.
        const double visits =
            double(g->cells()) * transport::DomeGroundOptions{}.rays * double(l.dims.x + l.dims.y + l.dims.z + 3);
        CHECK(visits <= double(std::uint64_t(1) << 33));
    }
    s.effects.ground = false;
    CHECK_FALSE(sky::static_ground_cells(s, lighting_grids()[1]));
}

TEST_CASE("a strike's ground cells: cover the grid, at most 2048 a side (2^22 cells)") {
    scene::Scene s;
    s.effects.ground = s.effects.lightning = true;
    s.lightning.bolt.ground_height = -30.0;
    for (const core::GridGeometry& l : lighting_grids()) {
        CAPTURE(l.dims.x);
        CAPTURE(l.voxel_size);
        const auto g = runtime::strike_ground(s, l);
        REQUIRE(g);
        check_covers(*g, l, -30.0);
        CHECK(g->nx <= 2048);
        CHECK(g->ny <= 2048);
        CHECK(g->cells() <= (std::size_t(1) << 22));
    }
    // The default storm's: cells of two 750 m voxels, 39 a side (18 km + 2 x 20 km).
    const auto storm = runtime::strike_ground(s, lighting_grids()[1]);
    REQUIRE(storm);
    CHECK(storm->cell == 1500.0);
    CHECK(storm->nx == 39);
    s.effects.ground = false;
    CHECK_FALSE(runtime::strike_ground(s, lighting_grids()[1]));
    s.effects.ground = true;
    s.effects.lightning = false;
    CHECK_FALSE(runtime::strike_ground(s, lighting_grids()[1]));
}
