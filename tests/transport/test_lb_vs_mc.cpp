// Lattice-Boltzmann (exact single scattering + LB orders >= 2) against the Monte Carlo
// reference on a small cloud lit by a point light below the grid (numeric). A pinned
// regression of the comparison `fulgur-study lb-vs-mc` makes on the default storm
// (docs/lattice-boltzmann.md, "LB against Monte Carlo"). Monte Carlo results depend only on
// (seed, paths, batches), so the errors below are deterministic up to floating-point
// differences between compilers; the bounds are the values measured when the test was
// written plus a margin, so a loss of accuracy shows up here.
#include "support/test_support.h"
#include "transport/transport.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

// A 14^3 grid of 100 m voxels with a smooth blob (density 1 - (r/R)^2, R = 5.5 voxels) in
// its middle: axis-hop optical depth sigma_t h <= 0.4 (voxels thinner than a mean free
// path), optical diameter ~2.9, so orders 2..4 dominate the multiple part.
LightingMedium blob(double albedo, double extinction = 0.004) {
    const int n = 14;
    const double h = 100.0;
    core::GridGeometry g;
    g.dims = {n, n, n};
    g.voxel_size = h;
    g.origin = {-0.5 * n * h, -0.5 * n * h, 0.0};
    LightingMedium m;
    m.density = core::Grid3<float>(g, 0.0f);
    m.optics = Medium{extinction, albedo, 0.6};
    const double R = 5.5;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const double x = i + 0.5 - 0.5 * n, y = j + 0.5 - 0.5 * n, z = k + 0.5 - 0.5 * n;
                const double r2 = (x * x + y * y + z * z) / (R * R);
                if (r2 < 1.0) m.density.at(i, j, k) = float(1.0 - r2);
            }
    return m;
}

struct Errors {
    double total = 0.0, multiple = 0.0;              // relative L2 over cloud voxels, 26 directions
    double floor_total = 0.0, floor_multiple = 0.0;  // Monte Carlo noise floor ||SE|| / ||ref||
    double ratio_multiple = 0.0;                     // sum of LB multiple S / sum of MC multiple S
};

Errors compare(const LightingMedium& m, const SourceField& S1, const SourceField& lb, const MonteCarloResult& mc) {
    const std::size_t n = S1.cells(), M = S1.directions.size();
    core::RelativeL2 total, multiple;
    double ft = 0, fm = 0, sum_lb = 0, sum_mc = 0;
    for (std::size_t k = 0; k < M; ++k)
        for (std::size_t c = 0; c < n; ++c) {
            if (!(m.density.data[c] > 0.0f)) continue;  // cloud voxels: density > 0
            const std::size_t i = k * n + c;
            const double ref_m = mc.multiple.data[i], ref_t = ref_m + mc.single.data[i];
            const double got_m = lb.data[i], got_t = got_m + S1.data[i];
            total.add(got_t, ref_t);
            multiple.add(got_m, ref_m);
            const double s1 = mc.single_se.data[i], sm = mc.multiple_se.data[i];
            ft += s1 * s1 + sm * sm;
            fm += sm * sm;
            sum_lb += got_m;
            sum_mc += ref_m;
        }
    return {total.value(), multiple.value(), std::sqrt(ft) / total.reference_norm(),
            std::sqrt(fm) / multiple.reference_norm(), sum_lb / sum_mc};
}

// What both cases compare the lattice against, for one light and 26 directions: the
// first-scattered source S1 with, from the same quadrature, the uncollided fluence phi1 the
// lattice takes with it; and the Monte Carlo reference (mc.energy.scattered_mean() is the
// power the lattice must be fed).
struct Reference {
    std::vector<glm::dvec3> dirs;
    core::Grid3<float> phi1;
    SourceField S1;
    MonteCarloResult mc;
    // The lattice's input; it points into this object.
    LbSources sources() const {
        LbSources src;
        src.first_scattered = &S1;
        src.first_scattered_fluence = &phi1;
        return src;
    }
};

Reference reference(const LightingMedium& m, const PointSource& light, std::uint64_t paths, std::uint64_t seed) {
    Reference r;
    r.dirs = output_directions(26);
    SingleScatteringOptions o;
    o.uncollided_fluence = &r.phi1;
    r.S1 = single_scattering(m, light, r.dirs, o);
    MonteCarloOptions mo;
    mo.paths = paths;
    mo.seed = seed;
    r.mc = monte_carlo(m, light, r.dirs, mo);
    return r;
}

double sum_of(const core::Grid3<float>& f) {
    double s = 0.0;
    for (float v : f.data) s += double(v);
    return s;
}

}  // namespace

TEST_CASE("LB vs Monte Carlo: small blob, point light below the grid") {
    const LightingMedium m = blob(0.95);
    const PointSource light{{37.0, -23.0, -200.0}, 1.0};  // outside the grid, 200 m below it
    // ~1 s on 2 cores; noise floor 0.8% (total), 2.1% (multiple)
    const Reference ref = reference(m, light, 8'000'000, 11);
    const auto& dirs = ref.dirs;
    const SourceField& S1 = ref.S1;
    const MonteCarloResult& mc = ref.mc;
    const LbSources src = ref.sources();
    LbSettings ls;
    ls.tolerance = 1e-6;
    ls.thick_voxels = LbThickVoxels::Saturate;
    const LbResult phys = solve_lattice_boltzmann(m, src, dirs, ls);
    ls.absorption = LbAbsorption::Conservative;
    const LbResult cons = solve_lattice_boltzmann(m, src, dirs, ls);
    REQUIRE(phys.converged);
    REQUIRE(cons.converged);
    ls.absorption = LbAbsorption::Physical;
    ls.thick_voxels = LbThickVoxels::DiffusionMatched;
    const LbResult matched = solve_lattice_boltzmann(m, src, dirs, ls);
    REQUIRE(matched.converged);
    {
        const Errors em = compare(m, S1, matched.source, mc);
        MESSAGE("physical, diffusion_matched: relative L2 total " << em.total << ", multiple " << em.multiple
                                                                  << " (LB/MC sum " << em.ratio_multiple << ")");
        // Thin voxels (hop optical depth <= 0.4): the matched mapping is within O(tau) of the
        // chord one (k - 1 <= 0.2 here): measured 0.0659 / 0.245 (LB/MC sum 1.02 instead of
        // 0.95; the shape error of the 18 directions dominates either way). Bounds as above:
        // total + 25%, multiple + 2 noise floors.
        CHECK(em.total < 0.085);
        CHECK(em.multiple < 0.29);
    }

    const Errors e = compare(m, S1, phys.source, mc);
    MESSAGE("physical: relative L2 total " << e.total << ", multiple " << e.multiple << " (LB/MC sum "
                                           << e.ratio_multiple << "); MC noise floor total " << e.floor_total
                                           << ", multiple " << e.floor_multiple << "; " << phys.iterations << " steps");
    // The MC noise is well below what is being bounded (else the bounds would test noise).
    CHECK(e.floor_total < 0.015);
    CHECK(e.floor_multiple < 0.03);
    // Measured 0.064 (dominated by the multiple part: S1 itself matches MC's order 1 to the
    // noise). Bound 0.08: a 25% margin, ~2 noise floors; a real loss of accuracy of the
    // lattice part by more than ~1/10 of its error fails here.
    CHECK(e.total < 0.08);
    // Measured 0.238 with the LB/MC sum at 0.95: in this thin blob the error is a shape
    // error, LB too low in the lower half and too high at the top (1.4-1.8x in the two top
    // layers); halving the voxel size (28^3, measured once) left it at 0.249, so it is not
    // the lattice's spatial resolution but its 18 directions (docs/lattice-boltzmann.md).
    // Bound 0.28: measured + 2 noise floors of the multiple part.
    CHECK(e.multiple < 0.28);

    // The power the lattice emits (sigma_s phi1 h^3 summed) is the power Monte Carlo scatters
    // at least once: measured 0.6949 vs 0.6932 +- 0.0010 W (0.24%). Bound 0.5%: 3-4 MC
    // standard errors plus the 1e-3 quadrature tolerance of single_scattering.
    CHECK(phys.injected_per_step == test::rel(mc.energy.scattered_mean(), 5e-3));

    // Albedo < 1: the conservative model re-emits what it absorbs, so it holds more light
    // than the physical one (measured: total fluence +4.5%; the physical model absorbs
    // 4.8% of the injected power, the conservative one nothing: all of it escapes).
    const double Ep = sum_of(phys.fluence), Ec = sum_of(cons.fluence);
    MESSAGE("fluence sums: physical " << Ep << ", conservative " << Ec << "; escaped/injected physical "
                                      << phys.escaped_last_step / phys.injected_per_step << ", conservative "
                                      << cons.escaped_last_step / cons.injected_per_step);
    CHECK(Ec > 1.02 * Ep);  // half the measured excess: the sign is the point, not the size
    CHECK(cons.escaped_last_step / cons.injected_per_step == test::rel(1.0, 1e-3));  // tol 1e-6 steady state
    CHECK(phys.escaped_last_step / phys.injected_per_step < 0.97);
    double conservative_multiple = 0.0, physical_multiple = 0.0;
    for (std::size_t i = 0; i < phys.source.data.size(); ++i) {
        physical_multiple += phys.source.data[i];
        conservative_multiple += cons.source.data[i];
    }
    CHECK(conservative_multiple > physical_multiple);
}

TEST_CASE("LB vs Monte Carlo: optically thick blob (hop optical depth up to 2), saturate vs diffusion_matched") {
    // The same blob 5x denser (sigma_t h <= 2, as the default storm's core on its 500 m
    // lighting grid) and albedo 0.99: voxels thicker than a mean free path, where the
    // exact-chord mapping lets light diffuse out too fast (docs/lattice-boltzmann.md).
    const LightingMedium m = blob(0.99, 0.02);
    const PointSource light{{37.0, -23.0, -200.0}, 1.0};
    const Reference ref = reference(m, light, 2'000'000, 12);
    const auto& dirs = ref.dirs;
    const SourceField& S1 = ref.S1;
    const MonteCarloResult& mc = ref.mc;
    const LbSources src = ref.sources();
    LbSettings ls;
    ls.tolerance = 1e-6;
    ls.thick_voxels = LbThickVoxels::Saturate;
    const LbResult sat = solve_lattice_boltzmann(m, src, dirs, ls);
    ls.thick_voxels = LbThickVoxels::DiffusionMatched;
    const LbResult mat = solve_lattice_boltzmann(m, src, dirs, ls);
    REQUIRE(sat.converged);
    REQUIRE(mat.converged);
    const Errors es = compare(m, S1, sat.source, mc), em = compare(m, S1, mat.source, mc);
    MESSAGE("thick blob, saturate: total " << es.total << ", multiple " << es.multiple << " (LB/MC sum "
                                           << es.ratio_multiple << ", escaped "
                                           << sat.escaped_last_step / sat.injected_per_step << ")");
    MESSAGE("thick blob, diffusion_matched: total " << em.total << ", multiple " << em.multiple << " (LB/MC sum "
                                                    << em.ratio_multiple << ", escaped "
                                                    << mat.escaped_last_step / mat.injected_per_step << ")");
    MESSAGE("noise floor total " << es.floor_total << ", multiple " << es.floor_multiple);
    const double mc_scattered = mc.energy.scattered_mean();
    const double mc_escaped = mc.energy.escaped_scattered_mean();
    MESSAGE("MC escaped / scattered " << mc_escaped / mc_scattered);
    // Noise: 2M paths give floors of 1.8% (total) / 2.8% (multiple), well below the errors.
    CHECK(es.floor_total < 0.025);
    CHECK(es.floor_multiple < 0.04);
    // Measured: saturate 0.225 / 0.401 (LB/MC sum 0.67; escapes 0.968 of the scattered power
    // against Monte Carlo's 0.948), diffusion_matched 0.0789 / 0.139 (sum 0.980, escapes
    // 0.948). Bounds: matched + 2 noise floors; saturate stays well above (the contrast is
    // the point: it must not silently become the same mapping).
    CHECK(em.total < 0.115);
    CHECK(em.multiple < 0.20);
    CHECK(es.total > 0.18);
    CHECK(em.total < 0.5 * es.total);
    // Escape (hence absorption) right to 0.01 with the matched mapping, 2% off with saturate.
    CHECK(std::fabs(mat.escaped_last_step / mat.injected_per_step - mc_escaped / mc_scattered) < 0.01);
}
