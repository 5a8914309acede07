// The platform layer: headless (OSMesa) contexts in both pixel formats, and a GLFW window
// (run under xvfb-run by CTest) rendering the same frame as the headless context.
#include "platform/platform.h"
#include "render/render.h"

#include "core/core.h"

#include <doctest/doctest.h>

#include <chrono>
#include <cstdlib>
#include <thread>

using namespace fulgur;

namespace {

/// A frame of the sky and ground only (no volume): deterministic, cheap, non-trivial.
std::vector<std::uint8_t> sky_frame(platform::Context& ctx) {
    render::Renderer r(ctx.get_proc_address());
    render::Settings st;
    st.sky_zenith = 0.05 * glm::dvec3(0.45, 0.6, 1.0);  // bright enough to give mid-grey levels
    st.sky_horizon = 0.05 * glm::dvec3(2.4, 2.3, 2.6);
    st.star_radiance = 2.0;
    st.dither = false;
    const render::Camera cam = render::Camera::orbit({0, 0, 1000}, 5000, 20, 5, 60);
    r.render(cam, st, ctx.width(), ctx.height());
    return ctx.read_rgba8();
}

}  // namespace

TEST_CASE("headless contexts: GL 4.5 core through OSMesa, RGBA8 and float buffers") {
    auto ctx = platform::create_headless({.width = 64, .height = 48});
    CHECK(ctx->headless());
    CHECK(ctx->native_window() == nullptr);
    CHECK(ctx->description().find("4.5") != std::string::npos);
    CHECK(ctx->width() == 64);
    const auto a = sky_frame(*ctx);
    REQUIRE(a.size() == 64u * 48u * 4u);
    // The top row is sky, the bottom row ground: the image is not uniform and right side up
    // (sky brighter than the dark ground at the bottom edge).
    auto lum = [&](const std::vector<std::uint8_t>& img, int y) {
        double s = 0;
        for (int x = 0; x < 64; ++x) s += img[(std::size_t(y) * 64 + std::size_t(x)) * 4 + 2];
        return s / 64;
    };
    CHECK(lum(a, 0) > lum(a, 47) + 5.0);
    ctx->resize(32, 16);
    CHECK(ctx->width() == 32);
    CHECK(ctx->read_rgba8().size() == 32u * 16u * 4u);
    // A float buffer holds the same frame (8-bit conversion of the same values).
    auto f = platform::create_headless({.width = 64, .height = 48, .format = platform::PixelFormat::RGBA32F});
    const auto b = sky_frame(*f);
    int worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(int(a[i]) - int(b[i])));
    CHECK(worst <= 1);  // rounding of the float buffer vs the driver's 8-bit conversion
    CHECK_THROWS_AS(platform::create_headless({.width = 0, .height = 4}), core::Error);
}

TEST_CASE("window context (GLFW) renders what the headless context renders") {
    if (!std::getenv("DISPLAY")) {
        // CTest runs this executable under xvfb-run; without a display the window code
        // must say so clearly rather than crash.
        CHECK(!platform::display_available());
        CHECK_THROWS_AS(platform::create_window({.width = 64, .height = 48}), core::Error);
        MESSAGE("no DISPLAY: only the error path was tested");
        return;
    }
    // A freshly started Xvfb can refuse the first connections for a moment (seen when two
    // servers start at once): wait up to 5 s for it.
    bool ready = false;
    for (int i = 0; i < 50 && !(ready = platform::display_available()); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    REQUIRE(ready);
    auto win = platform::create_window({.width = 64, .height = 48, .title = "fulgur test", .visible = false});
    CHECK(!win->headless());
    CHECK(win->native_window() != nullptr);
    CHECK(win->description().find("4.5") != std::string::npos);
    REQUIRE(win->width() == 64);
    REQUIRE(win->height() == 48);
    const auto a = sky_frame(*win);
    CHECK(win->poll_events());
    win->present();
    auto head = platform::create_headless({.width = 64, .height = 48});
    const auto b = sky_frame(*head);
    int worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (i % 4 != 3) worst = std::max(worst, std::abs(int(a[i]) - int(b[i])));
    CHECK(worst <= 1);  // same driver (llvmpipe) through GLX and OSMesa
}
