// The sun through the lattice (numeric): the Appendix A decomposition of a light direction,
// the boundary injection's power, and the diffuse reflectance of a homogeneous half-space
// lit at normal incidence against the exact values the Monte Carlo oracle test carries
// (test_monte_carlo.cpp, "semi-infinite slab"), both for Geist's boundary injection (every
// order on the lattice) and for exact single scattering + the lattice for orders >= 2.
#include "support/test_support.h"
#include "transport/detail/lb_solver.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <numbers>

using namespace fulgur;
using namespace fulgur::transport;
using namespace fulgur::transport::lb;

TEST_CASE("Appendix A: forward directions only, unit power, first moment close to the light") {
    // A sweep over the sphere: the decomposition puts all its power on lattice directions
    // within 90 degrees of L, sums to 1, and its mean direction sum_q f_q n_q is near L (the
    // greedy Gram-Schmidt-like procedure is not moment-preserving: measured worst below).
    double worst_deg = 0.0, worst_power = 0.0;
    for (int a = 0; a < 60; ++a)
        for (int b = 0; b < 30; ++b) {
            const double phi = 2.0 * std::numbers::pi * (a + 0.37) / 60.0, ct = -1.0 + 2.0 * (b + 0.5) / 30.0;
            const double st = std::sqrt(1.0 - ct * ct);
            const glm::dvec3 L(st * std::cos(phi), st * std::sin(phi), ct);
            const auto f = resolve_direction(L);
            glm::dvec3 mean(0.0);
            double power = 0.0;
            for (int q = 1; q < kQ; ++q) {
                const Velocity& c = kVelocity[std::size_t(q)];
                const glm::dvec3 n = glm::dvec3(c.x, c.y, c.z) / hop_length(q);
                if (f[std::size_t(q)] > 0.0) REQUIRE(glm::dot(n, L) > 0.0);
                mean += f[std::size_t(q)] * n;
                power += f[std::size_t(q)];
            }
            worst_power = std::max(worst_power, std::fabs(power - 1.0));
            worst_deg = std::max(
                worst_deg, std::acos(std::min(1.0, glm::dot(glm::normalize(mean), L))) * 180.0 / std::numbers::pi);
        }
    MESSAGE("Appendix A over 1800 directions: worst angle between the decomposition's mean direction and L "
            << worst_deg << " deg, worst power error " << worst_power);
    CHECK(worst_power < 1e-12);  // unit intensity, rounding only
    // The greedy procedure stops once the dot products used exceed the unit intensity, so
    // for some directions its mean leans toward the first (nearest) lattice direction:
    // measured 27.1 degrees at worst (docs/sky.md); the bound guards against a regression.
    CHECK(worst_deg < 30.0);
}

TEST_CASE("boundary injection: the power entering per step is E times the grid's projected area") {
    const LightingMedium m = test::uniform_medium({7, 5, 4}, 30.0, {0, 0, 0}, 0.4f, {0.01, 0.9, 0.5});
    const glm::dvec3 ext = m.density.geom.extent();
    for (const glm::dvec3 L : {glm::dvec3(0, 0, -1), glm::dvec3(0.4, -0.3, -0.8), glm::dvec3(-1, 2, 0.5)}) {
        const glm::dvec3 d = glm::normalize(L);
        LbSources src;
        src.sun = DirectionalSource{L, 2.5};
        LbSettings s;
        s.max_iterations = 4;
        const LbResult r = solve_lattice_boltzmann(m, src, output_directions(1), s);
        const double area =
            ext.y * ext.z * std::fabs(d.x) + ext.x * ext.z * std::fabs(d.y) + ext.x * ext.y * std::fabs(d.z);
        CHECK(r.injected_per_step == test::rel(2.5 * area, 1e-6));  // float32 link values
    }
}

namespace {

struct Reflectance {
    double geist = 0.0, hybrid = 0.0;
    int steps_geist = 0, steps_hybrid = 0;
};

// A homogeneous slab periodic in x and y (an infinite slab), `depth` voxels of hop optical
// depth `tau_h`, isotropic scattering, lit from above at normal incidence. Reflectance:
// escaped power per step in the steady state over the incident power E A.
Reflectance slab_reflectance(double albedo, double tau_h, int depth) {
    const double h = 10.0, E = 1.0;
    const LightingMedium m = test::uniform_medium({4, 4, depth}, h, {0, 0, 0}, 1.0f, {tau_h / h, albedo, 0.0});
    const double incident = E * 16.0 * h * h;
    const std::array<Boundary, 3> slab{Boundary::Periodic, Boundary::Periodic, Boundary::Open};
    LbSettings s;
    s.tolerance = 1e-7;
    s.max_iterations = 40000;
    const auto dirs = output_directions(1);
    Reflectance out;
    LbSources sun;
    sun.sun = DirectionalSource{{0, 0, -1}, E};
    const LbResult g = solve(m, sun, dirs, s, slab);
    REQUIRE(g.converged);
    out.geist = g.escaped_last_step / incident;
    out.steps_geist = g.iterations;
    // Exact single scattering is uniform across x and y at normal incidence (no light enters
    // through the side faces), so the periodic lattice may be fed with it.
    SingleScatteringOptions so;
    core::Grid3<float> phi1;
    so.uncollided_fluence = &phi1;
    const SourceField s1 = single_scattering(m, DirectionalSource{{0, 0, -1}, E}, dirs, so);
    LbSources first;
    first.first_scattered = &s1;
    first.first_scattered_fluence = &phi1;
    const LbResult hy = solve(m, first, dirs, s, slab);
    REQUIRE(hy.converged);
    out.hybrid = hy.escaped_last_step / incident;
    out.steps_hybrid = hy.iterations;
    return out;
}

}  // namespace

TEST_CASE("half-space reflectance at normal incidence: Geist's injection and the hybrid against the exact values") {
    struct Case {
        double albedo, exact;
        int depth;  // voxels of hop optical depth 0.5: >= 10 diffusion lengths, the bottom escapes nothing
    };
    for (const Case c : {Case{0.8, 0.28525, 60}, Case{0.9, 0.41495, 80}, Case{0.99, 0.75272, 160}}) {
        const Reflectance r = slab_reflectance(c.albedo, 0.5, c.depth);
        std::printf(
            "half-space albedo %.2f: exact %.5f, Geist injection %.5f (%+.1f%%, %d steps), hybrid %.5f "
            "(%+.1f%%, %d steps)\n",
            c.albedo, c.exact, r.geist, 100.0 * (r.geist / c.exact - 1.0), r.steps_geist, r.hybrid,
            100.0 * (r.hybrid / c.exact - 1.0), r.steps_hybrid);
        // Measured: hybrid -7.8%, -4.8%, -1.1% (half the lattice's isotropic emission runs
        // parallel to the surface, c_z = 0, so first-scattered light near the top escapes
        // less than in the continuum: the error shrinks as multiple scattering dominates);
        // Geist's injection +1.8%, +2.5%, +1.5%. The bounds keep those with a margin.
        CHECK(r.hybrid == test::rel(c.exact, 0.10));
        CHECK(r.geist == test::rel(c.exact, 0.04));
    }
}
