// Monte Carlo reference solver: analytic oracles (the same templated tracing core on analytic
// media), delta tracking in heterogeneous grids, energy bookkeeping, determinism, hard inputs.
//
// Path counts are chosen so that the standard error of each oracle quantity is at most ~1/4
// of the 1% bound: "within 1%" is then implied by "within 3 SE" up to a <1e-4 chance per
// check, and the seeds are fixed, so the suite is deterministic. Total runtime ~5 s in
// release on 2 cores (~8 s under the sanitizers).
#include "support/test_support.h"
#include "transport/detail/monte_carlo_core.h"
#include "transport/transport.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

// |estimate - expect| <= 3 SE and <= 1% of expect (the two acceptance conditions).
void check_oracle(const char* what, double estimate, double se, double expect) {
    CAPTURE(what);
    CAPTURE(estimate);
    CAPTURE(se);
    CAPTURE(expect);
    MESSAGE(std::string(what) << ": " << estimate << " +- " << se << " (oracle " << expect << ", rel. error "
                              << (estimate / expect - 1.0) << ")");
    CHECK(std::fabs(estimate - expect) <= 3.0 * se);
    CHECK(std::fabs(estimate - expect) <= 0.01 * expect);
    CHECK(se <= 0.004 * expect);  // the run is precise enough for the 1% test to mean something
}

// Fraction of voxel-direction values where |a - b| <= 3 sqrt(se_a^2 + se_b^2), over voxels
// with density > 0.
double agreement(const LightingMedium& m, const SourceField& a, const SourceField* a_se, const SourceField& b,
                 const SourceField& b_se) {
    int n = 0, ok = 0;
    for (std::size_t c = 0; c < a.cells(); ++c) {
        if (!(m.density.data[c] > 0.0f)) continue;
        for (std::size_t k = 0; k < a.directions.size(); ++k) {
            const std::size_t i = k * a.cells() + c;
            const double s1 = a_se ? a_se->data[i] : 0.0, s2 = b_se.data[i];
            ++n;
            if (std::fabs(a.data[i] - b.data[i]) <= 3.0 * std::sqrt(s1 * s1 + s2 * s2)) ++ok;
        }
    }
    return n ? double(ok) / n : 0.0;
}

// Deterministic field S against a Monte Carlo estimate with batch SE, on a SMALL cloud. Even
// with S exact, |S - MC| / SE follows Student's t with 31 degrees of freedom (32 batches),
// beyond 3 with probability p0 = 0.0053, and the directions of one voxel are strongly
// correlated (for the sun, identical). So the number of failing voxels is ~Binomial(N, p0)
// with N cloud voxels, and with ~100 voxels "99% within 3 SE" would fail by chance about a
// third of the time. This checks the failing voxels against the binomial's mean + 3 sigma + 1
// (false alarm < 1e-3); the 99% criterion proper is asserted on the default cloud, which has
// thousands of voxels (test_transport_storm.cpp). Returns the failing-voxel fraction.
//
// max_rel_se: voxels whose MC relative SE exceeds it are not compared (for the analog
// track-length estimator, whose rarely reached voxels have a few hits per batch: the batch
// SE is then not a reliable error bar, the estimate being strongly skewed).
//
// extra_fraction: additional allowed failing fraction, for the track-length estimator, whose
// sampled flights cross many voxels each: one lucky batch moves many voxels the same way, so
// failures cluster (measured: all of one sign) and are not binomial. Delta tracking itself is
// validated to 0.03% by the uncollided-escape test; this is a consistency check.
// Whether any direction of cell c is more than 3 SE from the Monte Carlo estimate.
bool beyond_3se(const SourceField& S, const MonteCarloResult& r, std::size_t c) {
    for (std::size_t k = 0; k < S.directions.size(); ++k) {
        const std::size_t i = k * S.cells() + c;
        if (std::fabs(S.data[i] - r.single.data[i]) > 3.0 * r.single_se.data[i]) return true;
    }
    return false;
}

// The binomial's mean + 3 sigma + 1 failing voxels of n (see check_against_mc).
double allowed_failing(int n) {
    const double p0 = 0.0053, mean = p0 * n;
    return mean + 3.0 * std::sqrt(mean * (1.0 - p0)) + 1.0;
}

// Exact single scattering at tolerance 1e-4 (its error far below the Monte Carlo's noise) and
// the expected-value estimate of order 1 from 400k paths.
struct OrderOne {
    SourceField exact;
    MonteCarloResult ev;
};
OrderOne order_one(const LightingMedium& m, const PointSource& L, const std::vector<glm::dvec3>& dirs) {
    SingleScatteringOptions so;
    so.tolerance = 1e-4;
    MonteCarloOptions o;
    o.paths = 400'000;
    o.max_scatterings = 0;
    return {single_scattering(m, L, dirs, so), monte_carlo(m, L, dirs, o)};
}

double check_against_mc(const LightingMedium& m, const SourceField& S, const MonteCarloResult& r, const char* what,
                        double max_rel_se = 1e300, double extra_fraction = 0.0) {
    int voxels = 0, failing = 0;
    for (std::size_t c = 0; c < S.cells(); ++c) {
        if (!(m.density.data[c] > 0.0f)) continue;
        bool reliable = true;
        for (std::size_t k = 0; k < S.directions.size(); ++k) {
            const std::size_t i = k * S.cells() + c;
            if (!(r.single_se.data[i] <= max_rel_se * r.single.data[i])) reliable = false;
        }
        if (!reliable) continue;
        ++voxels;
        failing += beyond_3se(S, r, c);
    }
    const double allowed = allowed_failing(voxels) + extra_fraction * voxels;
    MESSAGE(std::string(what) << ": " << failing << " of " << voxels << " cloud voxels beyond 3 SE (allowed " << allowed
                              << ")");
    CHECK(voxels > 50);
    CHECK(double(failing) <= allowed);
    return voxels ? double(failing) / voxels : 1.0;
}

}  // namespace

TEST_CASE("oracle: homogeneous sphere, centred point source, albedo 1") {
    // Fraction of emitted power escaping after exactly one scattering (isotropic scattering).
    struct Case {
        double tau, f1;
        std::uint64_t paths;
    };
    for (const Case c :
         {Case{0.1, 0.08729, 2'000'000}, Case{1.0, 0.27129, 1'000'000}, Case{5.0, 0.013179, 12'000'000}}) {
        detail::HomogeneousSphere sphere;
        sphere.radius = 1.0;
        sphere.sigma = c.tau;
        const detail::PointEmitter em{{0, 0, 0}, 1.0};
        MonteCarloOptions o;
        o.paths = c.paths;
        o.seed = 11;
        o.max_scatterings = 1;  // the flight after the first scattering is traced: exact f1
        const auto r = detail::run_energy(sphere, em, 1.0, 0.0, o);
        const double P = r.energy.emitted.mean;
        CHECK(P == doctest::Approx(4.0 * std::numbers::pi));
        check_oracle("escape after one scattering", r.energy.escaped_by_order[1].mean / P,
                     r.energy.escaped_by_order[1].se / P, c.f1);
        // Uncollided escape e^{-tau}: its own run with enough paths for SE <= 0.25%.
        o.max_scatterings = 0;
        o.paths = c.tau > 2 ? 16'000'000 : 1'000'000;
        const auto u = detail::run_energy(sphere, em, 1.0, 0.0, o);
        check_oracle("uncollided escape", u.energy.escaped_by_order[0].mean / P, u.energy.escaped_by_order[0].se / P,
                     std::exp(-c.tau));
    }
}

TEST_CASE("oracle: semi-infinite slab, isotropic scattering, normal incidence") {
    struct Case {
        double albedo, reflectance;
        std::uint64_t paths;
    };
    for (const Case c : {Case{0.8, 0.28525, 400'000}, Case{0.9, 0.41495, 300'000}, Case{0.99, 0.75272, 150'000}}) {
        detail::HalfSpace slab;
        slab.sigma = 1.0;
        const detail::BeamEmitter beam{{0, 0, 0}, {0, 0, -1}, 1.0};
        MonteCarloOptions o;
        o.paths = c.paths;
        o.seed = 3;
        const auto r = detail::run_energy(slab, beam, c.albedo, 0.0, o);
        check_oracle("diffuse reflectance", r.energy.escaped.mean, r.energy.escaped.se, c.reflectance);
        CHECK(r.energy.escaped_by_order[0].mean == 0.0);  // nothing leaves a half-space uncollided
        // Per path exactly: emitted + roulette = absorbed + escaped (+ truncated = 0).
        CHECK(r.energy.emitted.mean + r.energy.roulette.mean ==
              test::rel(r.energy.absorbed.mean + r.energy.escaped.mean, 1e-12));
    }
}

TEST_CASE("oracle: infinite medium absorbs everything it receives") {
    // Implicit capture + Russian roulette: each path's absorbed weight is random; only the
    // expectation equals the emitted power, so this checks that roulette is unbiased.
    detail::InfiniteMedium inf;
    inf.sigma = 2.0;
    const detail::PointEmitter em{{0, 0, 0}, 1.0};
    MonteCarloOptions o;
    o.paths = 400'000;
    o.seed = 5;
    o.roulette_threshold = 0.2;  // roulette on early: the unbiasedness is what is tested
    const auto r = detail::run_energy(inf, em, 0.7, 0.5, o);
    check_oracle("absorbed / emitted", r.energy.absorbed.mean / r.energy.emitted.mean,
                 r.energy.absorbed.se / r.energy.emitted.mean, 1.0);
    CHECK(r.energy.escaped.mean == 0.0);
    CHECK(std::fabs(r.energy.roulette.mean) <= 3.0 * r.energy.roulette.se);  // expectation 0
    // Analog absorption: every path ends absorbed, exactly.
    o.implicit_capture = false;
    const auto a = detail::run_energy(inf, em, 0.7, 0.5, o);
    CHECK(a.energy.absorbed.mean == test::rel(a.energy.emitted.mean, 1e-12));
    // A bounded sphere with HG(0.8) and the same core: energy closes per path.
    detail::HomogeneousSphere sph;
    sph.sigma = 3.0;
    o.implicit_capture = true;
    o.paths = 100'000;
    const auto s = detail::run_energy(sph, em, 0.9, 0.8, o);
    CHECK(s.energy.emitted.mean + s.energy.roulette.mean ==
          test::rel(s.energy.absorbed.mean + s.energy.escaped.mean, 1e-12));
}

TEST_CASE("delta tracking in a heterogeneous grid: uncollided escape equals the DDA transmittance") {
    // Uncollided escape from a point inside a random-density grid is (1/4pi) integral
    // e^{-tau(w)} dw. Reference: the exact traversal on a 400 x 800 midpoint grid in
    // (cos theta, phi) (discretization error ~1e-4, below the MC standard error of ~4e-4).
    // MC: analog delta tracking with one global majorant, per-voxel majorants (macro-cell 1)
    // and 3^3 macro-cells (which do not divide the 7x6x5 grid evenly).
    core::GridGeometry g;
    g.dims = {7, 6, 5};
    g.voxel_size = 1.0;
    LightingMedium m;
    m.density = core::Grid3<float>(g);
    core::Rng rng(17);
    for (float& v : m.density.data) v = rng.uniform() < 0.3 ? 0.0f : float(rng.uniform());
    m.optics = {0.8, 1.0, 0.0};
    const glm::dvec3 xl(3.3, 2.9, 2.2);
    double ref = 0.0;
    const int nt = 400, np = 800;
    for (int a = 0; a < nt; ++a)
        for (int b = 0; b < np; ++b) {
            const double z = -1.0 + (a + 0.5) * 2.0 / nt, ph = (b + 0.5) * 2.0 * std::numbers::pi / np;
            const double r = std::sqrt(1.0 - z * z);
            ref += std::exp(-optical_depth(m, xl, xl + 100.0 * glm::dvec3(r * std::cos(ph), r * std::sin(ph), z)));
        }
    ref /= double(nt) * np;
    const std::vector<glm::dvec3> dir = {{0, 0, 1}};
    for (int macro : {0, 1, 3}) {
        CAPTURE(macro);
        MonteCarloOptions o;
        o.paths = 1'000'000;
        o.max_scatterings = 0;
        o.macro_cell = macro;
        o.tally_multiple = false;
        const MonteCarloResult r = monte_carlo(m, PointSource{xl, 1.0}, dir, o);
        const double P = r.energy.emitted.mean;
        check_oracle("uncollided escape (grid)", r.energy.escaped_by_order[0].mean / P,
                     r.energy.escaped_by_order[0].se / P, ref);
        if (macro == 0) CHECK(r.null_collisions > 0);  // the global majorant does reject
    }
}

TEST_CASE("order 1: expected-value and track-length estimators agree with exact single scattering") {
    // The track-length estimator deposits along flights sampled by delta tracking, so its mean
    // equals single scattering only if the free-path sampling is exact; the expected-value
    // estimator integrates exactly along random rays. Both must agree with the deterministic
    // voxel average (tolerance 1e-4 here, so its error is far below the MC noise) within 3 SE,
    // up to the statistical scatter check_against_mc() allows.
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.99, 0.6});
    const auto dirs = output_directions(6);
    const PointSource L{{200, -300, 400}, 1.0};
    const auto [S, ev] = order_one(m, L, dirs);
    check_against_mc(m, S, ev, "expected value");
    MonteCarloOptions o;
    o.max_scatterings = 0;
    o.single_estimator = MonteCarloOptions::SingleEstimator::TrackLength;
    o.paths = 1'000'000;
    const MonteCarloResult tl = monte_carlo(m, L, dirs, o);
    check_against_mc(m, S, tl, "track length (voxels with relative SE < 10%)", 0.1, 0.03);
}

TEST_CASE("order 1 with a peaked phase function and the light inside the cloud: exact and Monte Carlo agree") {
    // The expected-value estimator samples directions from the light and so needs no
    // grading toward the phase function's peak: an independent check of the face rules'
    // grading in a heterogeneous cloud, where the light's own voxel and its neighbours are
    // integrated by them. Before the grading, at g = 0.9 those voxels were 30-51 SE off (42%
    // at the worst), 4 of the 27 beyond 3 SE, and the whole cloud failed (7 of 180); at g = 0.99
    // 19 of the 27 and 22 of 180. Measured now: 1 of the 27 (3.05 SE), 4 of 180, at both g.
    for (const double g : {0.9, 0.99}) {
        CAPTURE(g);
        const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.99, g});
        const auto dirs = output_directions(26);
        const PointSource L{{30, -40, 1100}, 1.0};  // in the cloud's dense part
        const auto [S, ev] = order_one(m, L, dirs);
        check_against_mc(m, S, ev, "expected value, the whole cloud");
        // The light's 3x3x3 voxels, every direction: failing voxels against the same binomial
        // bound as check_against_mc (27 voxels: at most 2).
        const core::Int3 lc = m.density.geom.clamped_voxel(L.position);
        int failing = 0;
        for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const std::size_t c = m.density.geom.index(lc.x + di, lc.y + dj, lc.z + dk);
                    REQUIRE(m.density.data[c] > 0.0f);
                    failing += beyond_3se(S, ev, c);
                }
        CHECK(double(failing) <= allowed_failing(27));
    }
}

TEST_CASE("sun: Monte Carlo order 1 agrees with exact single scattering") {
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.9, 0.5});
    const auto dirs = output_directions(6);
    const DirectionalSource sun{glm::normalize(glm::dvec3(0.5, 0.2, -0.8)), 2.0};
    SingleScatteringOptions so;
    so.tolerance = 1e-4;
    const SourceField S = single_scattering(m, sun, dirs, so);
    MonteCarloOptions o;
    o.paths = 300'000;
    o.max_scatterings = 0;
    const MonteCarloResult r = monte_carlo(m, sun, dirs, o);
    check_against_mc(m, S, r, "sun");
    // Power entering = E * projected area of the grid's box.
    const glm::dvec3 ext = m.density.geom.extent();
    const double area = ext.y * ext.z * std::fabs(sun.direction.x) + ext.x * ext.z * std::fabs(sun.direction.y) +
                        ext.x * ext.y * std::fabs(sun.direction.z);
    CHECK(r.energy.emitted.mean == test::rel(2.0 * area, 1e-12));
}

TEST_CASE("sky dome: Monte Carlo order 1 agrees with exact single scattering summed over the dome") {
    // A dome brighter towards the zenith, tabulated at u = sin(elevation) = 0, 1/4, .. 1; one
    // output direction, so that the per-voxel failure count is binomial (check_against_mc).
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.9, 0.5});
    const std::vector<glm::dvec3> dirs = {glm::normalize(glm::dvec3(0.3, -0.2, 0.9))};
    const DomeSource sky{{0.2, 0.5, 1.0, 1.2, 1.5}};
    const auto radiance = [&](double u) {
        const double x = u * 4.0;
        const int k = std::min(int(x), 3);
        return sky.radiance[std::size_t(k)] * (k + 1 - x) + sky.radiance[std::size_t(k) + 1] * (x - k);
    };
    const glm::dvec3 ext = m.density.geom.extent();
    const auto area = [&](const glm::dvec3& toward) {
        return ext.y * ext.z * std::fabs(toward.x) + ext.x * ext.z * std::fabs(toward.y) + ext.x * ext.y * toward.z;
    };
    const auto toward = [](double u, double phi) {
        const double c = std::sqrt(1.0 - u * u);
        return glm::dvec3(c * std::cos(phi), c * std::sin(phi), u);
    };
    // The reference: the dome as 32 x 32 suns (midpoints in u and in azimuth, each of
    // irradiance L du dphi), each solved exactly. The midpoint rule's error, measured against
    // 96 x 96 on this cloud: at most 0.4% per voxel at 24 x 24, 0.2% at 48 x 48, far below the
    // 3 SE (~6%) the per-voxel comparison allows and the 0.6% SE of the cloud's sum. Each sun at
    // tolerance 1e-2: within 1.2% of the brute-force reference in any bright voxel and 7.5e-4 in
    // L1 from 5 to 60 degrees (docs/transport.md, "The sun"), also far below them.
    const int n = 32;
    const double du = 1.0 / n, dphi = 2.0 * std::numbers::pi / n;
    SingleScatteringOptions so;
    so.tolerance = 1e-2;
    SourceField S(m.density.geom, dirs);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const double u = (i + 0.5) * du;
            const DirectionalSource sun{-toward(u, (j + 0.5) * dphi), radiance(u) * du * dphi};
            const SourceField one = single_scattering(m, sun, dirs, so);
            for (std::size_t k = 0; k < S.data.size(); ++k) S.data[k] += one.data[k];
        }
    MonteCarloOptions o;
    o.paths = 300'000;
    o.max_scatterings = 0;
    const MonteCarloResult r = monte_carlo(m, sky, m.density.geom, dirs, o);
    check_against_mc(m, S, r, "sky dome");
    double sum = 0.0;
    for (std::size_t c = 0; c < S.cells(); ++c)
        if (m.density.data[c] > 0.0f) sum += S.data[c];
    CAPTURE(sum);
    CAPTURE(r.sums.single.mean);
    CAPTURE(r.sums.single.se);
    CHECK(std::fabs(r.sums.single.mean - sum) <= 3.0 * r.sums.single.se + 0.002 * sum);
    // The power entering the box, the emitter's closed form against a 2000 x 2000 midpoint sum
    // of L A over the dome (its own error ~1e-6: the sqrt(1 - u^2) near the zenith).
    double power = 0.0;
    const int fine = 2000;
    for (int i = 0; i < fine; ++i)
        for (int j = 0; j < fine; ++j) {
            const double u = (i + 0.5) / fine;
            power += radiance(u) * area(toward(u, (j + 0.5) * 2.0 * std::numbers::pi / fine));
        }
    power *= 2.0 * std::numbers::pi / (double(fine) * fine);
    CHECK(r.energy.emitted.mean == test::rel(power, 1e-5));
    // A uniform dome of radiance L: pi L (A_yz + A_xz + A_xy), half of Cauchy's pi L x surface.
    const MonteCarloResult uniform = monte_carlo(m, DomeSource{{2.0, 2.0}}, m.density.geom, dirs, o);
    CHECK(uniform.energy.emitted.mean ==
          test::rel(2.0 * std::numbers::pi * (ext.y * ext.z + ext.x * ext.z + ext.x * ext.y), 1e-12));
    // Bad tables name the value; a dark dome emits nothing (and does not hang).
    CHECK_THROWS_WITH(monte_carlo(m, DomeSource{{1.0}}, m.density.geom, dirs, o), doctest::Contains("sky.radiance"));
    CHECK_THROWS_WITH(monte_carlo(m, DomeSource{{1.0, -0.5}}, m.density.geom, dirs, o),
                      doctest::Contains("sky.radiance[1]"));
    CHECK_THROWS_WITH(monte_carlo(m, DomeSource{{1.0, std::nan("")}}, m.density.geom, dirs, o),
                      doctest::Contains("sky.radiance[1]"));
    CHECK(monte_carlo(m, DomeSource{{0.0, 0.0}}, m.density.geom, dirs, o).energy.emitted.mean == 0.0);
}

TEST_CASE("sun tallied on a coarser grid: the same paths, each cell the volume average of the fine tallies") {
    // 12 x 12 x 8 voxels coarsened by 2 and by 5 (a partial trailing block: 3 x 3 x 2 cells).
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.9, 0.5});
    const auto dirs = output_directions(6);
    const DirectionalSource sun{glm::normalize(glm::dvec3(-0.3, 0.4, -0.85)), 1.5};
    MonteCarloOptions o;
    o.paths = 40'000;
    o.seed = 9;
    const MonteCarloResult fine = monte_carlo(m, sun, dirs, o);
    const MonteCarloResult same = monte_carlo(m, sun, m.density.geom, dirs, o);
    CHECK(same.single.data == fine.single.data);  // the fine grid itself: the single-grid overload
    CHECK(same.multiple.data == fine.multiple.data);
    for (const int f : {2, 3, 4, 5}) {
        CAPTURE(f);
        core::GridGeometry g = m.density.geom;
        g.voxel_size *= f;
        g.dims = {(g.dims.x + f - 1) / f, (g.dims.y + f - 1) / f, (g.dims.z + f - 1) / f};
        const MonteCarloResult coarse = monte_carlo(m, sun, g, dirs, o);
        // A cell inside the medium: the mean of its f^3 fine voxels. A trailing cell reaching
        // past the medium (f = 3, 5): the fine voxels it holds summed over f^3 (block_average
        // divides by the voxels it has: scaled back), plus the light crossing its part outside
        // the medium (tallied as empty space), so at least that.
        const SourceField avg1 = block_average(fine.single, f), avgm = block_average(fine.multiple, f);
        double worst = 0.0, peak = 0.0;
        for (int k = 0; k < g.dims.z; ++k)
            for (int j = 0; j < g.dims.y; ++j)
                for (int i = 0; i < g.dims.x; ++i) {
                    const int nx = std::min(f, m.density.geom.dims.x - i * f),
                              ny = std::min(f, m.density.geom.dims.y - j * f),
                              nz = std::min(f, m.density.geom.dims.z - k * f);
                    const double inside = double(nx * ny * nz) / double(f * f * f);
                    for (std::size_t d = 0; d < dirs.size(); ++d) {
                        const std::size_t c = d * g.cell_count() + g.index(i, j, k);
                        for (const auto& [a, b] :
                             {std::pair{&avg1, &coarse.single}, std::pair{&avgm, &coarse.multiple}}) {
                            const double ref = a->data[c] * inside;
                            peak = std::max(peak, std::fabs(ref));
                            if (inside == 1.0)
                                worst = std::max(worst, std::fabs(b->data[c] - ref));
                            else
                                worst = std::max(worst, ref - b->data[c]);
                        }
                    }
                }
        // Float32 tallies summed in another order: a few units in the last place of the peak.
        CHECK(worst <= 1e-5 * peak);
    }
}

TEST_CASE("S toward a point: every cell holds what a tally along its own direction to the point gives") {
    // A still camera 6 km from a 3 x 3 x 2 km cloud at g = 0.7: the direction to it turns by
    // ~40 degrees across the grid, so a field of one fixed direction would differ by tens of
    // percent from cell to cell (the mutation check below).
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 250.0, {0.004, 0.9, 0.7});
    const core::GridGeometry& g = m.density.geom;
    const DirectionalSource sun{glm::normalize(glm::dvec3(-0.3, 0.4, -0.85)), 1.5};
    const glm::dvec3 camera = g.origin + 0.5 * g.extent() + glm::dvec3(2500.0, -5000.0, 1500.0);
    MonteCarloOptions o;
    o.paths = 20'000;
    o.seed = 5;
    MonteCarloOptions toward = o;
    toward.toward = camera;
    const MonteCarloResult r = monte_carlo(m, sun, output_directions(1), toward);
    // The same paths and seed tally the same flights; a run along one cell's own direction (the
    // cell's centre to the camera) deposits the same products into that cell. Both are sums of
    // the same doubles in the same order, stored as float32: equal but for a rounding of the
    // phase's dot product (fused or not), far below one float32 ulp (6e-8) of the cell.
    int compared = 0;
    double spread_lo = 1e300, spread_hi = 0.0;
    for (const core::Int3 c : {core::Int3{6, 6, 4}, core::Int3{2, 9, 1}, core::Int3{10, 3, 6}, core::Int3{5, 6, 7}}) {
        CAPTURE(c.x);
        CAPTURE(c.y);
        CAPTURE(c.z);
        const std::size_t cell = g.index(c.x, c.y, c.z);
        const glm::dvec3 own = camera - g.centre(c.x, c.y, c.z);
        const MonteCarloResult along = monte_carlo(m, sun, std::span(&own, 1), o);
        REQUIRE(along.multiple.data[cell] > 0.0f);
        CHECK(r.single.data[cell] == test::rel(along.single.data[cell], 2e-7));
        CHECK(r.multiple.data[cell] == test::rel(along.multiple.data[cell], 2e-7));
        // The field of one fixed direction (the middle cell's) at this cell: not the same.
        const glm::dvec3 mid = camera - g.centre(6, 6, 4);
        const MonteCarloResult fixed = monte_carlo(m, sun, std::span(&mid, 1), o);
        const double ratio = double(fixed.single.data[cell]) / double(r.single.data[cell]);
        spread_lo = std::min(spread_lo, ratio);
        spread_hi = std::max(spread_hi, ratio);
        ++compared;
    }
    CHECK(compared == 4);
    // Off the middle cell a fixed direction is off by well over the 2e-7 above (measured: the
    // ratios span 0.92-1.05), so the check above tells the cell's own direction from any other.
    CHECK(spread_hi - spread_lo > 0.05);
    CHECK(r.single.directions.size() == 1);
    CHECK(r.multiple.directions.size() == 1);
    // A camera inside the cloud, on a cell's centre: every value finite, that cell holds the
    // phase's mean over directions (1 / (4 pi)) in place of a direction's.
    toward.toward = g.centre(6, 6, 4);
    const MonteCarloResult inside = monte_carlo(m, sun, output_directions(1), toward);
    for (const float v : inside.multiple.data) REQUIRE(std::isfinite(v));
    for (const float v : inside.single.data) REQUIRE(std::isfinite(v));
    CHECK(inside.multiple.data[g.index(6, 6, 4)] > 0.0f);
    // Misuse named: several directions, a point that is not finite.
    const auto dirs2 = output_directions(6);
    CHECK_THROWS_WITH_AS(monte_carlo(m, sun, dirs2, toward), doctest::Contains("one direction"), core::Error);
    toward.toward = glm::dvec3(0.0, std::nan(""), 0.0);
    CHECK_THROWS_WITH_AS(monte_carlo(m, sun, output_directions(1), toward), doctest::Contains("monte_carlo.toward"),
                         core::Error);
}

TEST_CASE("full transport in a grid: energy closes per path, roulette is unbiased, orders add up") {
    LightingMedium m = test::synthetic_cloud({10, 10, 8}, 200.0, {0.01, 0.6, 0.7});
    const auto dirs = output_directions(1);
    MonteCarloOptions o;
    o.paths = 200'000;
    o.roulette_threshold = 0.3;  // low albedo + high threshold: roulette is exercised
    const MonteCarloResult r = monte_carlo(m, PointSource{{0, 0, 900}, 1.0}, dirs, o);
    const EnergyTally& e = r.energy;
    CHECK(e.emitted.mean == test::rel(4.0 * std::numbers::pi, 1e-12));
    // Exact per path (round-off only).
    CHECK(e.emitted.mean + e.roulette.mean == test::rel(e.absorbed.mean + e.escaped.mean + e.truncated.mean, 1e-12));
    CHECK(e.truncated.mean == 0.0);
    CHECK(std::fabs(e.roulette.mean) <= 3.0 * e.roulette.se);  // expectation 0
    CHECK(e.roulette.se > 0.0);                                // roulette did happen
    double esc = 0.0, abs = 0.0;
    for (int k = 0; k < EnergyTally::kOrders; ++k) {
        esc += e.escaped_by_order[std::size_t(k)].mean;
        abs += e.absorbed_by_order[std::size_t(k)].mean;
    }
    CHECK(esc == test::rel(e.escaped.mean, 1e-12));
    CHECK(abs == test::rel(e.absorbed.mean, 1e-12));
    // What was scattered at least once is what the source put in minus what left or was
    // absorbed uncollided (energy closes per path; round-off only).
    CHECK(e.scattered_mean() ==
          doctest::Approx(e.emitted.mean + e.roulette.mean - e.escaped_by_order[0].mean - e.absorbed_by_order[0].mean)
              .epsilon(1e-12));
    CHECK(e.escaped_scattered_mean() == test::rel(e.escaped.mean - e.escaped_by_order[0].mean, 1e-12));
    // Multiple scattering is positive where there is cloud and its SE is finite.
    for (std::size_t c = 0; c < r.multiple.cells(); ++c)
        if (m.density.data[c] > 0.3f) {
            CHECK(r.multiple.data[c] > 0.0f);
            CHECK(std::isfinite(r.multiple_se.data[c]));
        }
    // max_scatterings = 2: what is cut off is reported as truncated; escape up to order 2 is
    // unchanged (every path has its own random stream, so the paths are identical up to the
    // cut and the numbers are equal).
    o.max_scatterings = 2;
    const MonteCarloResult t = monte_carlo(m, PointSource{{0, 0, 900}, 1.0}, dirs, o);
    for (int k = 0; k <= 2; ++k)
        CHECK(t.energy.escaped_by_order[std::size_t(k)].mean == e.escaped_by_order[std::size_t(k)].mean);
    CHECK(t.energy.truncated.mean > 0.0);
    CHECK(t.energy.emitted.mean + t.energy.roulette.mean ==
          test::rel(t.energy.absorbed.mean + t.energy.escaped.mean + t.energy.truncated.mean, 1e-12));
}

TEST_CASE("results depend on the seed, not on the thread count") {
    const LightingMedium m = test::synthetic_cloud({8, 8, 6}, 250.0, {0.004, 0.99, 0.6});
    const auto dirs = output_directions(6);
    MonteCarloOptions o;
    o.paths = 20'000;
    o.batches = 8;
    const int saved = core::thread_count();
    core::set_thread_count(1);
    const MonteCarloResult a = monte_carlo(m, PointSource{{100, 0, 300}, 1.0}, dirs, o);
    core::set_thread_count(2);
    const MonteCarloResult b = monte_carlo(m, PointSource{{100, 0, 300}, 1.0}, dirs, o);
    core::set_thread_count(3);  // more threads than cores and a batch count not divisible by it
    const MonteCarloResult c = monte_carlo(m, PointSource{{100, 0, 300}, 1.0}, dirs, o);
    core::set_thread_count(saved);
    CHECK(a.single.data == b.single.data);
    CHECK(a.multiple.data == b.multiple.data);
    CHECK(a.single_se.data == c.single_se.data);
    CHECK(a.multiple.data == c.multiple.data);
    CHECK(a.energy.absorbed.mean == b.energy.absorbed.mean);
    CHECK(a.energy.absorbed.mean == c.energy.absorbed.mean);
    o.seed = 2;
    const MonteCarloResult d = monte_carlo(m, PointSource{{100, 0, 300}, 1.0}, dirs, o);
    CHECK(d.multiple.data != a.multiple.data);
}

TEST_CASE("cloud sums: the fields' totals over the cloud, with standard errors the spread of seeds confirms") {
    // A coarser tally weighted by extinction (the truth's setting) on a cloud with empty margins.
    const LightingMedium m = test::synthetic_cloud({12, 12, 8}, 200.0, {0.004, 0.95, 0.6});
    core::GridGeometry coarse = m.density.geom;
    coarse.voxel_size *= 2.0;
    coarse.dims = {6, 6, 4};
    const auto dirs = output_directions(6);
    const std::vector<LineSource> lines = {{{-300.0, 0.0, 300.0}, {200.0, 100.0, 1200.0}, 0.01, 0}};
    const core::Grid3<float> coarse_rho = core::downsample(m.density, 2);  // > 0: the cloud's tally cells
    std::vector<double> single, multiple;
    double se_single = 0.0, se_multiple = 0.0;
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
        MonteCarloOptions o;
        o.paths = 20'000;
        o.seed = seed;
        o.tally_weight = MonteCarloOptions::TallyWeight::Extinction;
        const MonteCarloResult r = monte_carlo(m, {}, lines, coarse, dirs, o);
        // The sums are those of the fields over the cells holding density (float fields:
        // rounding of ~1e-7 per value).
        double s1 = 0.0, sm = 0.0;
        for (std::size_t c = 0; c < r.single.cells(); ++c)
            if (coarse_rho.data[c] > 0.0f)
                for (std::size_t k = 0; k < dirs.size(); ++k) {
                    s1 += r.single.data[k * r.single.cells() + c];
                    sm += r.multiple.data[k * r.single.cells() + c];
                }
        CHECK(r.sums.single.mean == test::rel(s1, 1e-6));
        CHECK(r.sums.multiple.mean == test::rel(sm, 1e-6));
        single.push_back(s1);
        multiple.push_back(sm);
        se_single += r.sums.single.se / 8.0;
        se_multiple += r.sums.multiple.se / 8.0;
    }
    // The standard deviation of 8 seeds' sums against the mean standard error: for 7 degrees of
    // freedom their ratio lies in [0.36, 1.93] with probability 0.999.
    const auto spread = [](const std::vector<double>& x) {
        double mean = 0.0, var = 0.0;
        for (double v : x) mean += v / double(x.size());
        for (double v : x) var += (v - mean) * (v - mean) / double(x.size() - 1);
        return std::sqrt(var);
    };
    MESSAGE("cloud sums: spread / SE single " << spread(single) / se_single << ", multiple "
                                              << spread(multiple) / se_multiple);
    CHECK(spread(single) / se_single > 0.36);
    CHECK(spread(single) / se_single < 1.93);
    CHECK(spread(multiple) / se_multiple > 0.36);
    CHECK(spread(multiple) / se_multiple < 1.93);
}

TEST_CASE("hard inputs: empty cloud, single voxel, dense voxel around the source, albedo 1, thick, thin") {
    const auto dirs = output_directions(1);
    MonteCarloOptions o;
    o.paths = 100'000;
    SUBCASE("empty cloud: everything escapes uncollided, S1 is the unattenuated value, no multiple") {
        const LightingMedium m = test::uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 0.0f, {1.0, 0.9, 0.0});
        const MonteCarloResult r = monte_carlo(m, PointSource{{1.5, 2.5, 0.5}, 1.0}, dirs, o);
        CHECK(r.energy.escaped_by_order[0].mean == test::rel(r.energy.emitted.mean, 1e-12));
        CHECK(r.collisions == 0);
        const SourceField S = single_scattering(m, PointSource{{1.5, 2.5, 0.5}, 1.0}, dirs);
        CHECK(agreement(m, S, nullptr, r.single, r.single_se) == 0.0);  // no cloud voxel to compare...
        int ok = 0;
        for (std::size_t c = 0; c < S.cells(); ++c)
            ok += std::fabs(S.data[c] - r.single.data[c]) <= 3.0 * r.single_se.data[c];
        CHECK(ok >= int(0.97 * double(S.cells())));  // ...so compare all 64 voxels (t_31 tails)
        CHECK(*std::max_element(r.multiple.data.begin(), r.multiple.data.end()) == 0.0f);
    }
    SUBCASE("single-voxel cloud: finite; energy closes; absorption only in that voxel's flights") {
        LightingMedium m = test::uniform_medium({5, 5, 5}, 1.0, {0, 0, 0}, 0.0f, {2.0, 0.8, 0.3});
        m.density.at(2, 2, 2) = 1.0f;
        const MonteCarloResult r = monte_carlo(m, PointSource{{2.5, 2.5, 0.2}, 1.0}, dirs, o);
        const EnergyTally& e = r.energy;
        CHECK(e.absorbed.mean > 0.0);
        CHECK(e.emitted.mean + e.roulette.mean == test::rel(e.absorbed.mean + e.escaped.mean, 1e-12));
        for (float v : r.multiple.data) CHECK(std::isfinite(v));
    }
    SUBCASE("source inside a dense voxel (sigma h = 100), albedo 1: nothing absorbed, all escapes") {
        LightingMedium m = test::uniform_medium({3, 3, 3}, 1.0, {0, 0, 0}, 0.0f, {100.0, 1.0, 0.0});
        m.density.at(1, 1, 1) = 1.0f;
        o.paths = 2'000;  // ~600 collisions per path
        const MonteCarloResult r = monte_carlo(m, PointSource{{1.5, 1.5, 1.5}, 1.0}, dirs, o);
        CHECK(r.energy.absorbed.mean == 0.0);
        CHECK(r.energy.escaped.mean == test::rel(r.energy.emitted.mean, 1e-12));
        CHECK(r.energy.escaped_by_order[0].mean < 1e-12 * r.energy.emitted.mean);  // e^{-50}
        // Order 1 in the source voxel: S = albedo I / (V sigma) (see the single-scattering
        // test), estimated here with the expected-value estimator: within 3 SE.
        const std::size_t c = m.density.geom.index(1, 1, 1);
        CHECK(std::fabs(r.single.data[c] - 1.0 / 100.0) <= 3.0 * r.single_se.data[c] + 1e-7);
    }
    SUBCASE("source exactly on a voxel corner") {
        const LightingMedium m = test::uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 0.7f, {1.0, 0.9, 0.5});
        const MonteCarloResult r = monte_carlo(m, PointSource{{2, 2, 2}, 1.0}, dirs, o);
        const SourceField S = single_scattering(m, PointSource{{2, 2, 2}, 1.0}, dirs);
        CHECK(agreement(m, S, nullptr, r.single, r.single_se) >= 0.95);  // 64 voxels: t_31 tails
        CHECK(r.energy.emitted.mean + r.energy.roulette.mean ==
              test::rel(r.energy.absorbed.mean + r.energy.escaped.mean, 1e-12));
    }
    SUBCASE("very thick (optical depth 1000 across): reflectance of the semi-infinite slab") {
        // 10 x 10 x 10 voxels of sigma h = 100, sun at normal incidence on the top, isotropic
        // scattering, albedo 0.9: photons live within a few mean free paths of the top, so the
        // escaped fraction is the half-space reflectance 0.41495 (lateral leakage at the
        // edges affects < 0.5% of the power: the 1% bound holds, the 3 SE one is not asked).
        const LightingMedium m = test::uniform_medium({10, 10, 10}, 1.0, {0, 0, 0}, 1.0f, {100.0, 0.9, 0.0});
        o.paths = 200'000;
        const MonteCarloResult r = monte_carlo(m, DirectionalSource{{0, 0, -1}, 1.0}, dirs, o);
        const double R = r.energy.escaped.mean / r.energy.emitted.mean;
        MESSAGE("thick grid reflectance " << R << " +- " << r.energy.escaped.se / r.energy.emitted.mean);
        CHECK(std::fabs(R / 0.41495 - 1.0) < 0.01);
        for (float v : r.single.data) CHECK(std::isfinite(v));
        for (float v : r.multiple.data) CHECK(std::isfinite(v));
    }
    SUBCASE("very thin (optical depth 1e-6 across): nearly everything uncollided, S1 exact") {
        const LightingMedium m = test::uniform_medium({4, 4, 4}, 1.0, {0, 0, 0}, 1.0f, {2.5e-7, 1.0, 0.6});
        const MonteCarloResult r = monte_carlo(m, PointSource{{0.3, 1.9, 3.1}, 1.0}, dirs, o);
        CHECK(r.energy.escaped_by_order[0].mean / r.energy.emitted.mean > 1.0 - 1e-5);
        const SourceField S = single_scattering(m, PointSource{{0.3, 1.9, 3.1}, 1.0}, dirs);
        CHECK(agreement(m, S, nullptr, r.single, r.single_se) >= 0.95);  // 64 voxels
    }
}

TEST_CASE("bad Monte Carlo options are rejected with the field named") {
    const LightingMedium m = test::uniform_medium({2, 2, 2}, 1.0, {0, 0, 0}, 0.5f, {1.0, 0.9, 0.0});
    const auto dirs = output_directions(1);
    MonteCarloOptions o;
    o.batches = 1;
    CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 0}, 1.0}, dirs, o), doctest::Contains("batches"),
                         core::Error);
    o = {};
    o.paths = 3;
    CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 0}, 1.0}, dirs, o), doctest::Contains("paths"), core::Error);
    o = {};
    o.roulette_threshold = 0.0;
    CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 0}, 1.0}, dirs, o), doctest::Contains("roulette"),
                         core::Error);
    o = {};
    o.max_scatterings = -1;
    CHECK_THROWS_WITH_AS(monte_carlo(m, PointSource{{0, 0, 0}, 1.0}, dirs, o), doctest::Contains("max_scatterings"),
                         core::Error);
    CHECK_THROWS_WITH_AS(monte_carlo(m, DirectionalSource{{0, 0, 0}, 1.0}, dirs), doctest::Contains("sun.direction"),
                         core::Error);
}
