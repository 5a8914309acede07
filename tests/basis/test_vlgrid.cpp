#include "basis/basis.h"
#include "support/grids.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>

using namespace fulgur;
using basis::VirtualLightGrid;
using basis::VirtualLightParams;

namespace {

// An ellipsoidal cloud in a 40x40x30 grid of 100 m voxels, origin (-2000, -2000, 0):
// voxels i in [ci-rx, ci+rx] etc. above `k0` up to `k1`.
core::Grid3<float> blob(int k0 = 10, int k1 = 24, int i0 = 8, int i1 = 29, int j0 = 12, int j1 = 27) {
    core::Grid3<float> d = test::uniform_grid({40, 40, 30}, 100.0, {-2000.0, -2000.0, 0.0});
    const double ci = 0.5 * (i0 + i1), cj = 0.5 * (j0 + j1), ck = 0.5 * (k0 + k1);
    const double ri = 0.5 * (i1 - i0) + 0.5, rj = 0.5 * (j1 - j0) + 0.5, rk = 0.5 * (k1 - k0) + 0.5;
    for (int k = k0; k <= k1; ++k)
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) {
                const double q = std::pow((i - ci) / ri, 2) + std::pow((j - cj) / rj, 2) + std::pow((k - ck) / rk, 2);
                // Every layer and column of the box holds cloud along the axes through the centre.
                d.at(i, j, k) =
                    q <= 1.0 || (i == int(ci) && j == int(cj)) || (k == int(ck) && (i == int(ci) || j == int(cj)))
                        ? 0.8f
                        : 0.01f;
            }
    return d;
}

// Eq. 4's largest next distance from r (infinite when 1/r^2 <= epsilon).
double eq4_next(double r, double eps) {
    const double inv = 1.0 / (r * r) - eps;
    return inv > 0 ? 1.0 / std::sqrt(inv) : std::numeric_limits<double>::infinity();
}

// Checks the properties every grid must have for cloud bounds (world) and params.
void check_grid(const VirtualLightGrid& v, const core::Grid3<float>& d, const VirtualLightParams& p, double x0,
                double x1, double y0, double y1, double zb, double zt) {
    const double tol = 1e-9 * 1e4;  // coordinates ~1e4 m: 1e-5 m is far above double rounding
    // Horizontal: spacing exactly h_usr, footprint + margin covered, at least 2 nodes.
    for (const auto* axis : {&v.x, &v.y}) {
        REQUIRE(axis->size() >= 2);
        for (std::size_t i = 1; i < axis->size(); ++i) CHECK((*axis)[i] - (*axis)[i - 1] == doctest::Approx(p.h_usr));
    }
    CHECK(v.x.front() <= x0 - p.margin + tol);
    CHECK(v.x.back() >= x1 + p.margin - tol);
    CHECK(v.y.front() <= y0 - p.margin + tol);
    CHECK(v.y.back() >= y1 + p.margin - tol);
    // Not wider than needed: dropping an end node would uncover the footprint.
    CHECK(v.x.back() - v.x.front() < (x1 - x0 + 2 * p.margin) + p.h_usr + tol);
    // Vertical: the base is a node; uniform h_usr from the base through the top.
    CHECK(v.cloud_base == doctest::Approx(zb));
    CHECK(v.cloud_top == doctest::Approx(zt));
    REQUIRE(v.base_layer < v.z.size());
    CHECK(v.z[v.base_layer] == doctest::Approx(zb));
    for (std::size_t k = v.base_layer + 1; k < v.z.size(); ++k) CHECK(v.z[k] - v.z[k - 1] == doctest::Approx(p.h_usr));
    CHECK(v.z.back() >= zt - tol);
    CHECK(v.z.size() - v.base_layer >= 2);
    CHECK(v.z.back() - p.h_usr < zt + tol);  // no needless layer above the top
    // Below the base: r measured downward; Eq. 4 with the minimum spacing h_usr.
    const double depth = zb - p.ground_height;
    if (depth <= tol) {
        CHECK(v.base_layer == 0);
    } else {
        CHECK(v.z.front() == doctest::Approx(p.ground_height));
        std::vector<double> r;
        for (std::size_t k = v.base_layer; k-- > 0;) r.push_back(zb - v.z[k]);
        if (depth <= p.h_usr) {
            CHECK(r.size() == 1);  // the base is within h_usr of the ground: one layer there
        } else {
            CHECK(r.front() >= p.h_usr - tol);  // r_1 (Eq. 4 undefined at r_0 = 0)
            for (std::size_t l = 0; l + 1 < r.size(); ++l) {
                const double gap = r[l + 1] - r[l];
                CHECK(gap >= p.h_usr - tol);  // the paper's r_{l+1} - r_l >= h_usr
                const double planned = std::max(r[l] + p.h_usr, eq4_next(r[l], p.epsilon));
                if (l + 2 < r.size()) {
                    // Maximal spacing: exactly the larger of h_usr and Eq. 4's bound.
                    CHECK(r[l + 1] == test::rel(planned, 1e-12));
                    // Where Eq. 4 (not h_usr) set the spacing, Eq. 4 holds.
                    if (eq4_next(r[l], p.epsilon) > r[l] + p.h_usr)
                        CHECK(1 / (r[l] * r[l]) - 1 / (r[l + 1] * r[l + 1]) <= p.epsilon * (1 + 1e-9));
                } else {
                    // The ground layer: at most h_usr beyond where the plan would have put it.
                    CHECK(r[l + 1] < planned + p.h_usr + tol);
                }
            }
        }
    }
    // Lights inside the cloud volume: when h_usr is no larger than the cloud, virtual lights
    // sit inside its bounding box and in cloud voxels (the test clouds are dense around
    // their centre lines); every cloud voxel lies inside the virtual-light grid's box.
    if (p.h_usr <= std::min({x1 - x0, y1 - y0, zt - zb})) {
        std::size_t in_box = 0, in_cloud = 0;
        for (std::size_t l = 0; l < v.count(); ++l) {
            const glm::dvec3 q = v.position(l);
            if (q.x >= x0 && q.x <= x1 && q.y >= y0 && q.y <= y1 && q.z >= zb && q.z <= zt) ++in_box;
            if (d.geom.contains(q)) {
                const glm::dvec3 u = d.geom.to_voxel(q);
                if (d.at(int(u.x), int(u.y), int(u.z)) > float(p.density_threshold)) ++in_cloud;
            }
        }
        // Lattice of spacing h over an extent >= h: at least one node per axis inside.
        CHECK(in_box >= 1);
        CHECK(in_cloud >= 1);
    }
    for (int k = 0; k < d.dims().z; ++k)
        for (int j = 0; j < d.dims().y; ++j)
            for (int i = 0; i < d.dims().x; ++i)
                if (d.at(i, j, k) > float(p.density_threshold)) {
                    const glm::dvec3 c = d.geom.centre(i, j, k);
                    if (c.x < v.x.front() || c.x > v.x.back() || c.y < v.y.front() || c.y > v.y.back() ||
                        c.z < v.z.front() || c.z > v.z.back())
                        FAIL_CHECK("cloud voxel " << i << "," << j << "," << k << " outside the virtual-light grid");
                }
}

}  // namespace

TEST_CASE("virtual-light grid of a cloud: footprint + margin, uniform through the cloud, Eq. 4 below") {
    const core::Grid3<float> d = blob();
    // Footprint in world units: voxel boxes of i in [8, 29], j in [12, 27], k in [10, 24].
    const double x0 = -2000 + 800, x1 = -2000 + 3000, y0 = -2000 + 1200, y1 = -2000 + 2800, zb = 1000, zt = 2500;
    for (double eps : {0.0, 1e-8, 1e-7, 3e-7, 1e-6, 3e-6, 1e3}) {
        for (double h : {100.0, 250.0, 300.0, 700.0}) {
            VirtualLightParams p;
            p.h_usr = h;
            p.epsilon = eps;
            p.margin = 350.0;
            p.ground_height = 0.0;
            INFO("eps " << eps << " h " << h);
            check_grid(basis::build_virtual_light_grid(d, p), d, p, x0, x1, y0, y1, zb, zt);
        }
    }
    // Eq. 4 actually changes the spacing: with h = 100 m, epsilon 3e-6 puts fewer layers
    // below the base than epsilon 0 (uniform h_usr).
    VirtualLightParams p;
    p.h_usr = 100.0;
    p.epsilon = 0.0;
    const auto uniform = basis::build_virtual_light_grid(d, p);
    p.epsilon = 3e-6;
    const auto adaptive = basis::build_virtual_light_grid(d, p);
    CHECK(uniform.base_layer == 10);  // 1000 m in steps of 100 m
    // r = 100, 200, 300, 400 (h_usr wins), 555 (Eq. 4 wins), then the ground at 1000 m.
    CHECK(adaptive.base_layer == 6);
    CHECK(adaptive.z[1] == doctest::Approx(1000.0 - 1.0 / std::sqrt(1.0 / (400.0 * 400.0) - 3e-6)));
}

TEST_CASE("virtual-light grid hard cases") {
    VirtualLightParams p;
    p.h_usr = 300.0;
    p.margin = 200.0;
    p.epsilon = 1e-7;

    SUBCASE("empty cloud: an error naming the problem") {
        core::GridGeometry g;
        g.dims = {8, 8, 8};
        core::Grid3<float> d(g, 0.01f);
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("the cloud is empty"),
                             core::Error);
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("density_threshold 0.05"),
                             core::Error);
        d.at(3, 3, 3) = std::numeric_limits<float>::quiet_NaN();  // NaN is not cloud
        CHECK_THROWS_AS(basis::build_virtual_light_grid(d, p), core::Error);
    }
    SUBCASE("cloud touching the grid bottom (and the ground)") {
        const core::Grid3<float> d = blob(0, 12);
        const auto v = basis::build_virtual_light_grid(d, p);
        CHECK(v.base_layer == 0);
        CHECK(v.z.front() == 0.0);
        check_grid(v, d, p, -1200, 1000, -800, 800, 0, 1300);
    }
    SUBCASE("base within h_usr of the ground: one layer on the ground") {
        const core::Grid3<float> d = blob(1, 12);
        const auto v = basis::build_virtual_light_grid(d, p);
        CHECK(v.base_layer == 1);
        CHECK(v.z[0] == 0.0);
        CHECK(v.z[1] == 100.0);
    }
    SUBCASE("epsilon huge: after r_1 = h_usr the next layer is the ground") {
        p.epsilon = 1e6;
        const core::Grid3<float> d = blob();
        const auto v = basis::build_virtual_light_grid(d, p);
        REQUIRE(v.base_layer == 2);
        CHECK(v.z[0] == 0.0);
        CHECK(v.z[1] == doctest::Approx(1000.0 - 300.0));
    }
    SUBCASE("epsilon tiny: uniform h_usr below the base") {
        p.epsilon = 1e-30;
        const core::Grid3<float> d = blob();
        const auto v = basis::build_virtual_light_grid(d, p);
        // 1000 m: r = 300, 600, then 900 is within h_usr of the ground and is removed.
        REQUIRE(v.base_layer == 3);
        CHECK(v.z[0] == 0.0);
        CHECK(v.z[1] == doctest::Approx(400.0));
        CHECK(v.z[2] == doctest::Approx(700.0));
    }
    SUBCASE("h_usr larger than the cloud") {
        p.h_usr = 50000.0;
        const core::Grid3<float> d = blob();
        const auto v = basis::build_virtual_light_grid(d, p);
        CHECK(v.x.size() == 2);
        CHECK(v.y.size() == 2);
        CHECK(v.z.size() == 3);  // ground, base, base + h_usr
        check_grid(v, d, p, -1200, 1000, -800, 800, 1000, 2500);
    }
    SUBCASE("a single-voxel cloud") {
        const core::Grid3<float> d = test::single_voxel_cloud({5, 5, 5}, 100.0, {2, 2, 3});
        const auto v = basis::build_virtual_light_grid(d, p);
        check_grid(v, d, p, 200, 300, 200, 300, 300, 400);
    }
    SUBCASE("ground above the cloud base, bad parameters, too many lights") {
        const core::Grid3<float> d = blob();
        p.ground_height = 1500.0;
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("virtual_lights.ground_height"),
                             core::Error);
        p.ground_height = 0.0;
        p.h_usr = std::numeric_limits<double>::quiet_NaN();
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("virtual_lights.h_usr"),
                             core::Error);
        p.h_usr = -3.0;
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("virtual_lights.h_usr"),
                             core::Error);
        p.h_usr = 300.0;
        p.epsilon = -1.0;
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("virtual_lights.epsilon"),
                             core::Error);
        p.epsilon = 1e-7;
        p.density_threshold = 1.0;
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("density_threshold"),
                             core::Error);
        p.density_threshold = 0.05;
        p.h_usr = 0.5;
        CHECK_THROWS_WITH_AS(basis::build_virtual_light_grid(d, p), doctest::Contains("increase h_usr"), core::Error);
    }
}
