// The acceptance check of exact single scattering on the DEFAULT cloud: exact single scattering equals the Monte
// Carlo order-1 estimate within 3 standard errors for at least 99% of the cloud voxels.
#include "cloud/cloud.h"
#include "scene/scene.h"
#include "support/test_support.h"
#include "transport/transport.h"

#include <doctest/doctest.h>

#include <cmath>

using namespace fulgur;
using namespace fulgur::transport;

TEST_CASE("default storm cloud: single scattering equals the Monte Carlo order-1 estimate") {
    scene::Scene sc = scene::load_scene(test::source_dir() / "content/scenes/storm.json");
    // The acceptance check is specified on the 36x36x20 lighting grid of 500 m voxels
    // (downsample 4). The scene now bakes on 750 m voxels (downsample 6, docs/bake.md), where
    // the default tolerance gives 98.9% within 3 SE and tolerance 1e-4 gives 99.2%: larger
    // voxels see larger transmittance variation inside them, so 1e-3 is slightly optimistic
    // there (measured when the default changed; docs/transport.md).
    sc.lighting_downsample = 4;
    const core::Grid3<float> density = scene::make_density(sc);
    const LightingMedium m = scene::make_lighting_medium(sc, density);
    REQUIRE(!sc.point_lights.empty());
    const PointSource light{sc.point_lights[0].position, 1.0};
    // The scene's light sits below the cloud base (and, in the default scene, exactly on a
    // corner of the lighting grid: a hard case for both solvers).
    CHECK(light.position.z < cloud::cloud_base_height(density));
    const auto dirs = output_directions(sc.effective_directions());

    const SourceField S = single_scattering(m, light, dirs);  // default tolerance 1e-3
    MonteCarloOptions o;
    o.paths = 1'000'000;    // ~2 s on 2 cores; median relative SE of cloud voxels ~1.5%
    o.max_scatterings = 0;  // only order 1 is compared: the multiple-scattering part is not traced
    o.seed = 2;
    const MonteCarloResult r = monte_carlo(m, light, dirs, o);

    std::size_t voxels = 0, values = 0, within = 0, zero_se = 0;
    for (std::size_t c = 0; c < S.cells(); ++c) {
        if (!(m.density.data[c] > 0.0f)) continue;
        ++voxels;
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            const std::size_t i = k * S.cells() + c;
            ++values;
            zero_se += r.single_se.data[i] == 0.0f;
            if (std::fabs(S.data[i] - r.single.data[i]) <= 3.0 * r.single_se.data[i]) ++within;
        }
    }
    const double fraction = double(within) / double(values);
    MESSAGE(voxels << " cloud voxels x " << dirs.size() << " directions: " << 100.0 * fraction << "% within 3 SE ("
                   << zero_se << " with zero SE)");
    CHECK(voxels > 1000);
    // The acceptance criterion. With S exact, 32-batch t statistics put ~0.5% beyond 3 SE; the
    // measured fraction is ~99.3%, so the quadrature error at the default tolerance is well
    // inside the Monte Carlo noise (docs/transport.md has the dependence on the tolerance).
    CHECK(fraction >= 0.99);
}
