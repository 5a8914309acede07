#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace fulgur::core;

namespace {
GridGeometry geom(int nx, int ny, int nz, double h = 2.0, glm::dvec3 o = {-3.0, 1.0, 5.0}) {
    GridGeometry g;
    g.dims = {nx, ny, nz};
    g.voxel_size = h;
    g.origin = o;
    return g;
}
}  // namespace

TEST_CASE("grid index and unindex are inverse, x fastest") {
    const GridGeometry g = geom(5, 3, 4);
    CHECK(g.index(1, 0, 0) == 1);
    CHECK(g.index(0, 1, 0) == 5);
    CHECK(g.index(0, 0, 1) == 15);
    for (std::size_t i = 0; i < g.cell_count(); ++i) {
        const Int3 c = g.unindex(i);
        CHECK(g.index(c.x, c.y, c.z) == i);
    }
}

TEST_CASE("voxel centres and containment use the documented convention") {
    const GridGeometry g = geom(4, 4, 4);
    const glm::dvec3 c = g.centre(0, 0, 0);
    CHECK(c.x == doctest::Approx(-2.0));
    CHECK(c.z == doctest::Approx(6.0));
    CHECK(g.contains(g.origin));
    CHECK_FALSE(g.contains(g.upper()));  // upper bound is exclusive
    CHECK(g.to_voxel(c).x == doctest::Approx(0.5));
}

TEST_CASE("trilinear sampling reproduces a linear field exactly inside the centre hull") {
    Grid3<float> grid(geom(6, 5, 4));
    auto f = [](glm::dvec3 p) { return 0.5 + 0.25 * p.x - 0.125 * p.y + 0.0625 * p.z; };
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 5; ++j)
            for (int i = 0; i < 6; ++i) grid.at(i, j, k) = float(f(grid.geom.centre(i, j, k)));
    const glm::dvec3 lo = grid.geom.centre(0, 0, 0), hi = grid.geom.centre(5, 4, 3);
    for (double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
        const glm::dvec3 p = lo + t * (hi - lo);
        // float storage: values near 1 carry ~1e-7 relative rounding
        CHECK(grid.sample(p) == fulgur::test::rel(f(p), 1e-6));
    }
}

TEST_CASE("trilinear sampling clamps outside the grid and survives NaN positions") {
    Grid3<float> grid(geom(2, 2, 2), 0.0f);
    grid.at(0, 0, 0) = 1.0f;
    CHECK(grid.sample(glm::dvec3(-1e9)) == 1.0f);  // clamped to the first centre
    CHECK(grid.sample(glm::dvec3(1e9)) == 0.0f);
    const float v = grid.sample(glm::dvec3(std::nan(""), 0.0, 0.0));
    CHECK(std::isfinite(v));
}

TEST_CASE("downsample preserves the mean when dimensions divide") {
    Grid3<float> grid(geom(8, 4, 6));
    Rng rng(3);
    double sum = 0.0;
    for (float& v : grid.data) sum += (v = rng.uniform_float());
    const Grid3<float> d = downsample(grid, 2);
    CHECK(d.dims() == Int3{4, 2, 3});
    CHECK(d.geom.voxel_size == 4.0);
    double dsum = 0.0;
    for (float v : d.data) dsum += v;
    // each coarse value is a float-rounded mean of 8 values: relative error ~1e-7 each
    CHECK(dsum * 8.0 == fulgur::test::rel(sum, 1e-6));
}

TEST_CASE("resample_trilinear equals the point-wise sample at every destination centre") {
    // A coarse field and destinations finer by 3 (the per-strike transport grid's relation to
    // the lighting grid, with a trailing partial block), coarser, shifted and partly outside.
    Grid3<float> coarse(geom(7, 5, 4, 3.0));
    Rng rng(11);
    for (float& v : coarse.data) v = 10.0f * rng.uniform_float();
    for (const GridGeometry& to :
         {geom(20, 15, 11, 1.0), geom(3, 2, 2, 6.5, {-9.0, 0.0, 2.0}), geom(9, 8, 1, 2.5, {-20.0, -4.0, 30.0})}) {
        std::vector<float> out(to.cell_count());
        resample_trilinear(coarse.geom, coarse.data, to, out);
        double worst = 0.0;
        for (int k = 0; k < to.dims.z; ++k)
            for (int j = 0; j < to.dims.y; ++j)
                for (int i = 0; i < to.dims.x; ++i)
                    worst = std::max(
                        worst, std::abs(double(out[to.index(i, j, k)]) - double(coarse.sample(to.centre(i, j, k)))));
        // Both interpolate in double and round once to float; the axes' order differs, so
        // they agree to the last float bit of values <= 10 (ulp 9.5e-7).
        CHECK(worst <= 1e-6);
    }
}

TEST_CASE("validate_geometry names the problem") {
    GridGeometry g = geom(4, 4, 4);
    CHECK_NOTHROW(validate_geometry(g, "test"));
    g.voxel_size = -1.0;
    CHECK_THROWS_WITH_AS(validate_geometry(g, "cloud.voxel_size"), doctest::Contains("cloud.voxel_size"), Error);
    g = geom(0, 4, 4);
    CHECK_THROWS_AS(validate_geometry(g, "x"), Error);
}

TEST_CASE("compensated sum keeps small terms a naive sum loses") {
    CompensatedSum s;
    double naive = 0.0;
    s.add(1e16);
    naive += 1e16;
    for (int i = 0; i < 1000; ++i) {
        s.add(1.0);
        naive += 1.0;
    }
    s.add(-1e16);
    naive -= 1e16;
    CHECK(s.value() == 1000.0);
    CHECK(naive != 1000.0);
}
