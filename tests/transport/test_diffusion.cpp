// Flux-limited diffusion (transport/diffusion.h) against closed forms: a point emission in a
// homogeneous medium against diffusion's Green's function, the discrete energy balance, the flux
// limiter's bound, the source function's mean over the sphere and its sign; the ray-cast
// first-scattered emission against the exact quadrature's uncollided fluence; the cast through a
// finer density against the quadrature averaged over coarse cells, and its exact totals; hostile
// inputs and determinism.
#include "transport/diffusion.h"

#include "core/core.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>
#include <vector>

using namespace fulgur;

namespace {

// A cube of n^3 voxels of h metres centred on the origin, density 1.
transport::LightingMedium cube(int n, double h, transport::Medium optics) {
    return test::uniform_medium({n, n, n}, h, glm::dvec3(-0.5 * n * h), 1.0f, optics);
}

// The same cube with the density rho(x) at each voxel's centre x.
template <class F>
transport::LightingMedium cube(int n, double h, transport::Medium optics, F&& rho) {
    transport::LightingMedium m = cube(n, h, optics);
    const core::GridGeometry& g = m.density.geom;
    for (std::size_t c = 0; c < g.cell_count(); ++c) {
        const core::Int3 p = g.unindex(c);
        m.density.data[c] = float(rho(g.centre(p.x, p.y, p.z)));
    }
    return m;
}

}  // namespace

TEST_CASE("diffusion: a point emission in a homogeneous medium follows diffusion's Green's function") {
    // sigma_t 0.01/m (one free path per 100 m voxel), albedo 0.9, g 0.6: D = 82 m,
    // L = sqrt(D / sigma_a) = 287 m; the cube's faces are 2 km (7 L) away, so the vacuum
    // boundary changes phi within 1 km by under e^-5.
    const transport::Medium optics{0.01, 0.9, 0.6};
    const int n = 41;
    const double h = 100.0, V = h * h * h;
    const transport::LightingMedium m = cube(n, h, optics);
    std::vector<double> q(m.density.geom.cell_count(), 0.0);
    const std::size_t centre = m.density.geom.index(n / 2, n / 2, n / 2);
    const double P = 1e6;  // W, all in the centre voxel
    q[centre] = P / V;
    transport::DiffusionOptions plain;
    plain.limiter_passes = 0;
    plain.tolerance = 1e-6;
    const transport::DiffusionField f = transport::solve_diffusion(m, q, plain);
    CHECK(f.converged);
    const double st = 0.01, D = 1.0 / (3.0 * st * (1.0 - 0.9 * 0.6)), L = std::sqrt(D / (st * 0.1));
    double worst = 0.0;
    for (int d = 7; d <= 8; ++d)
        for (const core::Int3 o :
             {core::Int3{d, 0, 0}, core::Int3{0, 0, -d}, core::Int3{d, d, 0}, core::Int3{d, d, d}}) {
            const double r = h * std::sqrt(double(o.x * o.x + o.y * o.y + o.z * o.z));
            const double exact = P * std::exp(-r / L) / (4.0 * std::numbers::pi * D * r);
            const double mine = f.fluence[m.density.geom.index(n / 2 + o.x, n / 2 + o.y, n / 2 + o.z)];
            worst = std::max(worst, std::fabs(mine / exact - 1.0));
        }
    MESSAGE("largest relative difference from the Green's function at 7-8 voxels: " << worst);
    // Measured 0.036 (+3.6% along the axes, -2% along the body diagonals): the seven-point
    // stencil's discrete Green's function is anisotropic by terms in (h / r)^2 (+9% / -4% at 3
    // voxels). A diffusivity 5% off moves every ratio by ~5% and fails one of the two
    // directions; the energy balance below pins the solution's scale exactly.
    CHECK(worst < 0.045);

    // Energy balance, exact for the discrete equations: what is absorbed in the cells plus what
    // leaves through the vacuum faces is what was emitted (to the solver's 1e-6 residual).
    core::CompensatedSum absorbed;
    for (std::size_t c = 0; c < f.fluence.size(); ++c) absorbed.add(st * 0.1 * double(f.fluence[c]) * V);
    double leaked = 0.0;
    const core::GridGeometry& g = m.density.geom;
    for (std::size_t c = 0; c < f.fluence.size(); ++c) {
        const core::Int3 p = g.unindex(c);
        const int faces = (p.x == 0) + (p.x == n - 1) + (p.y == 0) + (p.y == n - 1) + (p.z == 0) + (p.z == n - 1);
        leaked += faces * h * h * D / (0.5 * h + 2.0 * D) * double(f.fluence[c]);
    }
    MESSAGE("absorbed " << absorbed.value() / P << " + leaked " << leaked / P << " of the emitted power");
    // Float storage of phi (1e-7) and the 1e-6 residual.
    CHECK((absorbed.value() + leaked) / P == doctest::Approx(1.0).epsilon(1e-5));
}

TEST_CASE("diffusion: the limiter keeps |F| <= phi; a thin cloud's light spreads less than plain diffusion says") {
    // An optically thin cube: 0.2 free paths per voxel, 4 across the whole cube.
    const transport::Medium optics{0.002, 0.99, 0.6};
    const int n = 21;
    const double h = 100.0;
    const transport::LightingMedium m = cube(n, h, optics);
    std::vector<double> q(m.density.geom.cell_count(), 0.0);
    q[m.density.geom.index(n / 2, n / 2, n / 2)] = 1.0;
    transport::DiffusionOptions plain, limited;
    plain.limiter_passes = 0;
    const transport::DiffusionField fp = transport::solve_diffusion(m, q, plain);
    const transport::DiffusionField fl = transport::solve_diffusion(m, q, limited);
    CHECK(fl.converged);
    double worst = 0.0;
    for (std::size_t c = 0; c < fl.fluence.size(); ++c) {
        REQUIRE(std::isfinite(fl.fluence[c]));
        REQUIRE(fl.fluence[c] >= 0.0f);
        if (fl.fluence[c] > 0.0f) worst = std::max(worst, double(glm::length(fl.flux[c])) / fl.fluence[c]);
    }
    double plain_worst = 0.0;
    for (std::size_t c = 0; c < fp.fluence.size(); ++c)
        if (fp.fluence[c] > 0.0f) plain_worst = std::max(plain_worst, double(glm::length(fp.flux[c])) / fp.fluence[c]);
    MESSAGE("largest |F| / phi with the limiter: " << worst << ", plain diffusion " << plain_worst);
    // |F| = lambda(R) R phi < phi for the D a pass uses; the lagged R (from the pass before)
    // lets the last pass exceed it by what phi changed in it: measured 1.08 after the default
    // 2 passes (0.90 after 4), where plain diffusion's flux is several times phi.
    CHECK(worst < 1.15);
    CHECK(plain_worst > 2.0 * worst);
    // Plain diffusion is far too diffusive where the light streams: D = 1 / (3 sigma_tr) is
    // 410 m here, the limited D at most phi / |grad phi|. The limited fluence is higher at the
    // source (less leaks away) and falls faster.
    const std::size_t c0 = m.density.geom.index(n / 2, n / 2, n / 2);
    CHECK(fl.fluence[c0] > fp.fluence[c0]);
}

TEST_CASE("diffusion: the source function's mean over the sphere is a phi / (4 pi); it is never negative") {
    const transport::Medium optics{0.01, 0.95, 0.8};
    const int n = 9;
    const transport::LightingMedium m = cube(n, 100.0, optics);
    std::vector<double> q(m.density.geom.cell_count(), 0.0);
    q[m.density.geom.index(2, 4, 4)] = 1.0;  // off-centre: strong flux across the cube
    const transport::DiffusionField f = transport::solve_diffusion(m, q);
    const std::vector<glm::dvec3> dirs = core::fibonacci_sphere(4096);
    const std::size_t cells = f.fluence.size();
    std::vector<float> S(dirs.size() * cells, 0.0f);
    transport::add_diffusion_source(m, f, dirs, 2.0, S);
    double worst = 0.0, strongest = 0.0;
    for (std::size_t c = 0; c < cells; ++c) {
        double sum = 0.0;
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            REQUIRE(S[k * cells + c] >= 0.0f);
            sum += S[k * cells + c];
        }
        const double expected = 2.0 * 0.95 * f.fluence[c] * 0.25 / std::numbers::pi;
        worst = std::max(worst, std::fabs(sum / double(dirs.size()) / expected - 1.0));
        strongest = std::max(strongest, double(glm::length(f.flux[c])) / f.fluence[c]);
    }
    MESSAGE("mean over 4096 directions against a phi / (4 pi): " << worst << "; largest |F| / phi " << strongest);
    CHECK(strongest > 0.3);  // the lobes are far from isotropic
    // 4096 equal-area directions integrate an HG lobe of g <= 0.8 x 0.99 to ~1e-4.
    CHECK(worst < 1e-3);
}

TEST_CASE("diffusion: the ray-cast first-scattered emission and single scattering match the exact quadrature's") {
    // A blob of varying density around a point source: the emission a sigma_t phi1 from
    // 2048 rays against transport::single_scattering's uncollided fluence (voxel averages).
    const transport::Medium optics{0.004, 0.99, 0.6};
    const int n = 16;
    const double h = 250.0;
    const transport::LightingMedium m = cube(n, h, optics, [](const glm::dvec3& x) {
        return std::max(0.0, 1.0 - glm::length(x - glm::dvec3(300.0, 0.0, 400.0)) / 1800.0);
    });
    const core::GridGeometry& g = m.density.geom;
    const transport::PointSource src{glm::dvec3(-120.0, 70.0, -200.0), 3.0};
    std::vector<double> cast;
    transport::add_first_scattered_emission(m, std::span(&src, 1), 2048, 1, cast);
    core::Grid3<float> phi1;
    transport::SingleScatteringOptions so;
    so.tolerance = 1e-3;
    so.uncollided_fluence = &phi1;
    const std::vector<glm::dvec3> one = {glm::dvec3(0, 0, 1)};
    (void)transport::single_scattering(m, src, one, so);
    core::CompensatedSum d2, r2, mine, ref;
    for (std::size_t c = 0; c < g.cell_count(); ++c) {
        const double exact = optics.albedo * m.sigma_t(c) * double(phi1.data[c]);
        d2.add((cast[c] - exact) * (cast[c] - exact));
        r2.add(exact * exact);
        mine.add(cast[c]);
        ref.add(exact);
    }
    const double e = std::sqrt(d2.value() / r2.value());
    MESSAGE("relative L2 against the quadrature: " << e << ", ratio of totals " << mine.value() / ref.value());
    // Measured 0.03 and 1.000: 2048 rays still sample the voxels next to the source unevenly
    // (the 1/r^2 peak), the total is exact to the rays' quadrature of the sphere.
    CHECK(e < 0.06);
    CHECK(mine.value() / ref.value() == doctest::Approx(1.0).epsilon(0.01));

    // The same cast's single scattering against the exact quadrature's, per direction, over the
    // cloud's voxels (S where nothing scatters reaches no image); its emission is the one above,
    // bit for bit.
    const std::vector<glm::dvec3> dirs = {glm::dvec3(0, 0, 1), glm::normalize(glm::dvec3(1, -1, 0.3)),
                                          glm::dvec3(-1, 0, 0)};
    std::vector<double> emission, single;
    transport::add_point_scattering(m, std::span(&src, 1), 2048, 1, dirs, emission, single);
    CHECK(emission == cast);
    const transport::SourceField exact1 = transport::single_scattering(m, src, dirs, so);
    const std::size_t cells = g.cell_count();
    for (std::size_t k = 0; k < dirs.size(); ++k) {
        core::CompensatedSum s2, q2, t1, r1;
        for (std::size_t c = 0; c < cells; ++c) {
            if (!(m.density.data[c] > 0.0f)) continue;  // the cast leaves clear voxels at 0
            const double mine1 = single[k * cells + c], ref1 = exact1.data[k * cells + c];
            s2.add((mine1 - ref1) * (mine1 - ref1));
            q2.add(ref1 * ref1);
            t1.add(mine1);
            r1.add(ref1);
        }
        const double ek = std::sqrt(s2.value() / q2.value()), ratio = t1.value() / r1.value();
        MESSAGE("direction " << k << ": single scattering's relative L2 against the quadrature " << ek
                             << ", ratio of totals " << ratio);
        // Measured 0.025, 0.032 and 0.041 (the rays' sampling of the voxels next to the source,
        // as for the emission), totals within 0.3%; a single part 5% off fails the ratio in
        // every direction.
        CHECK(ek < 0.06);
        CHECK(ratio == doctest::Approx(1.0).epsilon(0.02));
    }
}

TEST_CASE("diffusion: the cast through a finer density averages S over each coarse cell by volume, exactly per ray") {
    // A cloud of 125 m voxels with a sharp base (clear below z = 250 m, halfway up a coarse cell; a blob above) under a
    // coarse grid of 500 m cells: the truth's S on the coarse grid is the volume average of the
    // fine grid's S, which the cast reproduces, and which the coarse density's own cast misses
    // where a cell holds both clear air and cloud.
    const transport::Medium optics{0.004, 0.99, 0.6};
    const int n = 24, nest = 4;
    const double h = 125.0;
    const transport::LightingMedium fine = cube(n, h, optics, [](const glm::dvec3& x) {
        const double blob = std::max(0.0, 1.0 - glm::length(x - glm::dvec3(200.0, -100.0, 600.0)) / 1400.0);
        return x.z > 250.0 ? 0.3 + 0.7 * blob : 0.0;
    });
    const core::GridGeometry& g = fine.density.geom;
    core::GridGeometry coarse = g;
    coarse.voxel_size = h * nest;
    coarse.dims = {n / nest, n / nest, n / nest};
    const transport::PointSource src{glm::dvec3(-90.0, 40.0, -180.0), 2.0};  // below the base
    const std::vector<glm::dvec3> dirs = {glm::dvec3(0, 0, 1), glm::normalize(glm::dvec3(1, -1, 0.3)),
                                          glm::dvec3(-1, 0, 0)};
    std::vector<double> emission, single;
    transport::add_point_scattering_fine(fine, coarse, std::span(&src, 1), 4096, 1, dirs, emission, single);

    transport::SingleScatteringOptions so;
    so.tolerance = 1e-4;
    core::Grid3<float> phi1;
    so.uncollided_fluence = &phi1;
    const transport::SourceField exact =
        transport::block_average(transport::single_scattering(fine, src, dirs, so), nest);
    // The exact emission a sigma_t phi1, averaged the same way.
    transport::SourceField q(g, std::vector<glm::dvec3>{dirs[0]});
    for (std::size_t c = 0; c < g.cell_count(); ++c)
        q.data[c] = float(optics.albedo * fine.sigma_t(c) * double(phi1.data[c]));
    const transport::SourceField exact_q = transport::block_average(q, nest);
    // The coarse density's own cast, for contrast.
    transport::LightingMedium lm{core::downsample(fine.density, nest), optics};
    std::vector<double> lm_emission, lm_single;
    transport::add_point_scattering(lm, std::span(&src, 1), 4096, 1, dirs, lm_emission, lm_single);
    REQUIRE(lm.density.geom == coarse);

    const std::size_t cells = coarse.cell_count();
    auto error = [&](std::span<const double> mine, std::span<const float> ref, std::size_t k, double& ratio) {
        core::CompensatedSum d2, r2, t1, r1;
        for (std::size_t c = 0; c < cells; ++c) {
            if (!(lm.density.data[c] > 0.0f)) continue;  // cells with cloud: what an image sees
            const double a = mine[k * cells + c], b = ref[k * cells + c];
            d2.add((a - b) * (a - b));
            r2.add(b * b);
            t1.add(a);
            r1.add(b);
        }
        ratio = t1.value() / r1.value();
        return std::sqrt(d2.value() / r2.value());
    };
    double ratio = 0.0;
    const double eq = error(emission, exact_q.data, 0, ratio);
    MESSAGE("emission against the volume-averaged quadrature: " << eq << ", ratio of totals " << ratio);
    // Measured 0.0052 and 1.0001: what 4096 rays leave of the cells next to the source (their
    // sampling of the 1/r^2 peak); the bound is 2x that. A 5% emission fails the ratio.
    CHECK(eq < 0.01);
    CHECK(ratio == doctest::Approx(1.0).epsilon(0.01));
    for (std::size_t k = 0; k < dirs.size(); ++k) {
        const double ek = error(single, exact.data, k, ratio);
        double lm_ratio = 0.0;
        const double lm_ek = error(lm_single, exact.data, k, lm_ratio);
        MESSAGE("direction " << k << ": single " << ek << " (ratio " << ratio << "); the coarse density's cast "
                             << lm_ek << " (ratio " << lm_ratio << ")");
        // Measured 0.0016-0.0022, totals within 0.06%; the bound on the L2 is the emission's.
        // A single part 5% off fails the ratio. The coarse density's cast is 19-33% off here,
        // 0.68-0.82 of the totals: it spreads the cloud of the cells across the base over their
        // clear lower half, where the source's light is brightest.
        CHECK(ek < 0.01);
        CHECK(ratio == doctest::Approx(1.0).epsilon(0.01));
        CHECK(lm_ek > 10.0 * ek);
    }

    // With the coarse density beside it the cast crosses clear cells a cell at a time: the
    // same sums to round-off.
    auto rel_l2 = [](const std::vector<double>& a, const std::vector<double>& b) {
        core::CompensatedSum dd, rr;
        for (std::size_t i = 0; i < a.size(); ++i) {
            dd.add((a[i] - b[i]) * (a[i] - b[i]));
            rr.add(b[i] * b[i]);
        }
        return std::sqrt(dd.value() / rr.value());
    };
    std::vector<double> e3, s3;
    transport::add_point_scattering_fine(fine, coarse, std::span(&src, 1), 4096, 1, dirs, e3, s3, &lm.density);
    REQUIRE(s3.size() == single.size());
    CHECK(rel_l2(e3, emission) < 1e-12);
    CHECK(rel_l2(s3, single) < 1e-12);

    // Grids that do not nest (`onto` 1 mm off) take each voxel's cell by its midpoint: the
    // same field but for the stretches within 1 mm of a cell's face.
    core::GridGeometry shifted = coarse;
    shifted.origin += glm::dvec3(1e-3);
    std::vector<double> e2, s2;
    transport::add_point_scattering_fine(fine, shifted, std::span(&src, 1), 4096, 1, dirs, e2, s2);
    CHECK(rel_l2(s2, single) < 1e-4);
}

TEST_CASE("diffusion: the fine cast's totals are exact: a I 4 pi of emission, a I / sigma of isotropic S") {
    // A homogeneous cube 40 optical depths from its centre to each face: every ray stops at
    // optical depth 30 (e^-30 ~ 1e-13 of its light left). With exact transmittance per voxel
    // the whole-grid sums are exact up to that and round-off.
    const transport::Medium optics{0.01, 0.9, 0.0};
    const transport::LightingMedium m = cube(80, 100.0, optics);
    core::GridGeometry coarse = m.density.geom;
    coarse.voxel_size *= 4;
    coarse.dims = {20, 20, 20};
    const transport::PointSource src{glm::dvec3(13.0, -7.0, 21.0), 5.0};
    const std::vector<glm::dvec3> dirs = {glm::dvec3(0, 0, 1)};
    std::vector<double> emission, single;
    // Every cell holds cloud: the walk through `onto`'s cells descends into each.
    const core::Grid3<float> coarse_density = core::downsample(m.density, 4);
    transport::add_point_scattering_fine(m, coarse, std::span(&src, 1), 64, 9, dirs, emission, single, &coarse_density);
    const double V = std::pow(coarse.voxel_size, 3);
    core::CompensatedSum e, s1;
    for (std::size_t c = 0; c < emission.size(); ++c) {
        e.add(emission[c] * V);
        s1.add(single[c] * V);
    }
    const double a = optics.albedo, I = src.intensity, sigma = optics.extinction;
    CHECK(e.value() / (a * I * 4.0 * std::numbers::pi) == doctest::Approx(1.0).epsilon(1e-9));
    CHECK(s1.value() / (a * I / sigma) == doctest::Approx(1.0).epsilon(1e-9));
}

TEST_CASE("diffusion: hostile inputs give zeros or finite fields; the same input the same bits") {
    const transport::Medium optics{0.01, 0.99, 0.6};
    const transport::LightingMedium m = cube(8, 100.0, optics);
    const std::size_t cells = m.density.geom.cell_count();
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    std::vector<double> q(cells, 0.0);
    q[3] = nan;
    q[5] = inf;
    q[7] = -1.0;
    const transport::DiffusionField none = transport::solve_diffusion(m, q);
    for (const float v : none.fluence) REQUIRE(v == 0.0f);
    // An empty medium: nothing to solve.
    const transport::LightingMedium empty = test::uniform_medium({4, 4, 4}, 100.0, glm::dvec3(0.0), 0.0f, optics);
    std::vector<double> q_empty(empty.density.geom.cell_count(), 1.0);
    const transport::DiffusionField fe = transport::solve_diffusion(empty, q_empty);
    for (const float v : fe.fluence) REQUIRE(v == 0.0f);
    // Sources: non-finite ones add nothing; one absurdly far away ends (counted steps).
    std::vector<double> e;
    const std::vector<transport::PointSource> bad = {{glm::dvec3(nan, 0, 0), 1.0},
                                                     {glm::dvec3(0.0), inf},
                                                     {glm::dvec3(1e300, -1e300, 1e300), 1.0},
                                                     {glm::dvec3(1e9, 0.0, 0.0), 1e6}};
    transport::add_first_scattered_emission(m, bad, 64, 7, e);
    REQUIRE(e.size() == cells);
    for (const double v : e) REQUIRE(std::isfinite(v));
    std::vector<double> fe_e, fe_s;
    const std::vector<glm::dvec3> up = {glm::dvec3(0, 0, 1)};
    transport::add_point_scattering_fine(m, m.density.geom, bad, 64, 7, up, fe_e, fe_s);
    REQUIRE(fe_e.size() == cells);
    REQUIRE(fe_s.size() == cells);
    for (const double v : fe_e) REQUIRE(std::isfinite(v));
    for (const double v : fe_s) REQUIRE(std::isfinite(v));
    // A grid `onto` off to the side of the fine one: rays leave it unlit where they do not overlap.
    core::GridGeometry aside = m.density.geom;
    aside.origin += glm::dvec3(1e6, 0.0, 0.0);
    std::vector<double> as_e, as_s;
    const std::vector<transport::PointSource> one = {{glm::dvec3(30.0, -20.0, 10.0), 1.0}};
    transport::add_point_scattering_fine(m, aside, one, 64, 7, up, as_e, as_s);
    for (const double v : as_s) REQUIRE(v == 0.0);
    // Deterministic.
    const std::vector<transport::PointSource> src = {{glm::dvec3(30.0, -20.0, 10.0), 1.0}};
    std::vector<double> a, b;
    transport::add_first_scattered_emission(m, src, 32, 3, a);
    transport::add_first_scattered_emission(m, src, 32, 3, b);
    CHECK(a == b);
    std::vector<double> fa_e, fa_s, fb_e, fb_s;
    transport::add_point_scattering_fine(m, m.density.geom, src, 32, 3, up, fa_e, fa_s);
    transport::add_point_scattering_fine(m, m.density.geom, src, 32, 3, up, fb_e, fb_s);
    CHECK(fa_e == fb_e);
    CHECK(fa_s == fb_s);
    const transport::DiffusionField fa = transport::solve_diffusion(m, a), fb = transport::solve_diffusion(m, b);
    CHECK(fa.fluence == fb.fluence);
    CHECK(fa.converged);
}
