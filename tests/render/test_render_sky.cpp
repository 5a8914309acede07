// The static light (sun, moon, sky) and the sun at full resolution in the ray march: analytic
// boxes, a switched-off effect costing nothing (the same pixels as never having set it), the
// automatic exposure applied as a manual one would be, bad inputs named.
#include "gl_fixture.h"
#include "support/test_support.h"

#include "transport/transport.h"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

using namespace fulgur;
using test::gl_renderer;
using test::render_at;

namespace {

struct Box {
    core::Grid3<float> density;
    render::Camera cam;
};

// A 16^3 box of 100 m voxels at density 0.5 (F16: exact), kappa 1.25e-3: tau = 1 across.
Box box(render::Renderer& r) {
    Box b;
    b.density = test::make_grid({16, 16, 16}, 100.0, {0, 0, 0}, [](int, int, int) { return 0.5f; });
    r.set_volume({.density = &b.density, .extinction = 1.25e-3, .precision = render::DensityPrecision::F16});
    b.cam.position = {-1500.0, -2600.0, 2300.0};
    b.cam.target = {800.0, 800.0, 800.0};
    b.cam.vertical_fov_deg = 45.0;
    return b;
}

// The box with no flash and no sun set (each test sets the terms it checks).
Box dark_box(render::Renderer& r) {
    Box b = box(r);
    r.clear_source();
    r.clear_sun();
    return b;
}

// A coarse 4^3 static-light grid of 400 m cells over the box.
core::GridGeometry static_grid(const Box& b) {
    core::GridGeometry lg = b.density.geom;
    lg.dims = {4, 4, 4};
    lg.voxel_size = 400.0;
    return lg;
}

// The march buffer (rgba32f, `w` wide) of the volume alone, without jitter.
std::vector<float> march(render::Renderer& r, const Box& b, int W, int H, int& w) {
    render::Settings st = test::volume_only();
    st.jitter = false;
    render_at(r, b.cam, st, W, H);
    int h = 0;
    return r.read_march(w, h);
}

// The static light: every one of 26 directions holds the same colour everywhere.
void upload_constant_static(render::Renderer& r, const core::GridGeometry& g, const glm::dvec3& rgb) {
    std::vector<float> one(g.cell_count() * 3);
    for (std::size_t c = 0; c < g.cell_count(); ++c)
        for (int k = 0; k < 3; ++k) one[3 * c + std::size_t(k)] = float(rgb[k]);
    render::StaticUpload up;
    up.geometry = g;
    up.direction_count = 26;
    up.rgb.assign(26, std::span<const float>(one));
    r.upload_static(up);
}

double chord(const Box& b, const glm::dvec3& d) {
    double t0 = 0, t1 = 1e300;
    return core::clip_ray_to_box(b.cam.position, d, b.density.geom.origin, b.density.geom.upper(), t0, t1) ? t1 - t0
                                                                                                           : 0.0;
}

}  // namespace

TEST_CASE("static light in colour: L = S_rgb (1 - exp(-tau)) per channel") {
    render::Renderer& r = gl_renderer();
    const Box b = dark_box(r);
    const core::GridGeometry lg = static_grid(b);
    const glm::dvec3 S(2.0, 1.0, 0.5);
    upload_constant_static(r, lg, S);
    const int W = 40, H = 30;
    int w = 0;
    const std::vector<float> m = march(r, b, W, H, w);
    int inside = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const double T = std::exp(-1.25e-3 * 0.5 * chord(b, test::pixel_ray(b.cam, x, y, W, H)));
            const float* p = &m[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4];
            for (int c = 0; c < 3; ++c)
                // Exact for any step (pieces clipped to the chord); 1e-4 relative covers float
                // sums over ~30 pieces and the rgba32f resolve of 26 equal directions.
                CHECK(double(p[c]) == doctest::Approx(S[c] * (1.0 - T)).epsilon(1e-4).scale(1.0));
            inside += T < 1.0;
        }
    CHECK(inside > W * H / 5);
    const std::vector<float> resolved = r.read_resolved_static();
    REQUIRE(resolved.size() == lg.cell_count() * 3);
    CHECK(resolved[4] == test::rel(1.0, 1e-6));  // green of cell 1: the partition of unity
    r.clear_static();
}

TEST_CASE("the sun at full resolution: albedo p(view . sun) E T_sun, the exact phase for each ray") {
    render::Renderer& r = gl_renderer();
    const Box b = box(r);
    r.clear_source();
    r.clear_static();
    core::Grid3<float> Tsun(b.density.geom, 0.5f);  // a uniform transmittance to the sun: 0.5
    render::SunDesc sun;
    sun.direction = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
    sun.irradiance_rgb = {3.0, 2.0, 1.0};
    sun.albedo = 0.9;
    sun.g = 0.6;
    sun.transmittance = &Tsun;
    r.set_sun(sun);
    const int W = 40, H = 30;
    int w = 0;
    const std::vector<float> m = march(r, b, W, H, w);
    for (int y = 2; y < H; y += 5)
        for (int x = 2; x < W; x += 5) {
            const glm::dvec3 d = test::pixel_ray(b.cam, x, y, W, H);
            const double T = std::exp(-1.25e-3 * 0.5 * chord(b, d));
            const double p = transport::hg_phase(glm::dot(-d, sun.direction), sun.g);
            const float* px = &m[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4];
            for (int c = 0; c < 3; ++c)
                // Float phase function and R16F transmittance (0.5 is exact in half): 1e-4.
                CHECK(
                    double(px[c]) ==
                    doctest::Approx(sun.albedo * p * sun.irradiance_rgb[c] * 0.5 * (1.0 - T)).epsilon(1e-4).scale(1.0));
        }
    r.clear_sun();
}

TEST_CASE("a switched-off static light or sun costs nothing: the same pixels as never set, no resolve") {
    render::Renderer& r = gl_renderer();
    const Box b = dark_box(r);
    r.clear_static();
    render::Settings st = test::volume_only();
    st.sky = true;
    const int W = 48, H = 32;
    render_at(r, b.cam, st, W, H);
    const std::vector<std::uint8_t> none = test::gl_context().read_rgba8();
    upload_constant_static(r, static_grid(b), {1.0, 1.0, 1.0});
    core::Grid3<float> Tsun(b.density.geom, 1.0f);
    render::SunDesc sun;
    sun.irradiance_rgb = {5.0, 5.0, 5.0};
    sun.transmittance = &Tsun;
    r.set_sun(sun);
    render::Settings off = st;
    off.static_light = false;
    off.sun_light = false;
    const render::FrameStats s = render_at(r, b.cam, off, W, H);
    CHECK(test::gl_context().read_rgba8() == none);  // bit for bit: the march never samples them
    CHECK(s.wall.resolve == 0.0);                    // no resolve of the static light
    const render::FrameStats on = render_at(r, b.cam, st, W, H);
    CHECK(test::gl_context().read_rgba8() != none);
    CHECK(on.wall.resolve > 0.0);  // 26 directions: resolved toward the camera
    r.clear_static();
    r.clear_sun();
}

TEST_CASE("automatic exposure: the frame is tone mapped with the exposure it reports; adaptation and compensation") {
    render::Renderer& r = gl_renderer();
    const Box b = dark_box(r);
    const core::GridGeometry lg = static_grid(b);
    upload_constant_static(r, lg, {40.0, 40.0, 40.0});
    render::Settings st = test::volume_only();
    st.auto_exposure = true;
    const int W = 48, H = 32;
    const render::FrameStats a = render_at(r, b.cam, st, W, H);
    REQUIRE(a.metered_exposure > 0.0);
    CHECK(a.exposure == a.metered_exposure);  // no previous exposure: applied at once
    CHECK(a.wall.meter > 0.0);
    const std::vector<std::uint8_t> auto_px = test::gl_context().read_rgba8();
    render::Settings manual = test::volume_only();
    manual.exposure = a.exposure;
    const render::FrameStats m = render_at(r, b.cam, manual, W, H);
    CHECK(test::gl_context().read_rgba8() == auto_px);  // the same tone map
    CHECK(m.metered_exposure == 0.0);
    CHECK(m.wall.meter == 0.0);  // manual: no metering pass
    // Compensation: +1 stop doubles it; adaptation from a darker previous exposure: partway.
    render::Settings plus = st;
    plus.exposure_compensation = 1.0;
    CHECK(render_at(r, b.cam, plus, W, H).exposure == test::rel(2.0 * a.exposure, 1e-12));
    render::Settings adapt = st;
    adapt.previous_exposure = 0.5 * a.metered_exposure;
    adapt.adaptation_seconds = adapt.brighten_seconds;  // one time constant: 1 - 1/e of the way in log
    const render::FrameStats ad = render_at(r, b.cam, adapt, W, H);
    CHECK(std::log2(ad.exposure / adapt.previous_exposure) == test::rel(1.0 - std::exp(-1.0), 1e-9));
    r.clear_static();
}

TEST_CASE("extreme light and exposure: metered where it is, never pinned, black or NaN") {
    render::Renderer& r = gl_renderer();
    const Box b = dark_box(r);
    const core::GridGeometry lg = static_grid(b);
    render::Settings st = test::volume_only();
    st.auto_exposure = true;
    st.jitter = false;
    const int W = 48, H = 32;
    // Which pixels show the box (lit) and which are at display white, per channel byte.
    auto lit_and_white = [](const std::vector<std::uint8_t>& px) {
        std::size_t lit = 0, white = 0;
        for (std::size_t i = 0; i + 3 < px.size(); i += 4) {
            lit += (px[i] | px[i + 1] | px[i + 2]) != 0;
            white += px[i] == 255 && px[i + 1] == 255 && px[i + 2] == 255;
        }
        return std::pair{lit, white};
    };
    upload_constant_static(r, lg, {40.0, 40.0, 40.0});
    const render::FrameStats base = render_at(r, b.cam, st, W, H);
    const std::vector<std::uint8_t> base_px = test::gl_context().read_rgba8();
    const auto [base_lit, base_white] = lit_and_white(base_px);
    REQUIRE(base_lit > 100);
    REQUIRE(base_white == 0);  // the highlight guard keeps a uniformly lit box below white
    // The same light scaled as far as a scene may declare (a sun of 1e30 W/m^2 lights the cloud
    // at ~1e30): the exposure follows it (its key grows slowly with luminance, so the picture
    // brightens a little but never clips to white), and no pixel turns black from overflow.
    for (double scale : {1e10, 1e20, 1e30}) {
        CAPTURE(scale);
        upload_constant_static(r, lg, {40.0 * scale, 40.0 * scale, 40.0 * scale});
        const render::FrameStats s = render_at(r, b.cam, st, W, H);
        CHECK(std::isfinite(s.exposure));
        // exposure x luminance is the key, in [0.03, 1.03] whatever the scale: the ratio to the
        // unscaled frame's is within that range's ratio (34x), where a pinned meter is off by 1e6+.
        const double ratio = s.exposure * scale / base.exposure;
        CHECK(ratio > 1.0 / 34.0);
        CHECK(ratio < 34.0);
        const auto [lit, white] = lit_and_white(test::gl_context().read_rgba8());
        CHECK(lit == base_lit);
        CHECK(white == 0);
    }
    // A manual exposure as large as the renderer takes: every lit pixel white, the rest black
    // (no inf/inf in the tone curve turning the brightest pixels black).
    upload_constant_static(r, lg, {40.0, 40.0, 40.0});
    render::Settings manual = test::volume_only();
    manual.jitter = false;
    manual.exposure = 1e38;
    render_at(r, b.cam, manual, W, H);
    const auto [lit, white] = lit_and_white(test::gl_context().read_rgba8());
    CHECK(lit >= base_lit);  // the box's faintest edge pixels, black at the metered exposure, too
    CHECK(white == lit);
    manual.exposure = 2e38;  // past float32's largest power of ten: refused, named
    CHECK_THROWS_WITH_AS(render_at(r, b.cam, manual, W, H), doctest::Contains("settings.exposure"), core::Error);
    r.clear_static();
}

TEST_CASE("static light and sun: bad inputs are rejected naming the field") {
    render::Renderer& r = gl_renderer();
    const Box b = box(r);
    core::GridGeometry lg = b.density.geom;
    lg.dims = {2, 2, 2};
    std::vector<float> v(lg.cell_count() * 3, 1.0f);
    render::StaticUpload up;
    up.geometry = lg;
    up.direction_count = 26;
    up.rgb.assign(6, std::span<const float>(v));
    CHECK_THROWS_WITH_AS(r.upload_static(up), doctest::Contains("needs all 26 directions"), core::Error);
    up.direction_count = 6;
    std::vector<float> bad = v;
    bad[7] = std::nanf("");
    up.rgb[3] = std::span<const float>(bad);
    CHECK_THROWS_WITH_AS(r.upload_static(up), doctest::Contains("direction 3: value of cell 2 channel 1"), core::Error);
    up.rgb[3] = std::span<const float>(v.data(), v.size() - 3);
    CHECK_THROWS_WITH_AS(r.upload_static(up), doctest::Contains("x 3"), core::Error);
    up.rgb[3] = std::span<const float>(v);
    for (const double albedo : {-0.1, 1.5, double(std::nanf(""))}) {
        up.albedo = albedo;
        CHECK_THROWS_WITH_AS(r.upload_static(up), doctest::Contains("upload_static: albedo"), core::Error);
    }
    render::SunDesc s;
    s.direction = {0, 0, 0};
    CHECK_THROWS_WITH_AS(r.set_sun(s), doctest::Contains("set_sun: direction"), core::Error);
    s.direction = {0, 0, -1};
    core::Grid3<float> wrong(lg, 1.0f);
    s.transmittance = &wrong;
    CHECK_THROWS_WITH_AS(r.set_sun(s), doctest::Contains("set_sun: transmittance"), core::Error);
    core::Grid3<float> out_of_range(b.density.geom, 1.5f);
    s.transmittance = &out_of_range;
    CHECK_THROWS_WITH_AS(r.set_sun(s), doctest::Contains("outside [0, 1]"), core::Error);
    render::Settings st;
    st.highlight_fraction = 0.0;
    CHECK_THROWS_WITH_AS(render_at(r, b.cam, st, 8, 8), doctest::Contains("settings.highlight_fraction"), core::Error);
    r.clear_sun();
    r.clear_static();
}
