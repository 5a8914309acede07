// Rain shafts: the Marshall-Palmer extinction, the footprint under the thick columns, the
// rain's top at their base, the lean with the shear, the streaks, determinism and bounds.
#include "cloud/rain.h"
#include "core/parallel.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

using namespace fulgur;
using cloud::RainParams;

namespace {

// A 40 x 40 x 24 grid of 250 m voxels (10 x 10 x 6 km): a flat-based cloud from z = 1500 m,
// 1 km thick everywhere over a disc of 4 km radius, with a 4.5 km tall tower of 1.5 km
// radius at (-1000, 0). The tower's columns are the thick ones.
core::Grid3<float> tower_cloud() {
    core::GridGeometry g{{40, 40, 24}, 250.0, glm::dvec3(-5000.0, -5000.0, 0.0)};
    core::Grid3<float> d(g, 0.0f);
    for (int k = 0; k < 24; ++k)
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i) {
                const glm::dvec3 c = g.centre(i, j, k);
                const double r = std::hypot(c.x, c.y), rt = std::hypot(c.x + 1000.0, c.y);
                const bool deck = r < 4000.0 && c.z > 1500.0 && c.z < 2500.0;
                const bool tower = rt < 1500.0 && c.z > 1500.0 && c.z < 6000.0;
                if (deck || tower) d.at(i, j, k) = 0.8f;
            }
    return d;
}

// The rain's extinction-weighted horizontal centre in the layer k.
glm::dvec2 centre_of(const cloud::RainField& r, int k) {
    const core::GridGeometry& g = r.extinction.geom;
    glm::dvec2 s(0.0);
    double w = 0.0;
    for (int j = 0; j < g.dims.y; ++j)
        for (int i = 0; i < g.dims.x; ++i) {
            const double e = r.extinction.at(i, j, k);
            s += e * glm::dvec2(g.centre(i, j, k));
            w += e;
        }
    return w > 0.0 ? s / w : glm::dvec2(1e30);
}

}  // namespace

TEST_CASE("rain's extinction: Marshall-Palmer drops with extinction efficiency 2") {
    // sigma = pi N0 / Lambda^3, N0 = 8000 m^-3 mm^-1, Lambda = 4.1 R^-0.21 mm^-1, mm^2 -> m^2.
    CHECK(cloud::rain_extinction(1.0) == doctest::Approx(std::numbers::pi * 8000.0 / std::pow(4.1, 3) * 1e-6));
    // 0.37 R^0.63 per km: 25 mm/h is ~2.8 km^-1 (a visual range 3.9 / sigma of ~1.4 km).
    CHECK(cloud::rain_extinction(25.0) * 1000.0 == doctest::Approx(0.365 * std::pow(25.0, 0.63)).epsilon(0.01));
    CHECK(cloud::rain_extinction(25.0) > cloud::rain_extinction(5.0));
}

TEST_CASE("rain falls below the thick columns' base, to the ground, and nowhere else") {
    const core::Grid3<float> d = tower_cloud();
    RainParams p;
    p.rate = 25.0;
    p.streak_strength = 0.0;  // uniform rain: the footprint alone
    const cloud::RainField r = cloud::make_rain(d, p);
    const core::GridGeometry& g = d.geom;
    CHECK(r.top == doctest::Approx(1500.0));  // the voxel face under the base's first voxel
    CHECK(r.max_extinction == doctest::Approx(cloud::rain_extinction(25.0)).epsilon(1e-6));
    int wet_under_tower = 0, wet_elsewhere = 0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const float e = r.extinction.at(i, j, k);
                CHECK(std::isfinite(e));
                CHECK(e >= 0.0f);
                const glm::dvec3 c = g.centre(i, j, k);
                if (c.z > r.top) CHECK(e == 0.0f);  // never inside or above the cloud
                if (e <= 0.0f) continue;
                (std::hypot(c.x + 1000.0, c.y) < 2200.0 ? wet_under_tower : wet_elsewhere) += 1;
            }
    CHECK(wet_under_tower > 0);
    // The deck is thin (1 km of cloud against the tower's 4.5 km): no rain there, beyond the
    // footprint's blurred edge (2 x 1 column, i.e. 500 m past the tower's 1.5 km).
    CHECK(wet_elsewhere == 0);
    // At the ground, the full rate under the tower's centre.
    const cloud::RainField same = cloud::make_rain(d, p);
    CHECK(same.extinction.data == r.extinction.data);
    const float ground = r.extinction.at(16, 20, 0);  // (-875, 125, 125)
    CHECK(ground == doctest::Approx(cloud::rain_extinction(25.0)).epsilon(1e-6));
}

TEST_CASE("the shaft leans downwind with the shear; streaks vary the rate around its mean") {
    const core::Grid3<float> d = tower_cloud();
    RainParams p;
    p.streak_strength = 0.0;
    const cloud::RainField still = cloud::make_rain(d, p);
    p.shear = {600.0, 0.0};  // 600 m of drift per km of fall
    const cloud::RainField leaning = cloud::make_rain(d, p);
    // Layer 0 (z = 125 m) fell 1375 m from the base: 825 m downwind (+x).
    const double drift = centre_of(leaning, 0).x - centre_of(still, 0).x;
    MESSAGE("drift at 125 m: ", drift, " m (600 m/km over 1375 m: 825 m)");
    CHECK(drift == doctest::Approx(825.0).epsilon(0.05));
    CHECK(std::abs(centre_of(leaning, 0).y - centre_of(still, 0).y) < 1.0);

    p.shear = {0.0, 0.0};
    p.streak_strength = 0.8;
    p.seed = 3;
    const cloud::RainField streaky = cloud::make_rain(d, p);
    double lo = 1e9, hi = 0.0;
    for (std::size_t i = 0; i < streaky.extinction.data.size(); ++i) {
        if (still.extinction.data[i] < 0.999f * float(still.max_extinction))
            continue;  // the footprint's heart, below the fall depth
        const double m = streaky.extinction.data[i] / still.extinction.data[i];
        lo = std::min(lo, m);
        hi = std::max(hi, m);
    }
    MESSAGE("streak modulation: ", lo, " to ", hi, " (bounds 0.2 to 1.8)");
    CHECK(lo >= 0.2 - 1e-6);
    CHECK(hi <= 1.8 + 1e-6);
    CHECK(hi - lo > 0.5);  // the streaks show
}

TEST_CASE("a cloud that never gets dense, or that touches the ground, has no rain") {
    core::Grid3<float> thin(core::GridGeometry{{8, 8, 8}, 100.0, glm::dvec3(0.0)}, 0.05f);
    CHECK(cloud::make_rain(thin, RainParams{}).max_extinction == 0.0);
    core::Grid3<float> fog(core::GridGeometry{{8, 8, 8}, 100.0, glm::dvec3(0.0)}, 0.5f);
    CHECK(cloud::make_rain(fog, RainParams{}).max_extinction == 0.0);
    core::Grid3<float> empty(core::GridGeometry{{8, 8, 8}, 100.0, glm::dvec3(0.0)}, 0.0f);
    CHECK(cloud::make_rain(empty, RainParams{}).max_extinction == 0.0);
}

TEST_CASE("rain does not depend on the thread count") {
    const core::Grid3<float> d = tower_cloud();
    RainParams p;
    p.shear = {300.0, -200.0};
    const int threads = core::thread_count();
    core::set_thread_count(1);
    const cloud::RainField one = cloud::make_rain(d, p);
    core::set_thread_count(2);
    const cloud::RainField two = cloud::make_rain(d, p);
    core::set_thread_count(threads);
    CHECK(one.extinction.data == two.extinction.data);
}

TEST_CASE("bad rain parameters are refused, naming the scene field") {
    auto expect = [](RainParams p, const std::string& field) {
        CAPTURE(field);
        try {
            cloud::validate_rain(p);
            FAIL("accepted");
        } catch (const core::Error& e) {
            CHECK(e.where() == "rain." + field);
        }
    };
    const double nan = std::nan("");
    for (double v : {0.0, -1.0, 2000.0, nan}) {
        RainParams p;
        p.rate = v;
        expect(p, "rate");
    }
    for (double v : {-0.1, 1.0, nan}) {
        RainParams p;
        p.threshold = v;
        expect(p, "threshold");
    }
    RainParams p;
    p.shear = {1e4, 0.0};
    expect(p, "shear");
    p = RainParams{};
    p.shear = {0.0, nan};
    expect(p, "shear");
    p = RainParams{};
    p.streak_scale = 0.0;
    expect(p, "streak_scale");
    p = RainParams{};
    p.streak_strength = 1.5;
    expect(p, "streak_strength");
    p = RainParams{};
    p.g = 1.0;
    expect(p, "g");
    p = RainParams{};
    p.albedo = -0.5;
    expect(p, "albedo");
}
