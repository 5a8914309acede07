// The static light against its truth on the default storm (content/scenes/storm.json): the sun
// solved as the renderer's cache solves it (sky::solve_directional on sky::static_media with
// the scene's static settings: the lighting grid refined by 3, order 2 by Monte Carlo) against
// Monte Carlo of the sun from the grid's boundary through the full-resolution density, tallied
// on the lighting grid, at three sun elevations: relative L2 of S over the cloud, single and
// multiple scattering apart, and the ratio of their whole-cloud totals (the figures
// docs/sky.md quotes; fulgur-study static-frontier measures every configuration).
#include "sky/sky.h"

#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>

using namespace fulgur;

TEST_CASE("default storm: the static light's sun solve against its truth at elevations 60, 25 and 5 degrees") {
    const scene::Scene s = scene::load_scene(test::source_dir() / "content/scenes/storm.json");
    const core::Grid3<float> density = scene::make_density(s);
    const solve::Media media = sky::static_media(s, density);
    const sky::SolveSettings st = sky::solve_settings(s, density);
    REQUIRE(st.refine == 3);  // 750 m lighting voxels of 3 optical depths at density 1
    REQUIRE(st.exact_orders == 2);
    const solve::Media full = solve::make_media(s, density, 1, true);
    const auto dirs = transport::output_directions(s.effective_directions());
    const std::vector<float>& rho = media.lighting.density.data;
    const std::size_t cells = rho.size();
    struct Row {
        double elevation, azimuth, single_ratio, multiple_ratio;
    };
    for (const Row r :
         {Row{60.0, -60.0, 0.9831, 0.9711}, Row{25.0, 30.0, 0.9754, 0.9810}, Row{5.0, 150.0, 0.9734, 0.9799}}) {
        const transport::DirectionalSource sun{scene::sun_direction(r.elevation, r.azimuth), 1.0};
        const sky::LightField h = sky::solve_directional(media, std::span(&sun, 1), dirs, st);
        transport::MonteCarloOptions mo;
        mo.paths = 1'000'000;
        mo.seed = 17;
        mo.halves = true;
        const transport::MonteCarloResult truth =
            transport::monte_carlo(full.full, sun, media.lighting.density.geom, dirs, mo);
        core::RelativeL2 single, multiple, total;
        double hs = 0.0, hm = 0.0;
        for (std::size_t m = 0; m < dirs.size(); ++m)
            for (std::size_t i = 0; i < cells; ++i) {
                if (!(rho[i] > 0.0f)) continue;  // the cloud: lighting cells holding density
                const std::size_t k = m * cells + i;
                single.add(h.single.data[k], truth.single.data[k]);
                multiple.add(h.multiple.data[k], truth.multiple.data[k]);
                total.add(double(h.single.data[k]) + h.multiple.data[k],
                          double(truth.single.data[k]) + truth.multiple.data[k]);
                hs += h.single.data[k];
                hm += h.multiple.data[k];
            }
        // The truth's sums cover every cell holding density, as the loop above.
        const double ratio_single = hs / truth.sums.single.mean, ratio_multiple = hm / truth.sums.multiple.mean;
        const double se_single = ratio_single * truth.sums.single.se / truth.sums.single.mean,
                     se_multiple = ratio_multiple * truth.sums.multiple.se / truth.sums.multiple.mean;
        std::printf(
            "storm, sun at %4.1f deg: single %.2f%% (truth noise %.2f%%), multiple %.2f%% (noise %.2f%%), total "
            "%.2f%%; totals' ratio single %.4f +- %.4f, multiple %.4f +- %.4f; lattice %d steps\n",
            r.elevation, 100 * single.value(), 100 * truth.noise.single, 100 * multiple.value(),
            100 * truth.noise.multiple, 100 * total.value(), ratio_single, se_single, ratio_multiple, se_multiple,
            h.iterations);
        CHECK(h.converged);
        // Measured (1M paths; truth noise 2.1-2.5% single, 3.3-4.4% multiple, which the errors
        // include; at 2M: single 2.9-3.5%, multiple 8.2-9.4%, total 4.9-5.8%): single
        // 3.3-3.7%, multiple 8.3-9.8%, total 5.3-6.2%: within the aims of 10% total and 15%
        // multiple with margin (the 750 m grid solved before: 21-25% total).
        CHECK(single.value() < 0.06);
        CHECK(multiple.value() < 0.12);
        CHECK(total.value() < 0.08);
        // The whole-cloud totals, pinned to what this solve gives against a 2M-path truth (single
        // 0.973-0.983: the 250 m transport grid's medium against the 125 m truth; multiple
        // 0.971-0.981) within 0.002 (the solve's own order-2 noise: 400k paths, 0.1-0.2% on a
        // total) + 4 x this truth's standard error (1M paths: 0.17-0.34%): a 5% change of
        // either part moves its ratio by ~0.049 and fails (the band is at most 0.016).
        CHECK(std::fabs(ratio_single - r.single_ratio) <= 0.002 + 4.0 * se_single);
        CHECK(std::fabs(ratio_multiple - r.multiple_ratio) <= 0.002 + 4.0 * se_multiple);
        CHECK(std::fabs(h.injected_total - (h.absorbed_total + h.escaped_total + h.stored)) < 1e-6 * h.injected_total);
    }
}
