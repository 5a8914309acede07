// The glare pass against the eye's point-spread function it stands for: a point of light
// rendered with glare spreads its energy as render::glare_energy_within says, conserves it,
// and a frame without a drawn channel is untouched.
#include "gl_fixture.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

using namespace fulgur;
using test::gl_renderer;
using test::render_at;

namespace {

struct PointFrame {
    std::vector<float> rgb;  // read_hdr
    double total = 0.0;      // sum of the luminance
    double cx = 0.0, cy = 0.0;
};

// A channel segment one pixel long across the line of sight (a 1 x 1.5-pixel ribbon: its free
// ends are not extended) at the view's centre, nothing else: no volume, sky, ground or glow.
PointFrame render_point(render::Settings st, int size, double fov) {
    render::Renderer& r = gl_renderer();
    r.clear_volume();
    r.clear_source();
    r.clear_static();
    render::LitChannel b;
    const float half_px = float(8000.0 * std::tan(fov * std::numbers::pi / 360.0) / size);  // half a pixel at 8 km
    b.segments.push_back({{-half_px, 0.0f, 3000.0f}, {half_px, 0.0f, 3000.0f}, 1000.0f, 2.0f});
    r.set_channel(b);
    render::Camera cam;
    cam.position = {0, -8000, 3000};
    cam.target = {0, 0, 3000};
    cam.vertical_fov_deg = fov;
    st.sky = st.ground = st.glow = false;
    st.bolt = true;
    st.star_radiance = 0.0;
    st.flash_colour = {1.0, 1.0, 1.0};
    render_at(r, cam, st, size, size);
    PointFrame f;
    f.rgb = r.read_hdr();
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const double v = f.rgb[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 3];
            f.total += v;
            f.cx += v * (x + 0.5);
            f.cy += v * (y + 0.5);
        }
    f.cx /= f.total;
    f.cy /= f.total;
    return f;
}

}  // namespace

TEST_CASE("glare: a point's light spreads as the eye's point-spread function, energy conserved") {
    const int size = 256;
    // 1 and 0.5: glare_first.frag's fixed reads of the core; 0.75: its general footprint
    // (a pixel on a footprint's boundary shared by two march pixels; a plain mean of the pixels
    // touched gave 0.79 of the energy here).
    for (const double scale : {1.0, 0.5, 0.75}) {
        CAPTURE(scale);
        render::Settings st;
        st.dither = false;
        st.internal_scale = scale;
        const double fov = 20.0, pixel_deg = fov / size;
        const PointFrame off = render_point(st, size, fov);
        st.glare = true;
        const PointFrame on = render_point(st, size, fov);
        // Energy: the fit keeps P's energy within the frame's half diagonal; the pyramid clamps
        // at the frame's edges, which counts the little light its widest levels carry there
        // more than once (measured -0.2%, -0.2% and +0.7% at the three scales): within 1.5%.
        const double reach =
            std::atan(std::tan(fov * std::numbers::pi / 360.0) * std::sqrt(2.0)) * 180.0 / std::numbers::pi;
        CHECK(on.total / off.total == test::rel(render::glare_energy_within(reach), 0.015));
        for (const double R_px : {2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 120.0}) {
            double within = 0.0;
            for (int y = 0; y < size; ++y)
                for (int x = 0; x < size; ++x)
                    if (std::hypot(x + 0.5 - off.cx, y + 0.5 - off.cy) <= R_px)
                        within += on.rgb[(std::size_t(y) * std::size_t(size) + std::size_t(x)) * 3];
            const double rendered = within / off.total, model = render::glare_energy_within(R_px * pixel_deg);
            CAPTURE(R_px);
            MESSAGE("scale " << scale << ", R " << R_px << " px: energy within " << rendered << ", P " << model);
            // The fit's own error (<= 0.011 of the point's light, test_glare_model) plus the
            // pyramid's filters being Gaussians only approximately and the source a 1 x 1.5-pixel
            // ribbon: measured <= 0.014 at every radius and scale.
            CHECK(std::abs(rendered - model) <= 0.02);
        }
    }
    gl_renderer().set_channel({});
}

TEST_CASE("glare: frames that draw no channel are the same with it on or off") {
    render::Renderer& r = gl_renderer();
    r.clear_volume();
    r.clear_source();
    r.set_channel({});
    render::Camera cam;
    render::Settings st;
    st.dither = false;
    render_at(r, cam, st, 64, 36);
    const std::vector<float> off = r.read_hdr();
    st.glare = true;
    const render::FrameStats s = render_at(r, cam, st, 64, 36);
    CHECK(r.read_hdr() == off);
    CHECK(s.wall.glare == 0.0);
    CHECK(s.glare_keep == 1.0);
}

TEST_CASE(
    "glare: frames a few pixels across draw, and as without it where a march pixel is wider than the half diagonal") {
    // 1x1 to 3x3 at 50 degrees: the frame's half diagonal is 33.4 degrees; a march pixel spans
    // 50 degrees at one march pixel (every size at scale 0.3: lround(0.3-0.9) = 1; 1x1 at 1),
    // where the pyramid has no surround to spread to, and 17-25 degrees at 2x2 and 3x3 at 1,
    // where it spreads as at any size.
    for (const int size : {1, 2, 3})
        for (const double scale : {1.0, 0.3}) {
            CAPTURE(size);
            CAPTURE(scale);
            render::Settings st;
            st.dither = false;
            st.internal_scale = scale;
            const PointFrame off = render_point(st, size, 50.0);
            st.glare = true;
            const PointFrame on = render_point(st, size, 50.0);
            const int march_rows = std::max(1, int(std::lround(size * scale)));
            CHECK(std::isfinite(on.total));
            if (march_rows == 1)
                CHECK(on.rgb == off.rgb);
            else
                CHECK(on.rgb != off.rgb);
        }
    gl_renderer().set_channel({});
}
