// Voxel-averaged single scattering: accuracy against an independent reference, the tolerance
// knob, hard inputs (empty and single-voxel clouds, source in a dense voxel and on a corner,
// albedo 1, very thick and very thin media), the sun, validation and determinism.
#include "support/test_support.h"
#include "transport/transport.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;
using test::homogeneous_box_integral;
using test::uniform_medium;

namespace {

struct Deviation {
    double max_rel = 0.0;
    int compared = 0;
};

// Compares S on a homogeneous 5x5x5 grid (h = 1, source inside) with the divergence-theorem
// reference for directions m in `ms`. Voxels whose reference is below 1e-9 of the largest
// are skipped: the reference sums face integrals of opposite signs, and its absolute accuracy
// (~1e-16 of the face terms) makes smaller values meaningless.
Deviation compare_homogeneous(double sigma, double g, glm::dvec3 xl, double tolerance, std::vector<int> ms) {
    const LightingMedium m = uniform_medium({5, 5, 5}, 1.0, {0, 0, 0}, 1.0f, {sigma, 1.0, g});
    const auto dirs = output_directions(26);
    SingleScatteringOptions o;
    o.tolerance = tolerance;
    const SourceField S = single_scattering(m, PointSource{xl, 1.0}, dirs, o);
    const core::GridGeometry& geo = m.density.geom;
    std::vector<double> ref(geo.cell_count() * ms.size());
    double ref_max = 0.0;
    for (std::size_t c = 0; c < geo.cell_count(); ++c) {
        const core::Int3 v = geo.unindex(c);
        const glm::dvec3 lo(v.x, v.y, v.z);
        for (std::size_t k = 0; k < ms.size(); ++k) {
            // albedo 1, I = 1, V = 1: S is the box integral itself.
            ref[c * ms.size() + k] = homogeneous_box_integral(lo, lo + 1.0, xl, sigma, g, dirs[std::size_t(ms[k])]);
            ref_max = std::max(ref_max, ref[c * ms.size() + k]);
        }
    }
    Deviation d;
    for (std::size_t c = 0; c < geo.cell_count(); ++c)
        for (std::size_t k = 0; k < ms.size(); ++k) {
            const double r = ref[c * ms.size() + k];
            if (!(r > 1e-9 * ref_max)) continue;
            const double v = S.data[std::size_t(ms[k]) * geo.cell_count() + c];
            d.max_rel = std::max(d.max_rel, std::fabs(v - r) / r);
            ++d.compared;
        }
    return d;
}

bool all_finite_nonnegative(const SourceField& f) {
    return std::all_of(f.data.begin(), f.data.end(), [](float v) { return std::isfinite(v) && v >= 0.0f; });
}

// Directions compared with the reference: +x, +z, -z and a cube corner.
const std::vector<int> kComparedDirections = {0, 4, 5, 20};

struct ReferenceCase {
    double sigma, g;
    glm::dvec3 xl;
    const char* what;
};

// Each case at the default tolerance 1e-3 against the reference: the bound 2e-3 allows the
// a-priori error model its factor-of-2 slack without hiding a real defect (a wrong breakpoint
// or Jacobian gives errors of 1e-2 and more, see docs/transport.md).
void check_default_tolerance(std::span<const ReferenceCase> cases) {
    for (const ReferenceCase& c : cases) {
        CAPTURE(c.what);
        const Deviation d = compare_homogeneous(c.sigma, c.g, c.xl, 1e-3, kComparedDirections);
        CHECK(d.compared > 300);
        CHECK(d.max_rel < 2e-3);
    }
}

}  // namespace

TEST_CASE("single scattering matches the divergence-theorem reference in homogeneous media") {
    const ReferenceCase cases[] = {
        {0.5, 0.6, {2.5, 2.5, 2.5}, "source at a voxel centre"},
        {0.5, 0.6, {3.0, 3.0, 3.0}, "source exactly on a voxel corner"},
        {0.5, 0.0, {2.5, 2.02, 2.5}, "source 0.02 voxel from a face"},
        {1.5, -0.5, {0.01, 0.02, 4.99}, "source next to a grid corner"},
        {5.0, 0.6, {2.3, 2.6, 2.5}, "optically thick voxels (sigma h = 5)"},
    };
    // Measured maximum over these cases: 4.3e-4.
    check_default_tolerance(cases);
    // The knob works: at tolerance 1e-5 the error falls below 1e-4 (measured 5.7e-5 worst).
    const Deviation tight = compare_homogeneous(0.5, 0.6, {3.0, 3.0, 3.0}, 1e-5, kComparedDirections);
    CHECK(tight.max_rel < 1e-4);
}

TEST_CASE("a peaked phase function keeps the tolerance: g from 0.6 to 0.99, forward and backward") {
    // Before the face rules were graded toward each direction's peak, the error at tolerance
    // 1e-3 grew with g from 4e-4 (g = 0.6, light at a voxel centre) to 5.6% at g = 0.9 and 87%
    // at 0.99 (in the light's own voxel and along the peak), and 4.7e-3 at g = 0.6 with the
    // light 0.02 voxel from a face. Measured now, worst over these lights for g = 0.3, +-0.6,
    // 0.8, +-0.9, 0.95 and +-0.99: 7.1e-4 at 1e-3 (g = -0.99, sigma h = 5) and 7.6e-6 at 1e-5;
    // the bounds are the test above's (the error model's factor-2 slack).
    const ReferenceCase cases[] = {
        {0.5, 0.6, {2.5, 2.02, 2.5}, "g 0.6, light 0.02 voxel from a face"},
        {0.5, 0.85, {2.3, 2.6, 2.45}, "g 0.85, light off-centre"},
        {0.5, 0.99, {2.5, 2.5, 2.5}, "g 0.99, light at a voxel centre"},
        {0.5, 0.99, {3.0, 3.0, 3.0}, "g 0.99, light on a voxel corner"},
        {0.5, 0.99, {2.5, 2.02, 2.5}, "g 0.99, light 0.02 voxel from a face"},
        {1.5, -0.95, {0.01, 0.02, 4.99}, "g -0.95, light next to a grid corner"},
        {5.0, 0.99, {2.3, 2.6, 2.5}, "g 0.99, optically thick voxels"},
    };
    check_default_tolerance(cases);
    // The knob still works at the peak: at 1e-5 (g = 0.99) 2.8e-6 and 2.2e-6 here (72% and 59%
    // before). Boxes along a peak that no split within the octree's depth brings within the
    // error model are integrated over their faces, graded: left to the deepest split's tensor
    // rule they erred by 1.7e-4 and 9.2e-4.
    for (const glm::dvec3 xl : {glm::dvec3(2.5, 2.5, 2.5), glm::dvec3(3.0, 3.0, 3.0)}) {
        const Deviation tight = compare_homogeneous(0.5, 0.99, xl, 1e-5, kComparedDirections);
        CHECK(tight.max_rel < 1e-4);
    }
}

TEST_CASE("empty cloud: S is the unattenuated albedo p I / r^2 voxel average") {
    // Density 0 everywhere: T = 1, and the reference with sigma = 0 is exact.
    LightingMedium m = uniform_medium({4, 4, 3}, 2.0, {-4, -4, 0}, 0.0f, {0.01, 0.9, 0.3});
    const auto dirs = output_directions(6);
    const glm::dvec3 xl(0.7, -1.1, 7.5);  // above the grid, outside it
    const SourceField S = single_scattering(m, PointSource{xl, 2.0}, dirs);
    REQUIRE(all_finite_nonnegative(S));
    const core::GridGeometry& g = m.density.geom;
    double worst = 0.0;
    for (std::size_t c = 0; c < g.cell_count(); ++c) {
        const core::Int3 v = g.unindex(c);
        const glm::dvec3 lo = g.origin + glm::dvec3(v.x, v.y, v.z) * g.voxel_size;
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            const double ref = 0.9 * 2.0 * homogeneous_box_integral(lo, lo + g.voxel_size, xl, 0.0, 0.3, dirs[k]) / 8.0;
            worst = std::max(worst, std::fabs(S.data[k * g.cell_count() + c] - ref) / ref);
        }
    }
    CHECK(worst < 2e-3);  // default tolerance 1e-3, as above
}

TEST_CASE("very thin medium: S tends to the empty-medium value") {
    // sigma h = 1e-9: S differs from the sigma = 0 value by ~1e-9 relative (attenuation),
    // far below float precision; 1e-6 bounds round-off of the float output.
    const LightingMedium thin = uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 1.0f, {1e-9, 0.8, 0.5});
    const LightingMedium empty = uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 0.0f, {1e-9, 0.8, 0.5});
    const auto dirs = output_directions(18);
    const glm::dvec3 xl(1.3, 2.2, 0.9);
    const SourceField a = single_scattering(thin, PointSource{xl, 1.0}, dirs);
    const SourceField b = single_scattering(empty, PointSource{xl, 1.0}, dirs);
    for (std::size_t i = 0; i < a.data.size(); ++i) CHECK(a.data[i] == test::rel(b.data[i], 1e-6));
}

TEST_CASE("point source inside a very dense voxel") {
    // sigma h = 100, source at the voxel centre: every ray is absorbed within the voxel, so
    // S_source(s) = albedo I / (V sigma) * integral p(s . w) (1 - e^{-sigma R(w)}) dw
    //             = albedo I / (V sigma) (1 - O(e^{-50})) for EVERY direction s (p normalized).
    const double h = 10.0, sigma = 10.0;
    LightingMedium m = uniform_medium({3, 3, 3}, h, {0, 0, 0}, 1.0f, {sigma, 0.7, 0.4});
    const auto dirs = output_directions(26);
    const SourceField S = single_scattering(m, PointSource{{15, 15, 15}, 3.0}, dirs);
    REQUIRE(all_finite_nonnegative(S));
    const std::size_t centre = m.density.geom.index(1, 1, 1);
    const double expect = 0.7 * 3.0 / (h * h * h * sigma);
    // g = 0.4: the angular integral of p is done by the face rule at the default tolerance
    // (1e-3); 2e-3 as in the homogeneous comparison.
    for (std::size_t k = 0; k < dirs.size(); ++k) CHECK(S.data[k * S.cells() + centre] == test::rel(expect, 2e-3));
    // Isotropic: the angular integral is trivial, only round-off of the float32 result and
    // the face rule's sum (measured 7.6e-6 relative; 1e-5 bounds it).
    m.optics.g = 0.0;
    const SourceField Si = single_scattering(m, PointSource{{15, 15, 15}, 3.0}, output_directions(1));
    CHECK(Si.data[centre] == test::rel(expect, 1e-5));
    // Neighbours see the light only through >= 50 optical depths of the source voxel:
    // tiny, finite, non-negative.
    for (std::size_t c = 0; c < m.density.geom.cell_count(); ++c)
        if (c != centre) CHECK(S.data[c] < 1e-15 * S.data[centre]);
}

TEST_CASE("point source exactly on a voxel corner: symmetric, finite and continuous") {
    const LightingMedium m = uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 0.8f, {1.0, 1.0, 0.0});
    const std::vector<glm::dvec3> dir = {{0, 0, 1}};
    const SourceField on = single_scattering(m, PointSource{{2, 2, 2}, 1.0}, dir);
    REQUIRE(all_finite_nonnegative(on));
    // The eight voxels sharing the corner are images of each other under reflections: equal
    // up to quadrature round-off (1e-6 relative).
    const double v0 = on.data[m.density.geom.index(1, 1, 1)];
    for (int k = 1; k <= 2; ++k)
        for (int j = 1; j <= 2; ++j)
            for (int i = 1; i <= 2; ++i) CHECK(on.data[m.density.geom.index(i, j, k)] == test::rel(v0, 1e-6));
    // Moving the source by 1e-7 voxel changes S by O(1e-7): 1e-4 relative (the quadrature
    // rule may switch between inside and outside forms, each accurate to the tolerance).
    const SourceField off = single_scattering(m, PointSource{{2 + 1e-7, 2 - 1e-7, 2 + 1e-7}, 1.0}, dir);
    for (std::size_t c = 0; c < on.data.size(); ++c) CHECK(off.data[c] == test::rel(on.data[c], 2e-3));
}

TEST_CASE("single-voxel cloud: finite, and it shadows the voxels behind it") {
    LightingMedium m = uniform_medium({5, 1, 1}, 1.0, {0, 0, 0}, 0.0f, {3.0, 1.0, 0.0});
    m.density.at(1, 0, 0) = 1.0f;  // sigma h = 3
    const std::vector<glm::dvec3> dir = {{1, 0, 0}};
    const glm::dvec3 xl(-2.0, 0.5, 0.5);  // on the row's axis, outside the grid
    const SourceField S = single_scattering(m, PointSource{xl, 1.0}, dir);
    REQUIRE(all_finite_nonnegative(S));
    LightingMedium clear = m;
    clear.density.at(1, 0, 0) = 0.0f;
    const SourceField C = single_scattering(clear, PointSource{xl, 1.0}, dir);
    // In front of the cloud voxel nothing changes; behind it the light crossed a chord of
    // optical depth between 3 (along the axis) and ~3.2 (the widest angle of the next voxel):
    // the ratio lies in [e^{-3.2}, e^{-3}].
    CHECK(S.data[0] == test::rel(C.data[0], 1e-6));
    for (int i = 2; i < 5; ++i) {
        const double ratio = S.data[std::size_t(i)] / C.data[std::size_t(i)];
        CHECK(ratio > std::exp(-3.2));
        CHECK(ratio < std::exp(-3.0) * 1.0001);
    }
}

TEST_CASE("albedo scales S linearly; albedo 1 is finite, albedo 0 gives 0") {
    LightingMedium m = test::synthetic_cloud({8, 8, 6}, 100.0, {0.01, 1.0, 0.6});
    const auto dirs = output_directions(6);
    const PointSource L{{30, -20, 150}, 1.0};
    const SourceField a1 = single_scattering(m, L, dirs);
    m.optics.albedo = 0.25;
    const SourceField aq = single_scattering(m, L, dirs);
    m.optics.albedo = 0.0;
    const SourceField a0 = single_scattering(m, L, dirs);
    REQUIRE(all_finite_nonnegative(a1));
    for (std::size_t i = 0; i < a1.data.size(); ++i) {
        CHECK(aq.data[i] == test::rel(0.25 * a1.data[i], 1e-6));  // float round-off
        CHECK(a0.data[i] == 0.0f);
    }
}

TEST_CASE("very thick medium (optical depth 1000 across): finite, monotone, analytic first layer") {
    // 10 layers of sigma h = 100 lit by the sun from above at normal incidence: the top layer's
    // voxel average is albedo p E (1 - e^{-100}) / 100 exactly; deeper layers are e^{-100}
    // smaller per layer (underflow to 0 in float), never NaN, never negative, never increasing.
    const LightingMedium m = uniform_medium({3, 3, 10}, 1.0, {0, 0, 0}, 1.0f, {100.0, 0.95, 0.7});
    const std::vector<glm::dvec3> dirs = {{0, 0, -1}, {1, 0, 0}};
    const SourceField S = single_scattering(m, DirectionalSource{{0, 0, -1}, 2.0}, dirs);
    REQUIRE(all_finite_nonnegative(S));
    const core::GridGeometry& g = m.density.geom;
    for (std::size_t k = 0; k < dirs.size(); ++k) {
        const double p = hg_phase(glm::dot(dirs[k], glm::dvec3(0, 0, -1)), 0.7);
        const double top = S.data[k * g.cell_count() + g.index(1, 1, 9)];
        CHECK(top == test::rel(0.95 * p * 2.0 / 100.0, 1e-6));  // float output
        for (int z = 9; z > 0; --z)
            CHECK(S.data[k * g.cell_count() + g.index(1, 1, z - 1)] <= S.data[k * g.cell_count() + g.index(1, 1, z)]);
    }
    // A point source just above the thick block: the voxels under it are lit, the ones at the
    // bottom are not; everything finite.
    const SourceField P = single_scattering(m, PointSource{{1.5, 1.5, 10.2}, 1.0}, dirs);
    REQUIRE(all_finite_nonnegative(P));
    CHECK(P.data[g.index(1, 1, 9)] > 0.0f);
    CHECK(P.data[g.index(1, 1, 0)] == 0.0f);
}

TEST_CASE("sun: exact in a homogeneous slab, consistent for oblique light") {
    // Normal incidence: voxel average = albedo p E e^{-sigma (top - z_hi)} (1 - e^{-sigma h})/(sigma h).
    const LightingMedium m = uniform_medium({4, 4, 6}, 2.0, {0, 0, 0}, 0.5f, {0.3, 0.9, 0.2});
    const std::vector<glm::dvec3> dirs = {{0, 0, -1}, {0, 1, 0}};
    SingleScatteringOptions o;
    o.tolerance = 1e-6;
    const SourceField S = single_scattering(m, DirectionalSource{{0, 0, -5}, 3.0}, dirs, o);
    const core::GridGeometry& g = m.density.geom;
    const double sigma = 0.15, h = 2.0;
    for (std::size_t k = 0; k < dirs.size(); ++k) {
        const double p = hg_phase(-dirs[k].z, 0.2);
        for (int z = 0; z < 6; ++z) {
            const double depth_above = (5 - z) * h;
            const double expect =
                0.9 * p * 3.0 * std::exp(-sigma * depth_above) * -std::expm1(-sigma * h) / (sigma * h);
            // tolerance 1e-6 requested; 1e-5 covers float output and the model's slack
            CHECK(S.data[k * g.cell_count() + g.index(2, 1, z)] == test::rel(expect, 1e-5));
        }
    }
    // Oblique sun in a heterogeneous cloud: finite, zero-density voxels lit, and the side
    // facing the sun brighter than the far side of the cloud.
    const LightingMedium c = test::synthetic_cloud({10, 10, 8}, 100.0, {0.02, 0.99, 0.5});
    const SourceField Sc = single_scattering(c, DirectionalSource{{0.6, 0.0, -0.8}, 1.0}, dirs);
    REQUIRE(all_finite_nonnegative(Sc));
    const core::GridGeometry& gc = c.density.geom;
    CHECK(Sc.data[gc.index(2, 5, 5)] > Sc.data[gc.index(7, 5, 5)]);
}

TEST_CASE("isotropic scattering: all output directions equal; one direction is enough") {
    const LightingMedium m = test::synthetic_cloud({8, 8, 6}, 100.0, {0.01, 0.9, 0.0});
    const auto dirs = output_directions(26);
    const SourceField S = single_scattering(m, PointSource{{10, 20, 50}, 1.0}, dirs);
    const SourceField S1 = single_scattering(m, PointSource{{10, 20, 50}, 1.0}, output_directions(1));
    for (std::size_t c = 0; c < S.cells(); ++c)
        for (std::size_t k = 0; k < dirs.size(); ++k) CHECK(S.data[k * S.cells() + c] == S1.data[c]);
}

TEST_CASE("uncollided fluence from the same pass equals 4 pi S of an isotropic unit-albedo medium") {
    // phi1 = (I / V) * integral T / r^2 over the voxel; S for g = 0, albedo 1 is phi1 / (4 pi).
    const LightingMedium m = test::synthetic_cloud({8, 8, 6}, 100.0, {0.01, 0.9, 0.7});
    LightingMedium iso = m;
    iso.optics.g = 0.0;
    iso.optics.albedo = 1.0;
    for (const PointSource L : {PointSource{{10, 20, 50}, 2.0}, PointSource{{-300, 40, -200}, 1.0}}) {
        core::Grid3<float> phi;
        SingleScatteringOptions o;
        o.uncollided_fluence = &phi;
        const SourceField aniso = single_scattering(m, L, output_directions(26), o);
        const SourceField ref = single_scattering(iso, L, output_directions(1));
        REQUIRE(phi.size() == ref.cells());
        // The anisotropic pass may pick other quadrature nodes (its error model includes the
        // phase function's variation). Over the grid they agree to the 1e-3 default tolerance
        // with 3x slack (measured: 1.8e-4 for the light inside the grid, 2.3e-3 for the one
        // outside it). Per voxel, the shadow edges of upstream voxels are outside the error
        // model (docs/transport.md): measured up to 0.9% and 6.6% in voxels at 0.4% and 4% of
        // the maximum; 10% bounds them.
        std::vector<float> expected(ref.cells());
        for (std::size_t c = 0; c < ref.cells(); ++c) expected[c] = float(4.0 * std::numbers::pi) * ref.data[c];
        CHECK(test::relative_l2(phi.data, expected) < 3e-3);
        for (std::size_t c = 0; c < ref.cells(); ++c) CHECK(double(phi.data[c]) == test::rel(expected[c], 0.10));
        CHECK(aniso.data.size() == 26 * ref.cells());
    }
}

TEST_CASE("results do not depend on the thread count; skipping far-empty voxels changes nothing else") {
    const LightingMedium m = test::synthetic_cloud({10, 10, 8}, 100.0, {0.01, 0.99, 0.6});
    const auto dirs = output_directions(26);
    const PointSource L{{120, -60, 180}, 1.0};
    const int saved = core::thread_count();
    core::set_thread_count(1);
    const SourceField a = single_scattering(m, L, dirs);
    core::set_thread_count(2);
    const SourceField b = single_scattering(m, L, dirs);
    SingleScatteringOptions o;
    o.skip_far_empty = true;
    const SourceField s = single_scattering(m, L, dirs, o);
    core::set_thread_count(saved);
    CHECK(a.data == b.data);  // bitwise: every voxel is computed independently
    const core::GridGeometry& g = m.density.geom;
    int skipped = 0;
    for (std::size_t c = 0; c < g.cell_count(); ++c) {
        const core::Int3 v = g.unindex(c);
        bool near_cloud = false;
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int x = v.x + dx, y = v.y + dy, z = v.z + dz;
                    if (x >= 0 && y >= 0 && z >= 0 && x < g.dims.x && y < g.dims.y && z < g.dims.z &&
                        m.density.at(x, y, z) > 0.0f)
                        near_cloud = true;
                }
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            const std::size_t i = k * g.cell_count() + c;
            if (near_cloud) {
                CHECK(s.data[i] == a.data[i]);
            } else {
                CHECK(s.data[i] == 0.0f);
                ++skipped;
            }
        }
    }
    CHECK(skipped > 0);
}

TEST_CASE("bad inputs are rejected with the field named") {
    LightingMedium m = uniform_medium({2, 2, 2}, 1.0, {0, 0, 0}, 0.5f, {1.0, 0.9, 0.0});
    const auto dirs = output_directions(1);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{nan, 0, 0}, 1.0}, dirs), doctest::Contains("light.position"),
                         core::Error);
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, -1.0}, dirs), doctest::Contains("light.intensity"),
                         core::Error);
    CHECK_THROWS_WITH_AS(single_scattering(m, DirectionalSource{{0, 0, 0}, 1.0}, dirs),
                         doctest::Contains("sun.direction"), core::Error);
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, 1.0}, std::vector<glm::dvec3>{}),
                         doctest::Contains("directions"), core::Error);
    SingleScatteringOptions o;
    o.tolerance = 0.0;
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, 1.0}, dirs, o), doctest::Contains("tolerance"),
                         core::Error);
    m.density.at(1, 0, 1) = 1.5f;
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, 1.0}, dirs),
                         doctest::Contains("medium.density[1,0,1]"), core::Error);
    m.density.at(1, 0, 1) = 0.5f;
    m.optics.extinction = nan;
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, 1.0}, dirs),
                         doctest::Contains("medium.extinction"), core::Error);
    m.optics.extinction = 1.0;
    m.optics.albedo = 1.2;
    CHECK_THROWS_WITH_AS(single_scattering(m, PointSource{{0, 0, 0}, 1.0}, dirs), doctest::Contains("medium.albedo"),
                         core::Error);
}

TEST_CASE("at the clamp, g = 0.999 and 0.9999: within the tolerance against a quadrature about the peak") {
    // The divergence-theorem cubature does not finish at these g (over 15 minutes); the second
    // reference integrates in spherical coordinates about each output direction. It agrees with
    // the first where both run (g = 0.99 along a peak). Measured: the solver within 3.6e-4 at
    // tolerance 1e-3 and 2e-5 at 1e-5 (the larger part of that in voxels off the peaks, where
    // the second reference's azimuths err by 1-2e-5 themselves); bounds as the tests above.
    const glm::dvec3 xl(2.5, 2.5, 2.5);
    const double sigma = 0.5;
    {
        const glm::dvec3 lo(2.0, 2.0, 3.0), s(0.0, 0.0, 1.0);
        const double a = homogeneous_box_integral(lo, lo + 1.0, xl, sigma, 0.99, s);
        const double b = test::peak_axis_box_integral(lo, lo + 1.0, xl, sigma, 0.99, s);
        CHECK(b == test::rel(a, 1e-6));  // measured (Python, the same scheme): 1e-8
    }
    const auto dirs = output_directions(26);
    const core::Int3 voxels[] = {{2, 2, 2}, {2, 2, 3}, {2, 2, 4}, {1, 3, 1}, {0, 4, 0}, {3, 2, 2}};
    for (const double g : {0.999, 0.9999}) {
        CAPTURE(g);
        const LightingMedium m = uniform_medium({5, 5, 5}, 1.0, {0, 0, 0}, 1.0f, {sigma, 1.0, g});
        std::vector<double> ref;
        for (const int k : {4, 20})
            for (const core::Int3 v : voxels) {
                const glm::dvec3 lo(v.x, v.y, v.z);
                ref.push_back(test::peak_axis_box_integral(lo, lo + 1.0, xl, sigma, g, dirs[std::size_t(k)]));
            }
        for (const auto& [tolerance, bound] : {std::pair{1e-3, 2e-3}, std::pair{1e-5, 1e-4}}) {
            CAPTURE(tolerance);
            SingleScatteringOptions o;
            o.tolerance = tolerance;
            const SourceField S = single_scattering(m, PointSource{xl, 1.0}, dirs, o);
            std::size_t i = 0;
            for (const int k : {4, 20})
                for (const core::Int3 v : voxels) {
                    CAPTURE(k);
                    CAPTURE(v.x + 10 * v.y + 100 * v.z);
                    const double value = S.data[std::size_t(k) * S.cells() + m.density.geom.index(v.x, v.y, v.z)];
                    CHECK(value == test::rel(ref[i++], bound));
                }
        }
    }
}

TEST_CASE("strongly peaked scattering, g from -0.999 to 0.999: finite, symmetric in g, fluence independent of g") {
    // |g| near 1 once split every box near the source to the deepest octree level (a bake's
    // plan at g = 0.99 did not finish in 5 minutes); the quadrature now bounds the phase
    // function's variation over the angles each box presents, so only boxes on a direction's
    // forward peak refine, and a box no split would bring within the model is integrated over
    // its faces, graded toward the peaks (accuracy: the test above).
    const LightingMedium base = uniform_medium({6, 6, 4}, 1.0, {0, 0, 0}, 1.0f, {0.5, 1.0, 0.0});
    const auto dirs = output_directions(26);
    std::vector<glm::dvec3> flipped;
    for (const glm::dvec3& d : dirs) flipped.push_back(-d);
    const glm::dvec3 xl(2.3, 2.6, -1.5);  // below the cloud, as most virtual lights are
    core::Grid3<float> phi0;
    SingleScatteringOptions o;
    o.uncollided_fluence = &phi0;
    (void)single_scattering(base, PointSource{xl, 1.0}, dirs, o);
    for (double g : {0.9, 0.99, 0.999}) {
        CAPTURE(g);
        LightingMedium fwd = base, bwd = base;
        fwd.optics.g = g;
        bwd.optics.g = -g;
        core::Grid3<float> phi;
        o.uncollided_fluence = &phi;
        const SourceField a = single_scattering(fwd, PointSource{xl, 1.0}, dirs, o);
        o.uncollided_fluence = nullptr;
        const SourceField b = single_scattering(bwd, PointSource{xl, 1.0}, flipped, o);
        REQUIRE(all_finite_nonnegative(a));
        REQUIRE(all_finite_nonnegative(b));
        // HG(theta; g) = HG(pi - theta; -g): S for g along s equals S for -g along -s. The two
        // runs choose their rules from the same slope bound, so they agree to float rounding
        // (1e-6 relative) rather than to the tolerance.
        for (std::size_t i = 0; i < a.data.size(); ++i) CHECK(a.data[i] == test::rel(b.data[i], 1e-6));
        // The uncollided fluence does not depend on g; the rules differ (finer where the phase
        // function is steep): per voxel up to 0.39% apart (the shadow edges of upstream voxels
        // are outside the 1e-3 error model, docs/transport.md); 5e-3 bounds it.
        for (std::size_t i = 0; i < phi.data.size(); ++i) CHECK(phi.data[i] == test::rel(phi0.data[i], 5e-3));
    }
}

TEST_CASE("single scattering's cost: a sample of voxels by distance, bounded by its time budget") {
    const LightingMedium m = uniform_medium({12, 12, 6}, 1.0, {0, 0, 0}, 1.0f, {0.5, 0.9, 0.9});
    const auto dirs = output_directions(26);
    SingleScatteringOptions o;
    o.tolerance = 1e-4;
    const PointSource src{{6.0, 6.0, 3.0}, 1.0};
    // Time to spare: every voxel measured (864 < the sample's 1024), the estimate their sum.
    const SingleScatteringCost all = single_scattering_cost(m, src, dirs, o, 1e9);
    CHECK(all.voxels == 864);
    CHECK(all.measured == 864);
    CHECK(all.complete);
    CHECK(all.seconds > 0.0);
    // No time: nothing measured, said so, and no figure invented.
    const SingleScatteringCost none = single_scattering_cost(m, src, dirs, o, -1.0);
    CHECK(none.voxels == 864);
    CHECK(none.measured == 0);
    CHECK_FALSE(none.complete);
    CHECK(none.seconds == 0.0);
    // Far-empty voxels are not computed by the solve, so not counted.
    LightingMedium hollow = m;
    for (int k = 0; k < 6; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 12; ++i) hollow.density.data[hollow.density.geom.index(i, j, k)] = i < 3 ? 1.0f : 0.0f;
    o.skip_far_empty = true;
    CHECK(single_scattering_cost(hollow, src, dirs, o, 1e9).voxels == 4 * 12 * 6);
    // Bad input named as the solve names it.
    o.tolerance = 0.0;
    CHECK_THROWS_WITH_AS(single_scattering_cost(m, src, dirs, o, 1.0), doctest::Contains("single_scattering.tolerance"),
                         core::Error);
}

TEST_CASE("the brute-force reference agrees with the divergence-theorem reference, the light's voxel included") {
    // sigma h = 1, g = 0.6, the light off-centre in the middle voxel: its own voxel (the 1/r^2
    // singularity, refined toward the light), a face and an edge neighbour, two far voxels.
    // Measured: 4.0e-6 in the light's voxel at 8^3 cells (8.0e-6 at 4^3: the cells left at the
    // depth limit), 1e-8 elsewhere; the bounds are 5x and 100x that, far below the 1e-3 the
    // quadrature is checked to with it below.
    const LightingMedium m = uniform_medium({5, 5, 5}, 1.0, {0, 0, 0}, 1.0f, {1.0, 1.0, 0.6});
    const auto dirs = output_directions(26);
    const glm::dvec3 xl(2.3, 2.6, 2.45);
    for (const core::Int3 v :
         {core::Int3{2, 2, 2}, core::Int3{3, 2, 2}, core::Int3{3, 3, 2}, core::Int3{4, 4, 4}, core::Int3{0, 2, 2}}) {
        CAPTURE(v.x);
        CAPTURE(v.y);
        CAPTURE(v.z);
        const bool own = v.x == 2 && v.y == 2 && v.z == 2;
        const auto r = single_scattering_reference(m, PointSource{xl, 1.0}, dirs, v, own ? 4 : 8);
        const glm::dvec3 lo(v.x, v.y, v.z);
        for (const int k : kComparedDirections) {
            const double exact = homogeneous_box_integral(lo, lo + 1.0, xl, 1.0, 0.6, dirs[std::size_t(k)]);
            CHECK(r[std::size_t(k)] == test::rel(exact, own ? 4e-5 : 1e-6));
        }
    }
    CHECK_THROWS_WITH_AS(single_scattering_reference(m, PointSource{xl, 1.0}, dirs, {5, 0, 0}, 8),
                         doctest::Contains("single_scattering_reference.voxel"), core::Error);
    CHECK_THROWS_WITH_AS(single_scattering_reference(m, PointSource{xl, 1.0}, dirs, {0, 0, 0}, 0),
                         doctest::Contains("single_scattering_reference.cells"), core::Error);
}

namespace {

// S against the brute-force reference (8^3 cells) at every third cloud voxel: the energy-weighted
// L1 error over the voxels and directions, and the largest relative error where the reference
// is above 1e-3 of its largest.
struct ReferenceErrors {
    double l1 = 0.0, largest = 0.0;
};
template <class Light>
ReferenceErrors against_reference(const LightingMedium& m, const SourceField& S, const Light& light,
                                  const std::vector<glm::dvec3>& dirs) {
    const core::GridGeometry& g = m.density.geom;
    std::vector<std::pair<std::size_t, std::vector<double>>> refs;
    double largest_ref = 0.0;
    for (std::size_t cell = 0; cell < g.cell_count(); cell += 3) {
        if (!(m.density.data[cell] > 0.0f)) continue;
        refs.emplace_back(cell, single_scattering_reference(m, light, dirs, g.unindex(cell), 8));
        for (const double v : refs.back().second) largest_ref = std::max(largest_ref, v);
    }
    REQUIRE(refs.size() >= 50);
    double l1n = 0.0, l1d = 0.0;
    ReferenceErrors e;
    for (const auto& [cell, r] : refs)
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            const double v = S.data[k * g.cell_count() + cell];
            l1n += std::fabs(v - r[k]);
            l1d += r[k];
            if (r[k] > 1e-3 * largest_ref) e.largest = std::max(e.largest, std::fabs(v - r[k]) / r[k]);
        }
    e.l1 = l1n / l1d;
    return e;
}

}  // namespace

TEST_CASE("shadow edges and rays grazing a cloud's base: within reach of the brute-force reference") {
    // A heterogeneous cloud (12x12x8 voxels of 250 m, sigma h up to 2.5, g = 0.6) lit by a light
    // level with its base beside it (the rays to the base voxels graze it), one under the base
    // (every ray to the cloud crosses the base at a slant) and one beyond its side (its light
    // crosses the whole cloud: shadow edges of every upstream voxel), every third cloud voxel
    // against the reference (8^3 cells: its own error, 8^3 against 16^3, is under 1e-3 in these
    // voxels). Errors: the energy-weighted L1 over the voxels and directions, and the largest
    // relative error where S is above 1e-3 of the largest.
    // Measured at tolerance 1e-3 (L1 / largest): level 1.3e-4 / 0.08%, under 3.6e-4 / 1.3%,
    // beside 2.0e-3 / 5.1%. Before the tensor rules took three nodes per axis wherever a ray
    // meets density (two nodes hide a kink from the check) and checked the sub-boxes that hold
    // much of their voxel's light below two levels: 1.9e-4 / 0.4%, 1.2e-3 / 8.9%, 7.4e-3 / 20%.
    // The bounds are 1.5x the measured values (the quadrature's choices depend on
    // floating-point comparisons an optimizer may reorder); the largest error of the light
    // beside the cloud is the shadow edges' the checks still let through (docs/transport.md).
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.01, 1.0, 0.6});
    const auto dirs = output_directions(26);
    struct Case {
        glm::dvec3 light;
        double l1, largest;
        const char* what;
    };
    for (const Case& c : {Case{{-1350.0, 110.0, 500.0}, 2e-4, 1.2e-3, "level with the base"},
                          Case{{-1350.0, 110.0, 380.0}, 5.4e-4, 0.02, "under the base"},
                          Case{{-2900.0, 300.0, 1700.0}, 3e-3, 0.077, "beyond the side"}}) {
        CAPTURE(c.what);
        SingleScatteringOptions o;
        o.tolerance = 1e-3;
        const SourceField S = single_scattering(m, PointSource{c.light, 1.0}, dirs, o);
        const ReferenceErrors e = against_reference(m, S, PointSource{c.light, 1.0}, dirs);
        CHECK(e.l1 < c.l1);
        CHECK(e.largest < c.largest);
    }
}

TEST_CASE("the sun over a heterogeneous cloud: within reach of the brute-force reference, high to grazing") {
    // The cloud of the test above lit by the sun at 60, 25 and 5 degrees of elevation (the
    // lowest crosses the whole cloud: shadow edges of every upstream voxel on most faces), every
    // third cloud voxel against the reference (8^3 cells), at the scenes' tolerance 1e-2 and at
    // 1e-3. Errors as above: L1 over voxels and directions, the largest where S > 1e-3 of the largest.
    // Measured (L1 / largest), 60 / 25 / 5 degrees: at 1e-2 1.9e-4 / 0.16%, 7.6e-4 / 0.12%,
    // 3.1e-4 / 0.15%; at 1e-3 9.0e-5 / 0.04%, 6.8e-5 / 0.06%, 6.1e-5 / 0.09% (there the reference's
    // own error, 8^3 cells, is of the same order). Before the entry faces were refined (a tensor
    // rule checked by the linear fit of its nodes' optical depths, a fixed face rule where that
    // failed), at 1e-2: 5.7e-3 / 3.2%, 3.5e-3 / 1.8%, 1.6e-2 / 7.4%; at 1e-3 3.2e-3 / 1.2%, 1.6e-3 /
    // 1.1%, 1.1e-2 / 5.5%: it fails every bound. The bounds are 1.5x the measured values (the
    // refinement's choices depend on floating-point comparisons an optimizer may reorder).
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.01, 1.0, 0.6});
    const auto dirs = output_directions(26);
    struct Case {
        double elevation, tolerance, l1, largest;
    };
    for (const Case& c :
         {Case{60.0, 1e-2, 2.8e-4, 2.4e-3}, Case{25.0, 1e-2, 1.14e-3, 1.9e-3}, Case{5.0, 1e-2, 4.7e-4, 2.3e-3},
          Case{60.0, 1e-3, 1.35e-4, 6.2e-4}, Case{25.0, 1e-3, 1.0e-4, 8.5e-4}, Case{5.0, 1e-3, 9.2e-5, 1.4e-3}}) {
        CAPTURE(c.elevation);
        CAPTURE(c.tolerance);
        const double e = c.elevation * std::numbers::pi / 180.0, az = 30.0 * std::numbers::pi / 180.0;
        const DirectionalSource sun{-glm::dvec3(std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)),
                                    1.0};
        SingleScatteringOptions o;
        o.tolerance = c.tolerance;
        const SourceField S = single_scattering(m, sun, dirs, o);
        const ReferenceErrors err = against_reference(m, S, sun, dirs);
        CHECK(err.l1 < c.l1);
        CHECK(err.largest < c.largest);
    }
}

TEST_CASE("the brute-force reference for the sun: a homogeneous slab's exact voxel mean") {
    // sigma h = 1 on a 5x5x5 grid, the sun 30 degrees from the zenith: a voxel at the bottom
    // whose rays toward the sun leave through the top (they shift 2.9 voxels toward +x over the
    // grid's 5, from x in [1, 2]: within the grid) sees
    // tau = sigma (top - z) / mu, whose voxel mean is mu (e^{-sigma (top - z1) / mu} -
    // e^{-sigma (top - z0) / mu}) / (sigma h). A 3-point rule per cell on e^{-x / mu} over a
    // cell of optical depth 1 / (8 mu) errs by ~1e-12: the bound is rounding's.
    const LightingMedium m = uniform_medium({5, 5, 5}, 1.0, {0, 0, 0}, 1.0f, {1.0, 0.8, 0.6});
    const double mu = std::cos(30.0 * std::numbers::pi / 180.0);
    const DirectionalSource sun{{-std::sqrt(1.0 - mu * mu), 0.0, -mu}, 2.0};
    const std::vector<glm::dvec3> dirs = {{0, 0, 1}, {1, 0, 0}};
    const auto r = single_scattering_reference(m, sun, dirs, {1, 2, 0}, 8);
    const double mean_t = mu * (std::exp(-(5.0 - 1.0) / mu) - std::exp(-5.0 / mu));
    for (std::size_t k = 0; k < dirs.size(); ++k)
        CHECK(r[k] == test::rel(0.8 * 2.0 * hg_phase(glm::dot(dirs[k], sun.direction), 0.6) * mean_t, 1e-9));
}
