// Exact voxel traversal (3D DDA) and transmittance through the piecewise-constant medium.
#include "support/test_support.h"
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

using namespace fulgur;
using transport::LightingMedium;

namespace {

LightingMedium random_medium(core::Int3 dims, double h, glm::dvec3 origin, std::uint64_t seed) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = h;
    g.origin = origin;
    LightingMedium m;
    m.density = core::Grid3<float>(g);
    core::Rng rng(seed);
    for (float& v : m.density.data) v = float(rng.uniform());
    m.optics.extinction = 0.7;
    return m;
}

// Independent reference: every parameter where the segment crosses a grid plane, sorted;
// between consecutive crossings the voxel is constant, found from the midpoint.
double reference_depth(const LightingMedium& m, glm::dvec3 a, glm::dvec3 b) {
    const core::GridGeometry& g = m.density.geom;
    std::vector<double> ts = {0.0, 1.0};
    const int n[3] = {g.dims.x, g.dims.y, g.dims.z};
    for (int ax = 0; ax < 3; ++ax) {
        if (b[ax] == a[ax]) continue;
        for (int i = 0; i <= n[ax]; ++i) {
            const double t = (g.origin[ax] + i * g.voxel_size - a[ax]) / (b[ax] - a[ax]);
            if (t > 0.0 && t < 1.0) ts.push_back(t);
        }
    }
    std::sort(ts.begin(), ts.end());
    const double len = glm::length(b - a);
    double tau = 0.0;
    for (std::size_t s = 0; s + 1 < ts.size(); ++s) {
        const glm::dvec3 mid = a + 0.5 * (ts[s] + ts[s + 1]) * (b - a);
        if (!g.contains(mid)) continue;
        const glm::dvec3 u = g.to_voxel(mid);
        tau += m.sigma_t(g.index(int(u.x), int(u.y), int(u.z))) * (ts[s + 1] - ts[s]) * len;
    }
    return tau;
}

}  // namespace

TEST_CASE("optical depth by DDA equals the sorted-crossings reference for random segments") {
    const LightingMedium m = random_medium({7, 5, 6}, 1.5, {-2.0, 1.0, 0.5}, 11);
    core::Rng rng(5);
    const glm::dvec3 lo = m.density.geom.origin - 3.0, hi = m.density.geom.upper() + 3.0;
    for (int it = 0; it < 2000; ++it) {
        glm::dvec3 a, b;
        for (int ax = 0; ax < 3; ++ax) {
            a[ax] = lo[ax] + (hi[ax] - lo[ax]) * rng.uniform();
            b[ax] = lo[ax] + (hi[ax] - lo[ax]) * rng.uniform();
        }
        const double ref = reference_depth(m, a, b);
        // Both sum the same ~20 products in a different order: round-off only (1e-12 rel).
        CHECK(transport::optical_depth(m, a, b) == doctest::Approx(ref).epsilon(1e-12).scale(1.0));
        // The integral does not depend on the direction of travel.
        CHECK(transport::optical_depth(m, b, a) == doctest::Approx(ref).epsilon(1e-12).scale(1.0));
    }
}

TEST_CASE("segment lengths tile the clipped segment exactly") {
    core::GridGeometry g;
    g.dims = {9, 4, 13};
    g.voxel_size = 0.3;
    g.origin = {1.0, -2.0, 0.25};
    core::Rng rng(9);
    for (int it = 0; it < 500; ++it) {
        glm::dvec3 a = g.origin + glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()) * g.extent();
        glm::dvec3 b = g.origin + glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()) * g.extent();
        const double len = glm::length(b - a);
        double sum = 0.0;
        int visits = 0;
        std::size_t prev = std::numeric_limits<std::size_t>::max();
        transport::detail::traverse(g, a, (b - a) / len, 0.0, len, [&](std::size_t cell, double t0, double t1) {
            CHECK(t1 >= t0);
            CHECK(cell < g.cell_count());
            CHECK(cell != prev);  // each step moves to a new voxel
            prev = cell;
            sum += t1 - t0;
            ++visits;
            return true;
        });
        // Both endpoints are inside: the pieces must add up to the length (round-off).
        CHECK(sum == test::rel(len, 1e-12));
        // A straight segment crosses at most |di|+|dj|+|dk|+1 voxels.
        const glm::dvec3 ua = g.to_voxel(a), ub = g.to_voxel(b);
        const int bound =
            int(std::fabs(std::floor(ua.x) - std::floor(ub.x)) + std::fabs(std::floor(ua.y) - std::floor(ub.y)) +
                std::fabs(std::floor(ua.z) - std::floor(ub.z))) +
            1;
        CHECK(visits <= bound);
    }
}

TEST_CASE("degenerate segments: zero length, outside, NaN") {
    const LightingMedium m = random_medium({4, 4, 4}, 1.0, {0, 0, 0}, 3);
    CHECK(transport::optical_depth(m, {1.5, 1.5, 1.5}, {1.5, 1.5, 1.5}) == 0.0);
    CHECK(transport::transmittance(m, {2, 2, 2}, {2, 2, 2}) == 1.0);
    // Entirely outside the grid (density 0 outside): no attenuation.
    CHECK(transport::optical_depth(m, {-5, -5, -5}, {-1, 9, -3}) == 0.0);
    CHECK(transport::optical_depth(m, {5, 0, 0}, {9, 4, 4}) == 0.0);
    // Ends exactly on the grid boundary from outside: touches but does not enter.
    CHECK(transport::optical_depth(m, {-3, 2.5, 2.5}, {0, 2.5, 2.5}) == 0.0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK(transport::optical_depth(m, {nan, 1, 1}, {2, 2, 2}) == 0.0);
    const double inf = std::numeric_limits<double>::infinity();
    CHECK(transport::optical_depth(m, {inf, 1, 1}, {2, 2, 2}) == 0.0);
}

TEST_CASE("axis-parallel rays, rays along faces and edges, endpoints on corners") {
    // Layered density: value depends on the voxel index only, so every answer is a short sum.
    core::GridGeometry g;
    g.dims = {4, 4, 4};
    g.voxel_size = 2.0;
    LightingMedium m;
    m.density = core::Grid3<float>(g);
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 4; ++j)
            for (int i = 0; i < 4; ++i) m.density.at(i, j, k) = float(0.1 * (i + 1) + 0.01 * j + 0.001 * k);
    m.optics.extinction = 1.0;
    const double h = 2.0;
    auto rho = [&](int i, int j, int k) { return double(m.density.at(i, j, k)); };
    // Along +x through voxel centres (j=1,k=2), from outside to outside.
    {
        double expect = 0.0;
        for (int i = 0; i < 4; ++i) expect += rho(i, 1, 2) * h;
        CHECK(transport::optical_depth(m, {-1, 3, 5}, {9, 3, 5}) == test::rel(expect, 1e-14));
        CHECK(transport::optical_depth(m, {9, 3, 5}, {-1, 3, 5}) == test::rel(expect, 1e-14));
    }
    // Along x exactly on the face y = 4 (between j = 1 and j = 2): documented convention,
    // the + side (j = 2) is sampled, whatever the direction of travel.
    {
        double expect = 0.0;
        for (int i = 0; i < 4; ++i) expect += rho(i, 2, 0) * h;
        CHECK(transport::optical_depth(m, {0, 4, 1}, {8, 4, 1}) == test::rel(expect, 1e-14));
        CHECK(transport::optical_depth(m, {8, 4, 1}, {0, 4, 1}) == test::rel(expect, 1e-14));
    }
    // Along z on the edge x = 2, y = 6 (four voxels meet): the + side in both x and y.
    {
        double expect = 0.0;
        for (int k = 0; k < 4; ++k) expect += rho(1, 3, k) * h;
        CHECK(transport::optical_depth(m, {2, 6, -1}, {2, 6, 9}) == test::rel(expect, 1e-14));
    }
    // On the grid's upper face x = 8: the last (inside) voxel layer is sampled.
    {
        double expect = 0.0;
        for (int j = 0; j < 4; ++j) expect += rho(3, j, 3) * h;
        CHECK(transport::optical_depth(m, {8, 0, 7}, {8, 8, 7}) == test::rel(expect, 1e-14));
    }
    // From a corner (2,2,2) to the corner (6,6,6): the diagonal crosses voxels (1,1,1) and
    // (2,2,2) only (it passes exactly through the shared corner (4,4,4)).
    {
        const double expect = (rho(1, 1, 1) + rho(2, 2, 2)) * h * std::sqrt(3.0);
        CHECK(transport::optical_depth(m, {2, 2, 2}, {6, 6, 6}) == test::rel(expect, 1e-13));
        CHECK(transport::optical_depth(m, {6, 6, 6}, {2, 2, 2}) == test::rel(expect, 1e-13));
    }
    // Starting on a face and moving away from it into the lower voxel.
    {
        const double expect = rho(0, 0, 0) * 1.5;
        CHECK(transport::optical_depth(m, {2, 1, 1}, {0.5, 1, 1}) == test::rel(expect, 1e-14));
    }
    // Segment from the grid's far corner to a point outside along the diagonal.
    {
        const double expect = rho(3, 3, 3) * h * std::sqrt(3.0);
        CHECK(transport::optical_depth(m, {6, 6, 6}, {20, 20, 20}) == test::rel(expect, 1e-13));
    }
}

TEST_CASE("optical depth to the sun goes backwards to the grid boundary") {
    const LightingMedium m = random_medium({5, 5, 5}, 1.0, {0, 0, 0}, 21);
    const glm::dvec3 x(2.3, 1.7, 0.6), d = glm::normalize(glm::dvec3(0.3, -0.2, -1.0));
    // Reference: the segment from x to a point far up-sun (outside the grid).
    const double ref = transport::optical_depth(m, x, x - 100.0 * d);
    CHECK(transport::optical_depth_to_sun(m, x, d) == test::rel(ref, 1e-14));
    CHECK(transport::optical_depth_to_sun(m, x, 5.0 * d) == test::rel(ref, 1e-14));
}
