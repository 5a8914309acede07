// The sun's and the sky's light through the lattice on a small cloud: energy bookkeeping,
// what the lattice is fed, linearity, refinement, Monte Carlo, the dome's quadrature and the
// full-resolution transmittance to the sun.
#include "lumpy_cloud.h"
#include "mc_errors.h"
#include "sky/sky.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <numbers>

using namespace fulgur;

namespace {

// The lumpy cloud in a 20 x 18 x 14 grid of 100 m voxels.
transport::LightingMedium blob(transport::Medium optics = {0.015, 0.95, 0.6}) {
    return test::lumpy_cloud({20, 18, 14}, {700.0, 650.0, 450.0}, 700.0, optics);
}

solve::Media media_of(const transport::LightingMedium& m) { return solve::Media{m, m, 1, {}, {}}; }

sky::SolveSettings settings(sky::Method method = sky::Method::Hybrid) {
    sky::SolveSettings s;
    s.method = method;
    // The sun's single scattering at 1e-2 is within 1.2% of the brute-force reference in any
    // bright voxel (docs/transport.md, "The sun"): far inside these tests' comparisons with Monte
    // Carlo. In the optically thin cloud below (optical depth 1e-6) T_in is smooth and the
    // sky's 1e-4 bound holds at this tolerance as it did at 1e-4.
    s.single_options.tolerance = 1e-2;
    s.lattice.tolerance = 1e-6;
    return s;
}

double relative_energy_error(const sky::LightField& f) {
    return std::fabs(f.injected_total - (f.absorbed_total + f.escaped_total + f.stored)) / f.injected_total;
}

}  // namespace

TEST_CASE("energy: injected = absorbed + escaped + stored, both methods, two sun directions") {
    const transport::LightingMedium m = blob();
    const auto dirs = transport::output_directions(26);
    for (const glm::dvec3 d : {glm::dvec3(0.3, 0.2, -1.0), glm::dvec3(-0.9, 0.1, -0.25)})
        for (sky::Method method : {sky::Method::Hybrid, sky::Method::Lattice}) {
            const transport::DirectionalSource sun{d, 1.0};
            const sky::LightField f = sky::solve_directional(media_of(m), std::span(&sun, 1), dirs, settings(method));
            INFO(sky::to_string(method) << " direction " << d.x << "," << d.y << "," << d.z);
            CHECK(f.converged);
            REQUIRE(f.injected_total > 0.0);
            // Double bookkeeping of float32 lattice sums: the project's 1e-6 energy criterion.
            CHECK(relative_energy_error(f) < 1e-6);
            if (method == sky::Method::Hybrid) {
                // The lattice is fed exactly the power scattered once: sigma_s phi1 h^3 summed.
                CHECK(f.injected_per_step == test::rel(f.first_scattered_power, 1e-5));  // float emission
                CHECK(!f.single.data.empty());
            } else {
                // Geist's injection: E times the grid's projected area enters every step.
                const glm::dvec3 u = glm::normalize(d), ext = m.density.geom.extent();
                const double area =
                    ext.y * ext.z * std::fabs(u.x) + ext.x * ext.z * std::fabs(u.y) + ext.x * ext.y * std::fabs(u.z);
                CHECK(f.injected_per_step == test::rel(area, 1e-6));  // float32 link values
                CHECK(f.single.data.empty());
            }
        }
}

TEST_CASE("linearity and units: two suns together, irradiance scaling, the uniform sky as the sum of its two ends") {
    const transport::LightingMedium m = blob();
    const auto dirs = transport::output_directions(18);
    const sky::SolveSettings st = settings();
    const transport::DirectionalSource a{{0.3, 0.2, -1.0}, 1.0}, b{{-0.5, 0.4, -0.6}, 3.0};
    const transport::DirectionalSource both[] = {a, b};
    const sky::LightField fa = sky::solve_directional(media_of(m), std::span(&a, 1), dirs, st);
    const sky::LightField fb = sky::solve_directional(media_of(m), std::span(&b, 1), dirs, st);
    const sky::LightField fab = sky::solve_directional(media_of(m), both, dirs, st);
    double err = 0.0, ref = 0.0;
    for (std::size_t i = 0; i < fab.multiple.data.size(); ++i) {
        const double sum = double(fa.multiple.data[i]) + double(fb.multiple.data[i]);
        err += (double(fab.multiple.data[i]) - sum) * (double(fab.multiple.data[i]) - sum);
        ref += sum * sum;
    }
    // Not exactly linear: the lattice's emission in each voxel is scaled to sigma_s phi1 h^3
    // (the 18-direction quadrature of the phase function is off by up to ~35% for g = 0.6,
    // docs/lattice-boltzmann.md "Sources"), and that factor depends on the mix of incoming
    // directions. Measured 2.4% for these two suns; 5% bounds it.
    CHECK(std::sqrt(err / ref) < 0.05);
    // Exactly linear in the irradiance.
    const transport::DirectionalSource a2{a.direction, 2.0};
    const sky::LightField f2 = sky::solve_directional(media_of(m), std::span(&a2, 1), dirs, st);
    for (std::size_t i = 0; i < f2.multiple.data.size(); ++i)
        CHECK(f2.multiple.data[i] == test::rel(2.0 * fa.multiple.data[i], 1e-4));  // steady state 1e-6/step
    for (std::size_t i = 0; i < fab.single.data.size(); ++i)
        CHECK(fab.single.data[i] == test::rel(fa.single.data[i] + fb.single.data[i], 1e-5));  // float sums

    sky::SolveSettings few = st;
    few.sky_samples = 8;
    const sky::SkyField g = sky::solve_sky(media_of(m), false, dirs, few);
    const sky::SkyField u = sky::solve_sky(media_of(m), true, dirs, few);
    REQUIRE(u.zenith.empty());
    REQUIRE(!g.zenith.empty());
    REQUIRE(!g.horizon.empty());
    for (std::size_t i = 0; i < u.uniform.single.data.size(); ++i)
        CHECK(u.uniform.single.data[i] ==
              test::rel(g.zenith.single.data[i] + g.horizon.single.data[i], 1e-5));  // float sums
    // The zenith basis carries more of the light at the top of the cloud, the horizon basis
    // more at its sides (the gradient weights the directions it comes from).
    CHECK(g.zenith.first_scattered_power > 0.0);
    CHECK(g.horizon.first_scattered_power > 0.0);
}

TEST_CASE("dome samples: equal solid angles summing to 2 pi, exact irradiance of a uniform sky") {
    for (int n : {1, 8, 32, 97}) {
        const std::vector<sky::DomeSample> d = sky::dome_samples(n);
        double omega = 0.0, cos_weighted = 0.0;
        for (const sky::DomeSample& s : d) {
            CHECK(s.toward.z > 0.0);
            CHECK(glm::length(s.toward) == test::rel(1.0, 1e-12));  // unit, rounding only
            omega += s.solid_angle;
            cos_weighted += s.solid_angle * s.toward.z;
        }
        CHECK(omega == test::rel(2.0 * std::numbers::pi, 1e-12));
        // The midpoint rule in z = cos(zenith angle) integrates z exactly: E = pi L.
        CHECK(cos_weighted == test::rel(std::numbers::pi, 1e-12));
    }
}

TEST_CASE("the sky against physics: a uniform sky of radiance 1 over an optically thin cloud") {
    // Isotropic scattering in a cloud too thin to shadow itself: every voxel sees the whole
    // upper hemisphere of radiance L = 1, so S1 = albedo / (4 pi) * 2 pi L = albedo / 2, and
    // nothing is scattered twice. The dome's quadrature is exact here (its solid angles sum to
    // 2 pi exactly); the cloud's optical depth (1e-6 across, <= 1e-4 along the most grazing
    // sample's path) bounds what the transmittance takes away: 1e-4 relative.
    core::GridGeometry g{{8, 8, 6}, 100.0, {-400.0, -400.0, 0.0}};
    transport::LightingMedium m;
    m.density = core::Grid3<float>(g, 1.0f);
    m.optics = {1.25e-9, 0.9, 0.0};  // sigma_t 800 m = 1e-6
    const auto dirs = transport::output_directions(1);
    const sky::SkyField f = sky::solve_sky(media_of(m), true, dirs, settings());
    float lo = 1e30f, hi = -1e30f, most_multiple = 0.0f;
    for (std::size_t i = 0; i < g.cell_count(); ++i) {
        lo = std::min(lo, f.uniform.single.data[i]);
        hi = std::max(hi, f.uniform.single.data[i]);
        most_multiple = std::max(most_multiple, std::fabs(f.uniform.multiple.data[i]));
    }
    MESSAGE("uniform sky over a thin cloud: S1 in [" << lo << ", " << hi
                                                     << "], physics 0.45; |S_multiple| <= " << most_multiple);
    CHECK(double(lo) == test::rel(0.45, 1e-4));
    CHECK(double(hi) == test::rel(0.45, 1e-4));
    CHECK(most_multiple <= 1e-5f);  // order 2 is of the order of the optical depth (1e-6) times S1
}

TEST_CASE("refinement: S averaged onto the lighting grid, or kept on the transport grid to the same average") {
    // A refined transport grid is averaged onto the lighting grid; transport.static_light.grid
    // "transport" only leaves out that average: averaging the kept S gives the lighting grid's
    // S to the last bit (the same fine fields, the same sums).
    const transport::LightingMedium fine = blob();
    solve::Media averaged;
    averaged.transport = fine;
    averaged.lighting.density = core::downsample(fine.density, 2);
    averaged.lighting.optics = fine.optics;
    averaged.refine = 2;
    const solve::Media kept{fine, fine, 1, {}, {}};
    const transport::DirectionalSource sun{{0.3, 0.2, -1.0}, 1.0};
    const std::vector<glm::dvec3> dirs = transport::output_directions(26);
    sky::SolveSettings st = settings();
    st.refine = 2;  // the media's (sky::static_media keeps them together)
    const sky::LightField a = sky::solve_directional(averaged, std::span(&sun, 1), dirs, st);
    CHECK(a.single.geom == averaged.lighting.density.geom);
    CHECK(a.multiple.geom == averaged.lighting.density.geom);
    st.keep_transport_grid = true;
    const sky::LightField k = sky::solve_directional(kept, std::span(&sun, 1), dirs, st);
    CHECK(k.single.geom == fine.density.geom);
    CHECK(k.multiple.geom == fine.density.geom);
    const transport::SourceField ks = transport::block_average(k.single, 2);
    const transport::SourceField km = transport::block_average(k.multiple, 2);
    REQUIRE(ks.data.size() == a.single.data.size());
    REQUIRE(km.data.size() == a.multiple.data.size());
    CHECK(ks.data == a.single.data);
    CHECK(km.data == a.multiple.data);
    // Fine structure the average removes: S varies within a lighting voxel (else keeping it
    // would buy nothing). The largest spread of the kept S over a 2x2x2 block, against S's
    // peak, is well above float rounding.
    float spread = 0.0f, peak = 0.0f;
    const core::Int3 d = fine.density.dims();
    const std::span<const float> s0 = k.multiple.direction(0);
    for (int z = 0; z + 1 < d.z; z += 2)
        for (int y = 0; y + 1 < d.y; y += 2)
            for (int x = 0; x + 1 < d.x; x += 2) {
                float lo = 1e30f, hi = -1e30f;
                for (int c = 0; c < 8; ++c) {
                    const float v = s0[fine.density.geom.index(x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2))];
                    lo = std::min(lo, v);
                    hi = std::max(hi, v);
                }
                spread = std::max(spread, hi - lo);
                peak = std::max(peak, hi);
            }
    CHECK(spread > 0.05f * peak);
}

TEST_CASE("isotropic scattering: one output direction; Monte Carlo agrees with both methods") {
    // Monte Carlo with the same directional source in the same medium: single scattering is
    // exact (the hybrid's), multiple scattering is where the lattice's error lives.
    const transport::LightingMedium m = blob({0.015, 0.95, 0.0});
    const auto dirs = transport::output_directions(1);
    const transport::DirectionalSource sun{{0.3, 0.2, -1.0}, 1.0};
    transport::MonteCarloOptions mo;
    mo.paths = 2'000'000;
    mo.halves = true;
    mo.seed = 9;
    const transport::MonteCarloResult mc = transport::monte_carlo(m, sun, dirs, mo);
    const sky::LightField h = sky::solve_directional(media_of(m), std::span(&sun, 1), dirs, settings());
    const sky::LightField l =
        sky::solve_directional(media_of(m), std::span(&sun, 1), dirs, settings(sky::Method::Lattice));
    REQUIRE(h.single.directions.size() == 1);
    test::SunMcErrors e;
    for (std::size_t i = 0; i < m.density.size(); ++i)
        if (m.density.data[i] > 0.05f) e.add(h, l, mc, i);  // cloud voxels
    auto& [single, multiple, total_h, total_l] = e;
    std::printf(
        "blob vs Monte Carlo (2M paths, noise single %.2f%% multiple %.2f%%): hybrid single %.2f%%, multiple "
        "%.2f%%, total %.2f%%; lattice (Geist) total %.2f%%\n",
        100 * mc.noise.single, 100 * mc.noise.multiple, 100 * single.value(), 100 * multiple.value(),
        100 * total_h.value(), 100 * total_l.value());
    // Exact single scattering against the Monte Carlo order 1: the noise (measured 1.58%
    // against a noise of 1.50%; 2.5% allows the estimate of the noise its own spread).
    CHECK(single.value() < 0.025);
    // The lattice's error on this small blob of hop optical depths up to ~1.5: measured 7.9%
    // (multiple), 4.6% (hybrid total), 13.3% (Geist's injection: the uncollided beam on 18
    // lattice directions too). The bounds add ~40% for noise and platform differences.
    CHECK(multiple.value() < 0.11);
    CHECK(total_h.value() < 0.065);
    CHECK(total_l.value() < 0.19);

    // Order 2 exact (the static light's default): order 2 by Monte Carlo through the medium
    // (here the same grid: refine 1), the lattice for orders >= 3. The lattice's error then
    // falls on dimmer light: the multiple part moves toward the Monte Carlo.
    solve::Media two = media_of(m);
    two.full = m;
    sky::SolveSettings st2 = settings();
    st2.exact_orders = 2;
    st2.order2_paths = 400'000;
    const sky::LightField h2 = sky::solve_directional(two, std::span(&sun, 1), dirs, st2);
    core::RelativeL2 multiple2;
    for (std::size_t i = 0; i < m.density.size(); ++i)
        if (m.density.data[i] > 0.05f) multiple2.add(h2.multiple.data[i], mc.multiple.data[i]);
    std::printf("blob, order 2 exact: multiple %.2f%% (the lattice for orders >= 2: %.2f%%)\n", 100 * multiple2.value(),
                100 * multiple.value());
    CHECK(h2.single.data == h.single.data);  // order 1 is the same exact single scattering
    // Measured 6.7% against the lattice's 7.9% (the reference's noise 1.6% in both): at least
    // half a point better (the solves are deterministic; the margin is for other platforms).
    CHECK(multiple2.value() < multiple.value() - 0.005);
    CHECK(std::fabs(h2.injected_total - (h2.absorbed_total + h2.escaped_total + h2.stored)) < 1e-6 * h2.injected_total);
}

TEST_CASE("sun transmittance at full resolution: exact where the renderer reads it, 1 elsewhere") {
    const transport::LightingMedium m = blob();
    const glm::dvec3 d = glm::normalize(glm::dvec3(0.4, -0.2, -1.0));
    const core::Grid3<float> T = sky::sun_transmittance(m.density, m.optics.extinction, d);
    const core::GridGeometry& g = m.density.geom;
    std::size_t computed = 0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const float t = T.at(i, j, k);
                REQUIRE(t >= 0.0f);
                REQUIRE(t <= 1.0f);
                const glm::dvec3 x = g.centre(i, j, k);
                const double exact = std::exp(-transport::optical_depth_to_sun(m, x, d));
                const bool face =
                    i == 0 || j == 0 || k == 0 || i == g.dims.x - 1 || j == g.dims.y - 1 || k == g.dims.z - 1;
                if (face || m.density.at(i, j, k) > 0.0f) {
                    CHECK(double(t) == test::rel(exact, 1e-6));  // float storage of the exact value
                    ++computed;
                }
            }
    CHECK(computed > 0);
    // Under the blob the shadow is deep; above it, no cloud is in the way.
    CHECK(T.at(10, 9, 0) < 0.5f);
    CHECK(T.at(10, 9, g.dims.z - 1) == 1.0f);
    CHECK_THROWS_AS(sky::sun_transmittance(m.density, m.optics.extinction, glm::dvec3(0.0)), core::Error);
}

TEST_CASE("bad input is rejected with the field named") {
    const transport::LightingMedium m = blob();
    const auto dirs = transport::output_directions(26);
    const transport::DirectionalSource zero{{0, 0, 0}, 1.0}, nan{{0, 0, -1}, std::nan("")};
    CHECK_THROWS_WITH_AS(sky::solve_directional(media_of(m), std::span(&zero, 1), dirs, settings()),
                         doctest::Contains("sun.direction"), core::Error);
    CHECK_THROWS_WITH_AS(sky::solve_directional(media_of(m), std::span(&nan, 1), dirs, settings()),
                         doctest::Contains("sun.irradiance"), core::Error);
    CHECK_THROWS_WITH_AS(sky::parse_method("exact", "sky.method"), doctest::Contains("sky.method"), core::Error);
    CHECK(sky::parse_method("lattice", "x") == sky::Method::Lattice);
}
