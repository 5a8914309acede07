// Images of the synthetic storm (procedural cumulonimbus, a branching cloud-to-ground bolt
// whose channel lights the cloud from inside, glow, night sky, lit ground) through the whole
// pipeline: a golden-image test, and (with FULGUR_WRITE_DOC_IMAGES=1) the documentation
// image docs/images/render_synthetic.png.
#include "gl_fixture.h"
#include "golden.h"

#include "support/synthetic_storm.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

using namespace fulgur;

namespace {

/// Renders the synthetic storm at w x h and returns the 8-bit frame (rows top to bottom).
/// With `detail`, the cloud carries that sub-voxel detail (eroded in the march); with `rain`,
/// rain falls under it (cloud::make_rain with those parameters).
std::vector<std::uint8_t> synthetic_storm(const core::Int3& dims, double voxel, int w, int h, bool dither = true,
                                          const std::optional<cloud::SubvoxelDetail>& detail = std::nullopt,
                                          const std::optional<cloud::RainParams>& rain = std::nullopt) {
    render::Renderer& r = test::gl_renderer();
    const synthetic::Storm storm = synthetic::storm(dims, voxel);
    std::optional<cloud::RainField> field;
    if (rain) field = cloud::make_rain(storm.density, *rain);
    r.set_volume({.density = &storm.density,
                  .extinction = storm.extinction,
                  .detail = detail,
                  .rain = field ? &*field : nullptr});
    r.upload_source(synthetic::needed_upload(r, storm));
    r.set_channel(storm.bolt);
    render::Settings st = storm.settings;
    st.dither = dither;
    test::render_at(r, storm.camera, st, w, h);
    std::vector<std::uint8_t> rgba = test::gl_context().read_rgba8();
    r.set_channel({});
    r.clear_source();
    return rgba;
}

}  // namespace

TEST_CASE("golden: synthetic storm") {
    const int W = 192, H = 108;
    const auto rgba = synthetic_storm({64, 64, 48}, 200.0, W, H);
    // llvmpipe's results differ slightly between CPUs (vector width, FMA): allow 0.5% of the
    // pixels to move by more than 6 levels (a star or the bolt's edge moving by a fraction of
    // a pixel) and a mean difference of 0.5 levels; a changed scene, camera, tone map or
    // lighting moves far more.
    const test::GoldenTolerance tol{.pixel_threshold = 6, .max_failing_fraction = 0.005, .max_mean_diff = 0.5};
    const auto res = test::compare_golden(test::source_dir() / "tests/render/golden/synthetic_storm.png", W, H, rgba,
                                          tol, std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / "golden");
    MESSAGE(res.message);
    CHECK(res.passed);
}

// A golden of the synthetic storm with an effect, at the undetailed golden's tolerance and for
// its reasons; and the effect shows: the frame is more than half a level away from the plain
// storm's on average (twice the golden's mean tolerance).
static void effect_golden(const std::string& name, const std::vector<std::uint8_t>& rgba, int w, int h) {
    const test::GoldenTolerance tol{.pixel_threshold = 6, .max_failing_fraction = 0.005, .max_mean_diff = 0.5};
    const auto res = test::compare_golden(test::source_dir() / ("tests/render/golden/" + name + ".png"), w, h, rgba,
                                          tol, std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / "golden");
    MESSAGE(res.message);
    CHECK(res.passed);
    const auto plain = synthetic_storm({64, 64, 48}, 200.0, w, h, true);
    double diff = 0.0;
    for (std::size_t i = 0; i < rgba.size(); ++i) diff += std::abs(int(rgba[i]) - int(plain[i]));
    MESSAGE(name, ": mean difference from the plain storm ", diff / double(rgba.size()), " levels");
    CHECK(diff / double(rgba.size()) > 0.5);
}

TEST_CASE("golden: synthetic storm with sub-voxel detail") {
    // Billows of 2 voxels (400 m), 3 octaves, strength 0.6: the same storm, its edges carved
    // (measured 1.06 levels from the plain storm).
    cloud::SubvoxelDetail d;
    d.seed = 5;
    d.scale = 400.0;
    d.octaves = 3;
    d.strength = 0.6;
    const int W = 192, H = 108;
    effect_golden("synthetic_storm_detail", synthetic_storm({64, 64, 48}, 200.0, W, H, true, d), W, H);
}

TEST_CASE("golden: synthetic storm with a rain shaft") {
    // 25 mm/h under the tower, leaning 400 m per km downwind, streaks of 300 m (measured 3.9
    // levels from the dry storm).
    cloud::RainParams rain;
    rain.rate = 25.0;
    rain.shear = {400.0, 0.0};
    rain.streak_scale = 300.0;
    const int W = 192, H = 108;
    effect_golden("synthetic_storm_rain", synthetic_storm({64, 64, 48}, 200.0, W, H, true, std::nullopt, rain), W, H);
}

TEST_CASE("documentation image (only with FULGUR_WRITE_DOC_IMAGES=1)") {
    const char* e = std::getenv("FULGUR_WRITE_DOC_IMAGES");
    if (!e || std::strcmp(e, "1") != 0) return;
    const int W = 960, H = 540;
    // No dither: the documentation image must stay small as a PNG (dither noise does not compress).
    const auto rgba = synthetic_storm({128, 128, 96}, 100.0, W, H, false);
    std::vector<std::uint8_t> rgb(std::size_t(W) * H * 3);
    for (std::size_t p = 0; p < std::size_t(W) * H; ++p)
        for (int c = 0; c < 3; ++c) rgb[p * 3 + std::size_t(c)] = rgba[p * 4 + std::size_t(c)];
    const auto path = test::source_dir() / "docs/images/render_synthetic.png";
    std::filesystem::create_directories(path.parent_path());
    core::write_png(path, W, H, 3, rgb);
    MESSAGE("wrote " << path.string());
}
