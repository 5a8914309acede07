// Golden image of the synthetic storm (procedural cloud, flash inside it, branching bolt,
// glow, sky, ground) at 192x108, through the whole pipeline.
#include "gl_fixture.h"
#include "golden.h"

#include "render/synthetic.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

using namespace fulgur;

TEST_CASE("golden: synthetic storm") {
    render::Renderer& r = test::gl_renderer();
    const double kappa = 0.004;
    const auto density = render::synthetic::cumulus({64, 64, 48}, 200.0, 7);
    r.set_volume({.density = &density, .extinction = kappa});
    const auto lg = render::synthetic::lighting_geometry(density.geom, 4);
    const glm::dvec3 flash(300.0, -200.0, 3200.0);
    const auto S = render::synthetic::point_flash_source(density, kappa, lg, 26, flash, 1e6);
    const render::Camera cam = render::Camera::orbit({0.0, 0.0, 3800.0}, 21000.0, -70.0, 6.0, 50.0);
    render::SourceUpload up{lg, 26, {}, {}};
    for (const auto& u : r.needed_directions(cam, lg, 26)) {
        up.directions.push_back(u.index);
        up.values.emplace_back(S.data() + std::size_t(u.index) * lg.cell_count(), lg.cell_count());
    }
    r.upload_source(up);
    r.set_bolt(render::synthetic::bolt(3, flash, 1e6 / 3000.0));
    render::Settings st;
    st.exposure = 2500.0;
    const int W = 192, H = 108;
    test::render_at(r, cam, st, W, H);
    const auto rgba = test::gl_context().read_rgba8();
    // llvmpipe's results differ slightly between CPUs (vector width, FMA): allow 0.5% of the
    // pixels to move by more than 6 levels (e.g. a star or the bolt's edge moving by a
    // fraction of a pixel) and a mean difference of 0.5 levels.
    const test::GoldenTolerance tol{.pixel_threshold = 6, .max_failing_fraction = 0.005, .max_mean_diff = 0.5};
    const auto res = test::compare_golden(test::source_dir() / "tests/render/golden/synthetic_storm.png", W, H, rgba, tol,
                                          std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / "golden");
    MESSAGE(res.message);
    CHECK(res.passed);
    r.set_bolt({});
}
