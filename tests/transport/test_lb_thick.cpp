// Thick-voxel correction of the lattice coefficients (LbThickVoxels::DiffusionMatched):
// the lattice diffusion coefficient formula, stability, energy, and convergence to the
// diffusion limit as voxels get optically thicker.
#include "lb_test_util.h"
#include "transport/lb_solver.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

using namespace fulgur;
using namespace fulgur::transport;
using namespace fulgur::transport::lb;

TEST_CASE("explore k") {
    for (double g : {0.0, 0.6, -0.6, 0.99, -0.99})
        for (double albedo : {1.0, 0.99, 0.5}) {
            const DiscretePhase ph = corrected_phase(g);
            const ThickVoxelModel tm = make_thick_voxel_model(LbThickVoxels::DiffusionMatched, ph, albedo);
            MESSAGE("g " << g << " albedo " << albedo << " pmin " << tm.p_min << " emax " << tm.e_max << " M " << tm.first_moment[0][0] << " "
                         << tm.first_moment[0][1] << " " << tm.first_moment[1][0] << " " << tm.first_moment[1][1]);
            for (double tau : {1e-4, 0.01, 0.1, 0.3, 1.0, 2.0, 3.0, 10.0, 100.0}) {
                const Medium m{tau, albedo, g};
                const SiteCoefficients c0 = site_coefficients(m, 1.0, 1.0);
                const SiteCoefficients c1 = site_coefficients(m, 1.0, 1.0, tm);
                MESSAGE("  tau " << tau << " chord " << c0.extinction[1] << "/" << c0.extinction[2] << " matched "
                                 << c1.extinction[1] << "/" << c1.extinction[2] << " k " << c1.extinction[1] / c0.extinction[1]);
            }
        }
}
