// Parameter validation of the cumulonimbus generator: every inconsistency is rejected with
// a core::Error whose where() is the scene field to fix.
#include "cloud/detail/automaton.h"
#include "cloud_test_util.h"

#include <doctest/doctest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

using namespace fulgur;
using cloud::CumulonimbusParams;

namespace {

// Expects validate_cumulonimbus *and* generate_cumulonimbus to reject p, naming `field`
// exactly as the scene file spells it; `reason` is a fragment of the explanation.
void expect_rejected(const CumulonimbusParams& p, const std::string& field, const std::string& reason) {
    CAPTURE(field);
    bool thrown = false;
    try {
        cloud::validate_cumulonimbus(p);
    } catch (const core::Error& e) {
        thrown = true;
        CHECK(e.where() == "cloud.generator." + field);
        CHECK_MESSAGE(e.reason().find(reason) != std::string::npos, e.what());
    }
    CHECK(thrown);
    CHECK_THROWS_AS(cloud::generate_cumulonimbus(p), core::Error);
}

// A small, valid cloud (fast even under the sanitizers).
CumulonimbusParams small() {
    CumulonimbusParams p;
    p.grid = {32, 32, 24};
    p.voxel_size = 500.0;
    p.base_height = 1000.0;
    p.top_height = 9000.0;
    p.tower_radius = 2000.0;
    p.anvil_radius = 4500.0;
    p.anvil_offset = 500.0;
    p.cells = 16;
    return p;
}

}  // namespace

TEST_CASE("the defaults and the small test cloud are valid") {
    CHECK_NOTHROW(cloud::validate_cumulonimbus(CumulonimbusParams{}));
    CHECK_NOTHROW(cloud::validate_cumulonimbus(small()));
}

TEST_CASE("inconsistent parameters are rejected naming the scene field") {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CumulonimbusParams p;
    SUBCASE("base above top") {
        p.base_height = 9500.0;
        expect_rejected(p, "top_height", "above base_height");
    }
    SUBCASE("base equal to top") {
        p.base_height = p.top_height;
        expect_rejected(p, "top_height", "above base_height");
    }
    SUBCASE("cloud too shallow for the grid") {
        p.top_height = p.base_height + 500.0;
        expect_rejected(p, "top_height", "6 voxels");
    }
    SUBCASE("top above the grid") {
        p.top_height = 9900.0;
        expect_rejected(p, "top_height", "does not fit");
    }
    SUBCASE("negative base") {
        p.base_height = -10.0;
        expect_rejected(p, "base_height", ">= 0");
    }
    SUBCASE("anvil narrower than the tower") {
        p.anvil_radius = 2000.0;
        expect_rejected(p, "anvil_radius", "larger than tower_radius");
    }
    SUBCASE("anvil wider than the grid") {
        p.anvil_radius = 8000.0;
        expect_rejected(p, "anvil_radius", "does not fit");
    }
    SUBCASE("tower wider than the grid") {
        p.anvil = false;
        p.flanking_towers = 0;
        p.tower_radius = 7000.0;
        expect_rejected(p, "tower_radius", "does not fit");
    }
    SUBCASE("tower too thin to resolve") {
        p.tower_radius = 200.0;
        expect_rejected(p, "tower_radius", "2 voxels");
    }
    SUBCASE("flanking line leaves the grid") {
        p.tower_radius = 3500.0;
        p.anvil_radius = 4000.0;
        p.anvil_offset = 0.0;
        expect_rejected(p, "flanking_towers", "do not fit");
    }
    SUBCASE("too many flanking towers") {
        p.flanking_towers = 9;
        expect_rejected(p, "flanking_towers", "[0, 8]");
    }
    SUBCASE("anvil too thick for the tower") {
        p.anvil_thickness = 5000.0;
        expect_rejected(p, "anvil_thickness", "30%");
    }
    SUBCASE("anvil thinner than 2 voxels") {
        p.anvil_thickness = 200.0;
        expect_rejected(p, "anvil_thickness", "2 voxels");
    }
    SUBCASE("overshoot taller than the anvil") {
        p.overshoot = 2000.0;
        expect_rejected(p, "overshoot", "anvil_thickness");
    }
    SUBCASE("anvil not over its tower") {
        p.anvil_offset = 4500.0;
        expect_rejected(p, "anvil_offset", "stays over the tower");
    }
    SUBCASE("shear tearing the tower apart") {
        p.shear = 6000.0;
        expect_rejected(p, "shear", "twice tower_radius");
    }
    SUBCASE("NaN voxel size") {
        p.voxel_size = nan;
        expect_rejected(p, "voxel_size", "finite");
    }
    SUBCASE("zero voxel size") {
        p.voxel_size = 0.0;
        expect_rejected(p, "voxel_size", "positive");
    }
    SUBCASE("NaN height") {
        p.top_height = nan;
        expect_rejected(p, "top_height", "finite");
    }
    SUBCASE("infinite radius") {
        p.tower_radius = std::numeric_limits<double>::infinity();
        expect_rejected(p, "tower_radius", "finite");
    }
    SUBCASE("tiny grid") {
        p.grid = {4, 128, 96};
        expect_rejected(p, "grid", "[8, 4096]");
    }
    SUBCASE("probability above 1") {
        p.p_ext = 1.5;
        expect_rejected(p, "p_ext", "[0, 1]");
    }
    SUBCASE("NaN probability") {
        p.p_hum = nan;
        expect_rejected(p, "p_hum", "finite");
    }
    SUBCASE("no activation: the cloud would be empty") {
        p.p_act = 0.0;
        expect_rejected(p, "p_act", "nothing ever condenses");
    }
    SUBCASE("no vapour: the cloud would be empty") {
        p.p_hum = 0.0;
        expect_rejected(p, "p_hum", "nothing ever condenses");
    }
    SUBCASE("window longer than the run") {
        p.average_steps = p.steps + 1;
        expect_rejected(p, "average_steps", "steps");
    }
    SUBCASE("no steps") {
        p.steps = 0;
        expect_rejected(p, "steps", "[1, 1000]");
    }
    SUBCASE("huge smoothing") {
        p.smoothing_radius = 17;
        expect_rejected(p, "smoothing_radius", "[0, 16]");
    }
    SUBCASE("zero softness") {
        p.edge_softness = 0.0;
        expect_rejected(p, "edge_softness", "(0, 1]");
    }
    SUBCASE("zero gain") {
        p.density_gain = 0.0;
        expect_rejected(p, "density_gain", "(0, 100]");
    }
    SUBCASE("negative cells") {
        p.cells = -1;
        expect_rejected(p, "cells", "[0, 1000]");
    }
}

TEST_CASE("anvil-only fields are not checked when the anvil is off") {
    CumulonimbusParams p;
    p.anvil = false;
    p.anvil_radius = 1.0;  // narrower than the tower: irrelevant without an anvil
    p.overshoot = 1e5;
    p.anvil_offset = 1e5;
    CHECK_NOTHROW(cloud::validate_cumulonimbus(p));
}

TEST_CASE("small clouds: every option combination gives a non-empty cloud with a flat base") {
    for (bool anvil : {true, false})
        for (int flanking : {0, 2})
            for (int cells : {0, 16})
                for (std::uint64_t seed : {1u, 99u}) {
                    CAPTURE(anvil);
                    CAPTURE(flanking);
                    CAPTURE(cells);
                    CAPTURE(seed);
                    CumulonimbusParams p = small();
                    p.anvil = anvil;
                    p.flanking_towers = flanking;
                    p.cells = cells;
                    p.seed = seed;
                    const core::Grid3<float> d = cloud::generate_cumulonimbus(p);
                    // A 2 km tower 8 km tall has ~800 voxels of (500 m)^3 in it; even the
                    // bare column must leave a few hundred dense voxels.
                    CHECK(cloud::test::cloudy_voxels(d, 0.5f) > 200);
                    // Base within one voxel of base_height (quantization), the top within
                    // the smoothing reach.
                    CHECK(std::fabs(cloud::cloud_base_height(d) - p.base_height) < p.voxel_size);
                    CHECK(std::fabs(cloud::cloud_top_height(d) - p.top_height) <=
                          (p.smoothing_radius + 1) * p.voxel_size);
                }
}

TEST_CASE("the layout is a pure function of the parameters, and the seed field honours the floor") {
    const CumulonimbusParams p = small();
    const auto a = cloud::detail::cumulonimbus_layout(p);
    const auto b = cloud::detail::cumulonimbus_layout(p);
    REQUIRE(a.size() == b.size());
    for (std::size_t i = 0; i < a.size(); ++i) CHECK(a[i].centre == b[i].centre);
    const core::GridGeometry g = cloud::cumulonimbus_geometry(p);
    const auto w = cloud::detail::seed_field(g, a, p.base_height);
    std::size_t below = 0, above = 0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const bool positive = w[g.index(i, j, k)] > 0;
                (g.centre(i, j, k).z < p.base_height ? below : above) += positive ? 1 : 0;
            }
    CHECK(below == 0);
    CHECK(above > 0);
}
