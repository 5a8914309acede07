// Lattice-Boltzmann units: lattice densities -> fluence and S in the Monte Carlo units,
// checked on homogeneous problems with analytic answers (numeric).
#include "support/test_support.h"
#include "transport/detail/lb_solver.h"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

using namespace fulgur;
using namespace fulgur::transport;
using namespace fulgur::transport::lb;

TEST_CASE("units: a collimated beam in a pure absorber gives the exact voxel-averaged fluence") {
    // Sun along +x enters the x = 0 face: the lattice carries it along +x only, and the
    // voxel average of E exp(-sigma x) over voxel k is E exp(-sigma k h)(1 - exp(-sigma h))/(sigma h).
    const double h = 25.0, kappa = 0.02, rho = 0.6, E = 3.0;
    const core::GridGeometry geom{{20, 3, 3}, h, {-10, 0, 0}};
    LightingMedium m;
    m.density = core::Grid3<float>(geom, float(rho));
    m.optics = Medium{kappa, 0.0, 0.3};
    LbSources src;
    src.sun = DirectionalSource{glm::dvec3(1, 0, 0), E};
    LbSettings s;
    s.tolerance = 1e-12;
    const auto dirs = output_directions(6);
    const LbResult r = solve_lattice_boltzmann(m, src, dirs, s);
    const double sigma = kappa * double(rho);
    for (int k = 0; k < 20; ++k) {
        const double expect = E * std::exp(-sigma * k * h) * -std::expm1(-sigma * h) / (sigma * h);
        CHECK(double(r.fluence.at(k, 1, 1)) == test::rel(expect, 2e-6));  // float32 densities
        CHECK(r.source.direction(0)[geom.index(k, 1, 1)] == 0.0f);        // albedo 0: no scattering
    }
}

TEST_CASE("units: infinite medium with a uniform isotropic first-scattered source") {
    // Periodic lattice = infinite homogeneous medium. The emission sigma_t * 4 pi * S1 per
    // unit volume balances absorption: phi = 4 pi S1 / (1 - albedo), and isotropic radiance
    // stays isotropic for any g, so S_ms = albedo * phi / (4 pi) in every direction.
    for (double g : {0.0, 0.6, -0.8})
        for (LbCollision form : {LbCollision::Corrected, LbCollision::Published}) {
            const double h = 40.0, albedo = 0.8, S1v = 0.25;
            const core::GridGeometry geom{{6, 5, 4}, h, {0, 0, 0}};
            LightingMedium m;
            m.density = core::Grid3<float>(geom, 0.5f);
            m.optics = Medium{0.03, albedo, g};
            SourceField S1(geom, output_directions(1));
            std::fill(S1.data.begin(), S1.data.end(), float(S1v));
            LbSources src;
            src.first_scattered = &S1;
            LbSettings s;
            s.collision = form;
            s.tolerance = 1e-8;
            s.max_iterations = 5000;
            const auto dirs = output_directions(26);
            const LbResult r = solve(m, src, dirs, s, {Boundary::Periodic, Boundary::Periodic, Boundary::Periodic});
            const double phi = 4.0 * std::numbers::pi * S1v / (1.0 - albedo);
            const double S = albedo * phi / (4.0 * std::numbers::pi);
            INFO("g " << g << (form == LbCollision::Corrected ? " corrected" : " published"));
            if (form == LbCollision::Corrected || g == 0.0) {
                CHECK(r.converged);
                for (std::size_t i = 0; i < geom.cell_count(); ++i) {
                    CHECK(double(r.fluence.data[i]) ==
                          test::rel(phi, 1e-5));  // converged to the float32 floor (~1e-7 per step)
                    for (std::size_t md = 0; md < dirs.size(); ++md)
                        CHECK(double(r.source.direction(md)[i]) == test::rel(S, 1e-5));
                }
            } else {
                // The published form scatters isotropic light anisotropically and does not
                // conserve energy: the same problem comes out wrong.
                double worst = 0.0;
                for (std::size_t md = 0; md < dirs.size(); ++md)
                    worst = std::max(worst, std::fabs(double(r.source.direction(md)[0]) / S - 1.0));
                CHECK(worst > 0.02);
            }
        }
}

TEST_CASE("units: plane source decay length follows transport theory (physical mapping)") {
    // Plane source (periodic y, z) in a thick, weakly absorbing, isotropically scattering
    // medium: far from the source phi ~ exp(-nu sigma_t |x|), where nu solves the 18-direction
    // discrete-ordinates dispersion relation 1 = albedo * sum_j w_j / (1 - nu mu_j); as
    // sigma_t h -> 0 the lattice (per-class hop extinction) tends to it. The paper's mapping
    // (one sigma for both classes) gives nu = 0.220 here, 9% low (measured once, docs).
    const double albedo = 0.98, h = 1.0, sigma = 0.2;  // sigma_t h = 0.2
    auto disp = [&](double nu) {
        double s = 0.0;
        for (int q = 1; q < kQ; ++q) {
            const Velocity& c = kVelocity[std::size_t(q)];
            s += weight(q) / (1.0 - nu * double(c.x) / hop_length(q));
        }
        return albedo * s - 1.0;
    };
    double lo = 1e-6, hi = 0.99;
    for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (disp(mid) < 0.0 ? lo : hi) = mid;
    }
    const double nu = 0.5 * (lo + hi);
    const int N = 160;
    const core::GridGeometry geom{{N, 4, 4}, h, {0, 0, 0}};
    LightingMedium m;
    m.density = core::Grid3<float>(geom, 1.0f);
    m.optics = Medium{sigma, albedo, 0.0};
    SourceField S1(geom, output_directions(1));
    for (int z = 0; z < 4; ++z)
        for (int y = 0; y < 4; ++y) S1.data[geom.index(N / 2, y, z)] = 1.0f;
    LbSources src;
    src.first_scattered = &S1;
    LbSettings s;
    s.tolerance = 1e-7;
    s.max_iterations = 30000;
    const auto dirs = output_directions(1);
    const LbResult r = solve(m, src, dirs, s, {Boundary::Open, Boundary::Periodic, Boundary::Periodic});
    CHECK(r.converged);
    // Fit the decay between 15 and 55 sites from the source (about 1 to 3 diffusion
    // lengths, away from the source transient and from the open faces 80 sites away).
    const double phi_a = r.fluence.at(N / 2 + 15, 0, 0), phi_b = r.fluence.at(N / 2 + 55, 0, 0);
    const double measured = std::log(phi_a / phi_b) / (40.0 * h * sigma);
    MESSAGE("decay constant nu: lattice " << measured << ", discrete ordinates " << nu);
    // The lattice's O(sigma_t h) = 0.2 discretization: measured 3.4% from the discrete
    // ordinates' decay constant; 4% bounds it.
    CHECK(measured == test::rel(nu, 0.04));
}
