// Rain in the ray march: its extinction (analytic slab), the channel's light it scatters, its
// shadow on the ground's flash light, and no rain (none given, or switched off) drawing the
// same pixels as a volume without it.
#include "gl_fixture.h"

#include "cloud/rain.h"
#include "support/test_support.h"
#include "transport/transport.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>

using namespace fulgur;
using test::gl_renderer;
using test::render_at;

namespace {

// 24 x 24 x 12 voxels of 100 m (2.4 x 2.4 x 1.2 km from z = 0): a cloud-free box.
core::GridGeometry box() { return {{24, 24, 12}, 100.0, glm::dvec3(-1200.0, -1200.0, 0.0)}; }

// Uniform rain of `sigma` (1/m) in every voxel (so trilinear filtering is exact), top at 1200 m.
cloud::RainField uniform_rain(double sigma) {
    cloud::RainField r;
    r.extinction = core::Grid3<float>(box(), float(sigma));
    r.top = 1200.0;
    r.max_extinction = sigma;
    return r;
}

// The only light: a channel from a to b (1 W/sr/m, radius 2 m), no S.
void light_by_channel(render::Renderer& r, glm::vec3 a, glm::vec3 b) {
    render::LitChannel ch;
    ch.segments.push_back({a, b, 1.0f, 2.0f});
    r.set_channel(ch);
    r.clear_source();
}

// A pixel's ray d and where it enters and leaves box() (t0 < t1); false when it misses.
bool box_chord(const render::Camera& cam, int x, int y, int w, int h, glm::dvec3& d, double& t0, double& t1) {
    d = test::pixel_ray(cam, x, y, w, h);
    t0 = 0.0;
    t1 = 1e300;
    const core::GridGeometry g = box();
    return core::clip_ray_to_box(cam.position, d, g.origin, g.upper(), t0, t1);
}

// The march with only the sky lit (horizon and zenith of other colours), no jitter, no early exit.
render::Settings sky_lit() {
    render::Settings st = test::volume_only();
    st.sky = true;
    st.star_radiance = 0.0;
    st.jitter = false;
    st.early_exit = false;
    st.sky_horizon = {0.5, 0.25, 0.125};
    st.sky_zenith = {0.05, 0.1, 0.2};  // the two ends apart: a gradient, not one colour
    return st;
}

// Uniform rain of `sigma` in box() seen from `pos` (toward the box's centre, 40 degrees of
// field, 64 x 48): the frame without rain (B) and with it (I); f(d, opacity, c, got, pixel) for
// each colour channel c of each pixel whose ray crosses the box over 10 m or more (shorter
// chords: the float rounding of their ends), with got = I - B (1 - opacity) the rain's own light.
template <class F>
void rain_light_per_pixel(render::Renderer& r, const glm::dvec3& pos, const render::Settings& st,
                          const cloud::RainField& rain, double sigma, F f) {
    const core::Grid3<float> empty(box(), 0.0f);
    const int W = 64, H = 48;
    render::Camera cam;
    cam.position = pos;
    cam.target = {0.0, 0.0, 600.0};
    cam.vertical_fov_deg = 40.0;
    const auto shot = [&](const cloud::RainField* rf) {
        r.set_volume({.density = &empty, .extinction = 4e-3, .precision = render::DensityPrecision::F16, .rain = rf});
        render_at(r, cam, st, W, H);
        int w = 0, h = 0;
        return r.read_march(w, h);
    };
    const std::vector<float> sky = shot(nullptr), img = shot(&rain);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            glm::dvec3 d;
            double t0, t1;
            if (!box_chord(cam, x, y, W, H, d, t0, t1) || t1 - t0 < 10.0) continue;
            const double opacity = 1.0 - std::exp(-sigma * (t1 - t0));
            for (int c = 0; c < 3; ++c) {
                const std::size_t at = (std::size_t(y) * W + std::size_t(x)) * 4 + std::size_t(c);
                f(d, opacity, c, img[at] - double(sky[at]) * (1.0 - opacity), double(img[at]));
            }
        }
}

// Henyey-Greenstein's phase function per steradian (volume.glsl's hg_phase, in double).
double hg(double cos_theta, double g) {
    const double a = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (4.0 * std::numbers::pi * a * std::sqrt(a));
}

render::Camera side_camera() {
    render::Camera cam;
    cam.position = {-300.0, -4000.0, 600.0};
    cam.target = {0.0, 0.0, 600.0};
    cam.vertical_fov_deg = 30.0;
    return cam;
}

constexpr int kSideW = 64, kSideH = 48;

// The march (RGBA, kSideW x kSideH) of box() holding no cloud and `rain`, seen by side_camera()
// without jitter or early exit, lit by the renderer's channel alone (no S).
std::vector<float> side_march(render::Renderer& r, const cloud::RainField& rain) {
    const core::Grid3<float> empty(box(), 0.0f);
    r.set_volume({.density = &empty, .extinction = 4e-3, .precision = render::DensityPrecision::F16, .rain = &rain});
    r.clear_source();
    render::Settings st = test::volume_only();
    st.jitter = false;
    st.early_exit = false;
    render_at(r, side_camera(), st, kSideW, kSideH);
    int w = 0, h = 0;
    return r.read_march(w, h);
}

// The rain's light from a channel from `lo` straight up to `hi` of `power` W/sr per metre (the
// march's 8 lights of equal power at the middles of its eighths), summed on the CPU over the
// march's pieces (cut at t0 + (k + 1/2) dt, sampled at their midpoints, r^2 floored at
// (50 m)^2) with the exact HG phase (g 0.85, albedo 1): sigma(p) the rain's extinction the march
// reads, tau(light, p, r) the optical depth from a light to p (r its distance, floored as r^2
// is). Per pixel of W x H; `unattenuated`: the same light summed without tau.
template <class Sigma, class Tau>
std::vector<double> cpu_rain_light(const render::Camera& cam, int W, int H, const glm::dvec3& lo, const glm::dvec3& hi,
                                   double power, Sigma sigma, Tau tau, double& unattenuated) {
    constexpr int kLights = 8;  // frame_setup.cpp's kRainLights
    const double intensity = power * glm::length(hi - lo) / kLights, dt = box().voxel_size;
    std::vector<double> expected(std::size_t(W) * H, 0.0);
    unattenuated = 0.0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            glm::dvec3 d;
            double t0, t1;
            if (!box_chord(cam, x, y, W, H, d, t0, t1)) continue;
            double T = 1.0, L = 0.0, a = t0;
            for (int k = 0; a < t1; ++k) {
                const double b = std::min(t0 + (k + 0.5) * dt, t1);
                const glm::dvec3 p = cam.position + 0.5 * (a + b) * d;
                const double s = sigma(p);
                const double alpha = 1.0 - std::exp(-s * (b - a));
                if (s > 0.0)
                    for (int i = 0; i < kLights; ++i) {
                        const glm::dvec3 light = lo + (hi - lo) * ((i + 0.5) / kLights);
                        const glm::dvec3 l = p - light;
                        const double r2 = std::max(glm::dot(l, l), 2500.0);
                        const double c = T * alpha * intensity * hg(glm::dot(l, -d) / std::sqrt(r2), 0.85) / r2;
                        L += c * std::exp(-tau(light, p, std::sqrt(r2)));
                        unattenuated += c;
                    }
                T *= 1.0 - alpha;
                a = b;
            }
            expected[std::size_t(y) * W + std::size_t(x)] = L;
        }
    return expected;
}

// The march's light of `channel` (straight from lo to hi, 1 W/sr per metre) in uniform rain
// (sigma 3e-4, albedo 1, g 0.85), no jitter, against cpu_rain_light's sum: the peak of the
// CPU's image and the worst relative error over its pixels above 1% of that peak.
std::pair<double, double> uniform_rain_against_cpu(render::Renderer& r, const render::LitChannel& channel,
                                                   const glm::dvec3& lo, const glm::dvec3& hi) {
    const double sigma = 3e-4;
    cloud::RainField rain = uniform_rain(sigma);
    rain.albedo = 1.0;
    rain.g = 0.85;
    r.set_channel(channel);
    const std::vector<float> img = side_march(r, rain);
    r.set_channel({});
    const render::Camera cam = side_camera();
    double unattenuated = 0.0;
    const std::vector<double> expected = cpu_rain_light(
        cam, kSideW, kSideH, lo, hi, 1.0, [&](const glm::dvec3&) { return sigma; },
        [&](const glm::dvec3&, const glm::dvec3&, double distance) { return sigma * distance; }, unattenuated);
    const double peak = *std::max_element(expected.begin(), expected.end());
    double worst = 0.0;
    for (std::size_t p = 0; p < expected.size(); ++p)
        if (expected[p] > 0.01 * peak) worst = std::max(worst, std::abs(double(img[p * 4]) / expected[p] - 1.0));
    return {peak, worst};
}

}  // namespace

TEST_CASE("rain's extinction: T = exp(-sigma chord) through a uniform rain box") {
    const double sigma = 1e-3;
    const std::vector<float> img = side_march(gl_renderer(), uniform_rain(sigma));
    const render::Camera cam = side_camera();
    const int W = kSideW, H = kSideH;
    double worst = 0.0;
    int inside = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            glm::dvec3 d;
            double t0, t1;
            const double chord = box_chord(cam, x, y, W, H, d, t0, t1) ? t1 - t0 : 0.0;
            inside += chord > 0.0;
            const double T = std::exp(-sigma * chord);
            worst = std::max(worst, std::abs(double(img[(std::size_t(y) * W + std::size_t(x)) * 4 + 3]) - T));
            // Without lights, sky or sun the rain only absorbs: no radiance.
            CHECK(img[(std::size_t(y) * W + std::size_t(x)) * 4] == 0.0f);
        }
    // The pieces cover the chord exactly and the rain is constant: only float rounding (as the
    // homogeneous cloud box's 1e-3 bound, which this shares).
    MESSAGE("worst |T - exp(-sigma chord)| ", worst, " over ", inside, " pixels in the box");
    CHECK(inside > W * H / 4);
    CHECK(worst < 1e-4);
}

TEST_CASE("a channel in the rain lights it; no rain, or rain off, draws the volume without it") {
    render::Renderer& r = gl_renderer();
    const core::Grid3<float> empty(box(), 0.0f);
    const cloud::RainField rain = uniform_rain(1e-3);
    const cloud::RainField none = [] {
        cloud::RainField z = uniform_rain(0.0);
        return z;
    }();
    render::LitChannel ch;
    for (int i = 0; i < 10; ++i)  // a vertical channel from the ground to 1 km at x = y = 0
        ch.segments.push_back({{0.0f, 0.0f, float(100 * i)}, {0.0f, 0.0f, float(100 * (i + 1))}, 1.0f, 2.0f});
    r.set_channel(ch);
    r.clear_source();
    const render::Camera cam = side_camera();
    const int W = 64, H = 48;
    render::Settings st = test::volume_only();
    st.jitter = false;
    auto shot = [&](const cloud::RainField* rf, bool on) {
        r.set_volume({.density = &empty, .extinction = 4e-3, .precision = render::DensityPrecision::F16, .rain = rf});
        render::Settings s = st;
        s.rain = on;
        render_at(r, cam, s, W, H);
        int w = 0, h = 0;
        return r.read_march(w, h);
    };
    const std::vector<float> plain = shot(nullptr, true);
    CHECK(shot(&none, true) == plain);   // a rain field with no rain: no rain at all
    CHECK(shot(&rain, false) == plain);  // switched off: not drawn
    const std::vector<float> wet = shot(&rain, true);
    // The channel's column (image centre) glows; the light falls off sideways.
    auto L = [&](const std::vector<float>& im, int x, int y) { return im[(std::size_t(y) * W + std::size_t(x)) * 4]; };
    // The channel is at x = 0, seen from x = -300 m: the image column of the target, shifted.
    int best_x = 0;
    for (int x = 0; x < W; ++x)
        if (L(wet, x, H / 2) > L(wet, best_x, H / 2)) best_x = x;
    MESSAGE("rain radiance at the channel's column ", L(wet, best_x, H / 2), ", 12 pixels aside ",
            L(wet, std::min(best_x + 12, W - 1), H / 2));
    CHECK(L(wet, best_x, H / 2) > 0.0f);
    CHECK(std::isfinite(L(wet, best_x, H / 2)));
    CHECK(L(wet, best_x, H / 2) > 3.0f * L(wet, std::min(best_x + 12, W - 1), H / 2));
    r.set_channel({});
}

TEST_CASE("rain shadows the ground's flash light") {
    render::Renderer& r = gl_renderer();
    const core::Grid3<float> empty(box(), 0.0f);
    const double sigma = 1e-3;
    // Albedo 0: the rain between the camera and the ground only absorbs, so the pixel is the
    // ground's radiance times the view's transmittance (the rain's own glow would add to it).
    cloud::RainField rain = uniform_rain(sigma);
    rain.albedo = 0.0;
    // A short channel 1 km up, over the box's centre; the camera looks down at the ground under it.
    light_by_channel(r, {0.0f, 0.0f, 1000.0f}, {0.0f, 0.0f, 1100.0f});
    render::Camera cam;
    cam.position = {0.0, -600.0, 3000.0};
    cam.target = {0.0, 0.0, 0.0};
    cam.vertical_fov_deg = 10.0;
    render::Settings st = test::volume_only();
    st.ground = true;
    st.jitter = false;
    st.ground_lights = 1;
    // `then`: the share set_rain_solved_share() gives after the upload (< 0: none).
    auto centre = [&](const cloud::RainField* rf, double share = 1.0, double then = -1.0) {
        r.set_volume({.density = &empty,
                      .extinction = 4e-3,
                      .precision = render::DensityPrecision::F16,
                      .rain = rf,
                      .rain_solved_share = share});
        if (then > 0.0) r.set_rain_solved_share(then);
        render_at(r, cam, st, 32, 32);
        int w = 0, h = 0;
        const std::vector<float> im = r.read_march(w, h);
        // The ground's radiance seen through the rain: divide by the march's transmittance.
        const std::size_t p = (std::size_t(16) * 32 + 16) * 4;
        return std::pair{double(im[p + 1]), double(im[p + 3])};
    };
    const auto [dry, dry_t] = centre(nullptr);
    const auto [wet, wet_t] = centre(&rain);
    // The light at 1050 m over the ground point: 1050 m of rain (the rain's top is above it):
    // exp(-1.05) on the ground's irradiance (4 samples of a uniform field: exact).
    const double shadow = wet / wet_t / dry;
    MESSAGE("ground under the rain keeps ", shadow, " of its flash light (exp(-1.05) = ", std::exp(-1.05), ")");
    CHECK(dry_t == doctest::Approx(1.0));
    // The light is the channel's power centroid, 1050 m up over the point; the rain's
    // top (1200 m) is above it, so the whole path is in rain.
    CHECK(shadow == test::rel(std::exp(-sigma * 1050.0), 0.001));  // measured 7e-5 apart
    // At the share of its extinction the light solves carry (the default storm's drops in its
    // cloud: 0.39), the ground's light is attenuated by that share alone, read from the lights'
    // map or integrated per pixel; the view's own transmittance through the rain keeps the full
    // extinction.
    for (const bool map : {true, false}) {
        CAPTURE(map);
        st.ground_rain_map = map;
        const auto [wet39, wet39_t] = centre(&rain, 0.39);
        CHECK(wet39_t == doctest::Approx(wet_t));
        CHECK(wet39 / wet39_t / dry == test::rel(std::exp(-0.39 * sigma * 1050.0), 0.001));  // the same sums
        // The share changed alone (a preset that traces the drops): the full extinction again,
        // the lights' map made anew.
        CHECK(centre(&rain, 0.39, 1.0).first == centre(&rain).first);
        CHECK(r.rain_solved_share() == 1.0);
    }
    r.set_channel({});
}

TEST_CASE("the ground's rain shadow: its lights' map and the per-pixel integral against the path integral") {
    render::Renderer& r = gl_renderer();
    // A rain shaft 900 m in radius (its edge falling to nothing over its outer 300 m) east of
    // a channel, under a top at 1500 m: the ground beyond it sees the channel through
    // kilometres of rain, with the shaft's edges as radial shadow edges. 100 m voxels, as the
    // storms'.
    const core::GridGeometry g{{48, 48, 16}, 100.0, glm::dvec3(-2400.0, -2400.0, 0.0)};
    const double sigma = 2e-3, top = 1500.0;
    cloud::RainField rain;
    rain.extinction = core::Grid3<float>(g, 0.0f);
    for (int k = 0; k < 16; ++k)
        for (int j = 0; j < 48; ++j)
            for (int i = 0; i < 48; ++i) {
                const glm::dvec3 c = g.origin + (glm::dvec3(i, j, k) + 0.5) * g.voxel_size;
                const double edge = std::clamp((900.0 - glm::length(glm::dvec2(c.x - 700.0, c.y))) / 300.0, 0.0, 1.0);
                rain.extinction.at(i, j, k) = c.z < top ? float(sigma * edge) : 0.0f;
            }
    rain.top = top;
    rain.max_extinction = sigma;
    rain.albedo = 0.0;  // it only absorbs: the ground's pixels are its radiance x the view's T
    const core::Grid3<float> empty(g, 0.0f);
    light_by_channel(r, {-500.0f, 0.0f, 1100.0f}, {-500.0f, 0.0f, 1300.0f});
    const std::vector<render::Renderer::FlashLight> lights = r.flash_lights(1, 0.0);
    REQUIRE(lights.size() == 1);
    const glm::dvec3 light = lights[0].position;
    render::Camera cam;
    cam.position = {0.0, -1500.0, 7000.0};
    cam.target = {300.0, 0.0, 0.0};
    cam.vertical_fov_deg = 36.0;
    const int W = 64, H = 64;
    render::Settings st = test::volume_only();
    st.ground = true;
    st.jitter = false;
    st.ground_lights = 1;
    const auto shot = [&](const cloud::RainField* rf, bool map) {
        r.set_volume({.density = &empty, .extinction = 4e-3, .precision = render::DensityPrecision::F16, .rain = rf});
        st.ground_rain_map = map;
        render_at(r, cam, st, W, H);
        int w = 0, h = 0;
        return r.read_march(w, h);
    };
    const std::vector<float> dry = shot(nullptr, true), mapped = shot(&rain, true), direct = shot(&rain, false);
    // The path integral: the rain's trilinear extinction (the texture's) along the segment from
    // the pixel's ground point to the light, below the top, at 4000 points.
    const auto path_transmittance = [&](const glm::dvec3& p) {
        const glm::dvec3 l = light - p;
        const double t1 = std::min(1.0, (top - p.z) / l.z);
        const int n = 4000;
        double tau = 0.0;
        for (int k = 0; k < n; ++k) tau += rain.extinction.sample(p + ((k + 0.5) / n * t1) * l);
        return std::exp(-tau * t1 * glm::length(l) / n);
    };
    double map_sq = 0.0, direct_sq = 0.0, ref_sq = 0.0, map_worst = 0.0, direct_worst = 0.0;
    int n = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const glm::dvec3 d = test::pixel_ray(cam, x, y, W, H);
            const glm::dvec3 p = cam.position + (-cam.position.z / d.z) * d;
            const std::size_t at = (std::size_t(y) * W + std::size_t(x)) * 4;
            // The view's transmittance through the shaft divides out the rain in front of the
            // ground; below 0.05 float rounding of the quotient would count.
            if (!(dry[at + 1] > 0.0f) || mapped[at + 3] < 0.05f || direct[at + 3] < 0.05f) continue;
            const double ref = path_transmittance(p);
            const double got_map = double(mapped[at + 1]) / double(mapped[at + 3]) / double(dry[at + 1]);
            const double got_direct = double(direct[at + 1]) / double(direct[at + 3]) / double(dry[at + 1]);
            map_sq += (got_map - ref) * (got_map - ref);
            direct_sq += (got_direct - ref) * (got_direct - ref);
            ref_sq += ref * ref;
            map_worst = std::max(map_worst, std::abs(got_map - ref));
            direct_worst = std::max(direct_worst, std::abs(got_direct - ref));
            ++n;
        }
    const double map_l2 = std::sqrt(map_sq / ref_sq), direct_l2 = std::sqrt(direct_sq / ref_sq);
    MESSAGE("ground's rain transmittance over ", n, " pixels, relative L2 / worst: map ", map_l2, " / ", map_worst,
            ", per-pixel 4 samples ", direct_l2, " / ", direct_worst);
    CHECK(n > W * H / 2);
    // Measured: the map 0.09% (worst 0.0041), the per-pixel integral 2.6% (worst 0.20). The map's
    // error is its sampling along the paths and its interpolation between texels, no noise; the
    // bounds are about twice it and fail the map integrated at a sample per two voxels (0.31%,
    // worst 0.016).
    CHECK(map_l2 < 0.002);
    CHECK(map_worst < 0.008);
    CHECK(map_l2 < 0.25 * direct_l2);
    r.set_channel({});
}

TEST_CASE("the channel's light in the rain: the march against its single-scattering sum on the CPU") {
    // One short channel below the rain's top (10 m at 1 W/sr per metre) is the rain's 8 point
    // lights of equal power along it (1.25 W/sr each, at the middles of its eighths); the rain
    // (albedo 1, g = 0.85, uniform) scatters them once toward the camera, each attenuated by the
    // rain on its way, exp(-sigma r). The CPU sums the same pieces (cut at t0 + (k + 1/2) dt,
    // sampled at their midpoints, r^2 floored at (50 m)^2) with the exact HG phase: in uniform
    // rain the lights' map holds the largest extinction exactly (1 in 8 bits), so what differs
    // is float rounding.
    render::LitChannel ch;
    ch.segments.push_back({{100.0f, 200.0f, 500.0f}, {100.0f, 200.0f, 510.0f}, 1.0f, 2.0f});
    const auto [peak, worst] =
        uniform_rain_against_cpu(gl_renderer(), ch, {100.0, 200.0, 500.0}, {100.0, 200.0, 510.0});
    // Measured 1.8e-5 (4.2e-6 before the attenuation); 1e-3 leaves room for another CPU's float rounding (FMA, vector width),
    // and a 5% error in the rain's light fails by far.
    MESSAGE("worst relative error of the rain's light (pixels above 1% of the peak): ", worst);
    CHECK(peak > 0.0);
    CHECK(worst < 1e-3);
}

TEST_CASE("a channel of several segments in the rain: its lights evenly along it, whatever way its segments run") {
    // A bolt lists its channel from the cloud down, each segment from its upper end to its lower;
    // its 600 m here are cut at uneven heights (900, 760, 700, 480, 300 m). The 8 lights are runs of
    // equal power along the channel in that order, so a straight channel's are at the middles of
    // its eighths whatever its cuts, as the CPU sum places them. Cutting each segment's runs from
    // its lower end instead (heights sorted) paired them up, 20-70 m apart with ~200 m between
    // pairs on the Cycles test scene's channel; this case's worst pixel was then 110% off.
    render::LitChannel ch;
    const float cuts[] = {900.0f, 760.0f, 700.0f, 480.0f, 300.0f};
    for (std::size_t i = 0; i + 1 < std::size(cuts); ++i)
        ch.segments.push_back({{100.0f, 200.0f, cuts[i]}, {100.0f, 200.0f, cuts[i + 1]}, 1.0f, 2.0f});
    const auto [peak, worst] =
        uniform_rain_against_cpu(gl_renderer(), ch, {100.0, 200.0, 300.0}, {100.0, 200.0, 900.0});
    // The bound is the single segment's above (float rounding, there 1.8e-5), the lights' positions
    // now summed from five segments' ends in float.
    MESSAGE("worst relative error of the rain's light (pixels above 1% of the peak): ", worst);
    CHECK(peak > 0.0);
    CHECK(worst < 1e-3);
}

TEST_CASE("the channel's light in a shaft beside it: each light attenuated by the rain on its path") {
    // Rain fills the half x > 0 of the box (sigma 3e-3, storm-full's 25 mm/h); a channel of
    // 400 m stands 300 m outside it, so the paths from its lights into the shaft run partly
    // through clear air: what the rain's mean extinction toward the lights' centroid, per voxel
    // (pass_rain_lights.cpp), approximates. The CPU integrates each light's path through the
    // same field the march filters (trilinear: a ramp over the voxel either side of x = 0) at
    // 1 m steps, and sums the march's pieces as the case above. Both density precisions (the
    // mean in 16-bit floats or 8 bits).
    render::Renderer& r = gl_renderer();
    const core::Grid3<float> empty(box(), 0.0f);
    const double sigma = 3e-3;
    cloud::RainField rain = uniform_rain(sigma);
    for (int k = 0; k < box().dims.z; ++k)
        for (int j = 0; j < box().dims.y; ++j)
            for (int i = 0; i < box().dims.x / 2; ++i) rain.extinction.at(i, j, k) = 0.0f;
    rain.albedo = 1.0;
    rain.g = 0.85;
    render::Camera cam = side_camera();
    cam.position = {600.0, -3000.0, 500.0};
    cam.target = {200.0, 100.0, 500.0};
    const int W = 64, H = 48;
    render::Settings st = test::volume_only();
    st.jitter = false;
    st.early_exit = false;
    // The field the march reads: voxel centres at x = -50 (0) and 50 m (sigma), linear between.
    const auto field = [&](const glm::dvec3& x) {
        const core::GridGeometry g = box();
        if (x.x < g.origin.x || x.y < g.origin.y || x.z < g.origin.z || x.x > g.upper().x || x.y > g.upper().y ||
            x.z > g.upper().z)
            return 0.0;
        return sigma * std::clamp((x.x + 50.0) / 100.0, 0.0, 1.0);
    };
    const auto optical_depth = [&](const glm::dvec3& a, const glm::dvec3& b) {
        const double len = glm::length(b - a);
        const int n = std::max(1, int(std::ceil(len)));
        double tau = 0.0;
        for (int k = 0; k < n; ++k) tau += field(a + (b - a) * ((k + 0.5) / n));
        return tau * len / n;
    };
    double unattenuated = 0.0;
    const std::vector<double> expected = cpu_rain_light(
        cam, W, H, {-300.0, 100.0, 300.0}, {-300.0, 100.0, 700.0}, 1.0, field,
        [&](const glm::dvec3& light, const glm::dvec3& p, double) { return optical_depth(light, p); }, unattenuated);
    const double peak = *std::max_element(expected.begin(), expected.end());
    double total = 0.0;
    for (const double e : expected) total += e;
    REQUIRE(peak > 0.0);
    MESSAGE("the attenuation takes ", 1.0 - total / unattenuated, " of the rain's light");
    for (const render::DensityPrecision precision : {render::DensityPrecision::F16, render::DensityPrecision::U8}) {
        r.set_volume({.density = &empty, .extinction = 4e-3, .precision = precision, .rain = &rain});
        light_by_channel(r, {-300.0f, 100.0f, 300.0f}, {-300.0f, 100.0f, 700.0f});
        render_at(r, cam, st, W, H);
        int w = 0, h = 0;
        const std::vector<float> img = r.read_march(w, h);
        double err2 = 0.0, ref2 = 0.0, worst = 0.0;
        for (std::size_t p = 0; p < expected.size(); ++p) {
            const double e = double(img[p * 4]) - expected[p];
            err2 += e * e;
            ref2 += expected[p] * expected[p];
            if (expected[p] > 0.01 * peak) worst = std::max(worst, std::abs(e) / expected[p]);
        }
        const double l2 = std::sqrt(err2 / ref2);
        CAPTURE(int(precision));
        MESSAGE("the shaft beside the channel: relative L2 ", l2, ", worst ", worst, " (pixels above 1% of the peak)");
        // Measured 3.6% and 10% (F16), 3.4% and 9.4% (U8): the edge of the shaft placed to within
        // a voxel, the mean toward the centroid rather than each light. The bounds leave room for
        // another CPU's rounding; the lights unattenuated err by 132% (the attenuation takes 57%
        // of the light), the mean on cells of 2 voxels by 15% and 28%, both far outside.
        CHECK(l2 < 0.05);
        CHECK(worst < 0.14);
    }
    r.set_channel({});
    r.clear_volume();
}

TEST_CASE("the rain's light follows the switches: no sky light without the static light, the flash's with the flash") {
    // The rain takes the sky's light only through the static light's S (next case): with none
    // uploaded, a sky behind uniform rain is only dimmed by it. The channel lights it only when
    // the flash lights the volume (Settings::flash_light and cloud_lighting), so a frame's terms
    // (the EXR's passes) hold the rain's light once.
    render::Renderer& r = gl_renderer();
    const double sigma = 1e-3;
    const cloud::RainField rain = uniform_rain(sigma);
    r.clear_source();
    r.clear_sun();
    r.clear_static();
    light_by_channel(r, {100.0f, 200.0f, 500.0f}, {100.0f, 200.0f, 510.0f});
    const auto rain_light = [&](const render::Settings& st) {
        double worst = 0.0;
        int n = 0;
        rain_light_per_pixel(r, glm::dvec3(-300.0, -4000.0, 600.0), st, rain, sigma,
                             [&](const glm::dvec3&, double, int, double got, double pixel) {
                                 worst = std::max(worst, std::abs(got) / pixel);
                                 ++n;
                             });
        CHECK(n > 1000);
        return worst;
    };
    render::Settings st = sky_lit();
    st.flash_light = false;
    const double sky_only = rain_light(st);
    st.flash_light = true;
    st.cloud_lighting = false;
    const double unlit = rain_light(st);
    st.cloud_lighting = true;
    const double lit = rain_light(st);
    MESSAGE("the rain's own light relative to the pixel: sky only " << sky_only << ", volume unlit " << unlit
                                                                    << ", with the flash up to " << lit);
    // Float rounding of I - B T (~1e-7 of the pixel, 2.5e-6 measured at worst).
    CHECK(sky_only < 1e-5);
    CHECK(unlit < 1e-5);
    CHECK(lit > 1e-3);  // the flash's light is there when it is on (1.9% of its pixel at most)
    r.set_channel({});
}

TEST_CASE("the static light in the rain: S at its points scattered by its albedo") {
    // The static light solved with the rain in its media (sky::static_media) holds, at the
    // rain's points, the light of every order the cloud and the rain scatter there, the sky's
    // included, carrying the cloud's albedo. The rain scatters it by its own albedo: with S
    // uniform (rgb, the same in every direction) and no sun, rain of constant sigma draws
    // (albedo_rain / albedo_cloud) S (1 - exp(-sigma chord)) over the sky behind it times
    // exp(-sigma chord), whatever the view.
    render::Renderer& r = gl_renderer();
    const double sigma = 1e-3;
    const cloud::RainField rain = uniform_rain(sigma);
    r.clear_source();
    r.clear_sun();
    r.set_channel({});
    const core::GridGeometry lg{{6, 6, 3}, 400.0, box().origin};  // the box in 400 m cells
    const std::array<double, 3> S{2.0, 1.0, 0.5};
    std::vector<float> rgb(lg.cell_count() * 3);
    for (std::size_t i = 0; i < lg.cell_count(); ++i)
        for (int c = 0; c < 3; ++c) rgb[3 * i + std::size_t(c)] = float(S[std::size_t(c)]);
    const render::Settings st = sky_lit();
    double worst = 0.0;
    int counted = 0;
    for (const double cloud_albedo : {0.99, 0.6}) {
        render::StaticUpload up;
        up.geometry = lg;
        up.direction_count = 1;
        up.albedo = cloud_albedo;
        up.rgb.assign(1, std::span<const float>(rgb));
        r.upload_static(up);
        for (const glm::dvec3 pos : {glm::dvec3(-300.0, -4000.0, 600.0), glm::dvec3(-300.0, -3000.0, 3200.0)})
            rain_light_per_pixel(r, pos, st, rain, sigma,
                                 [&](const glm::dvec3&, double opacity, int c, double got, double pixel) {
                                     const double expect = rain.albedo / cloud_albedo * S[std::size_t(c)] * opacity;
                                     if (expect < 0.1 * pixel) return;  // as above: the subtraction's rounding
                                     worst = std::max(worst, std::abs(got / expect - 1.0));
                                     ++counted;
                                 });
    }
    r.clear_static();
    MESSAGE("worst relative error " << worst << " over " << counted << " values");
    CHECK(counted > 4000);
    // The same sum as the march's: float rounding only, as the sky's case above (2e-5 there).
    CHECK(worst < 1e-4);
}

TEST_CASE("the flash's light at the rain: its S of orders >= 2 scattered by the rain's albedo, with the flash") {
    // runtime::Frame::rain (upload_rain_source): the flash's light of orders >= 2 at the rain's
    // points per unit albedo. With it uniform (the same in every direction) and no channel,
    // rain of constant sigma draws albedo_rain x S x flash colour x (1 - exp(-sigma chord)) over
    // the sky behind it times exp(-sigma chord), whatever the view and whichever grid the cloud's
    // S is on. The cloud's S (uploaded too, larger) is never read in rain alone; cleared, or the
    // flash off, the rain has none.
    render::Renderer& r = gl_renderer();
    const double sigma = 1e-3;
    const cloud::RainField rain = uniform_rain(sigma);
    r.clear_sun();
    r.clear_static();
    r.set_channel({});
    const core::GridGeometry lg{{6, 6, 3}, 400.0, box().origin};  // the box in 400 m cells
    const double S = 3.0;
    const std::vector<float> cloud_s(lg.cell_count(), 50.0f), rain_s(lg.cell_count(), float(S));
    render::SourceUpload up;
    up.geometry = lg;
    up.direction_count = 1;
    up.directions = {0};
    up.values = {std::span<const float>(cloud_s)};
    render::SourceUpload wet = up;
    wet.values = {std::span<const float>(rain_s)};
    render::Settings st = sky_lit();
    st.flash_colour = {1.0, 0.5, 0.25};
    const auto worst_of = [&](double scale) {
        double worst = 0.0;
        int counted = 0;
        for (const glm::dvec3 pos : {glm::dvec3(-300.0, -4000.0, 600.0), glm::dvec3(-300.0, -3000.0, 3200.0)})
            rain_light_per_pixel(r, pos, st, rain, sigma,
                                 [&](const glm::dvec3&, double opacity, int c, double got, double pixel) {
                                     const double expect = scale * rain.albedo * S * st.flash_colour[c] * opacity;
                                     if (scale == 0.0) {
                                         worst = std::max(worst, std::abs(got) / pixel);
                                     } else {
                                         if (expect < 0.1 * pixel) return;  // the subtraction's rounding
                                         worst = std::max(worst, std::abs(got / expect - 1.0));
                                     }
                                     ++counted;
                                 });
        CHECK(counted > 2000);
        return worst;
    };
    r.upload_source(up);
    r.upload_rain_source(wet);
    double lit = worst_of(1.0);
    // S on a grid twice as fine (a strike kept on the transport grid): the rain's light is read
    // from its own grid at S's nodes (the march's one fetch takes both).
    const core::GridGeometry fine{{12, 12, 6}, 200.0, box().origin};
    const std::vector<float> fine_s(fine.cell_count(), 50.0f);
    render::SourceUpload fine_up = up;
    fine_up.geometry = fine;
    fine_up.values = {std::span<const float>(fine_s)};
    r.upload_source(fine_up);
    lit = std::max(lit, worst_of(1.0));
    r.upload_source(up);
    st.flash_light = false;
    const double flash_off = worst_of(0.0);
    st.flash_light = true;
    r.clear_rain_source();
    const double cleared = worst_of(0.0);
    r.upload_rain_source(wet);
    r.clear_source();  // the flash's light at the rain goes with it
    const double dark = worst_of(0.0);
    MESSAGE("worst relative error " << lit << "; the rain's own light relative to the pixel with the flash off "
                                    << flash_off << ", cleared " << cleared << ", the flash cleared " << dark);
    // The same sum as the march's: float rounding only (the static light's case: 1e-4).
    CHECK(lit < 1e-4);
    // Float rounding of I - B T (as the switches' case above).
    CHECK(flash_off < 1e-5);
    CHECK(cleared < 1e-5);
    CHECK(dark < 1e-5);

    // Bad input is rejected with the direction named, and leaves nothing half-uploaded.
    std::vector<float> bad = rain_s;
    bad[7] = std::nanf("");
    wet.values = {std::span<const float>(bad)};
    CHECK_THROWS_WITH_AS(r.upload_rain_source(wet), doctest::Contains("direction 0"), core::Error);
    wet.values = {};
    CHECK_THROWS_AS(r.upload_rain_source(wet), core::Error);
}

TEST_CASE("the flash's light at the rain is read out geometrically between its directions") {
    // The drops' forward lobe (HG 0.85) is narrower than the 26 directions are apart, and a
    // lobe's convex tail between two nodes is nearer their geometric mean than their arithmetic
    // one: the rain's S toward the camera is exp(sum w_m log S_m) with the CPU's weights
    // (render::direction_weights, summing to 1), the cloud's S the arithmetic sum as before. A
    // node with a weighted S_m of 0, and a view that needs more than the 16 directions one
    // dispatch of the resolve takes (a camera among the nodes), fall back to the arithmetic sum.
    render::Renderer& r = gl_renderer();
    const double sigma = 1e-3;
    const cloud::RainField rain = uniform_rain(sigma);
    const core::Grid3<float> empty(box(), 0.0f);
    r.set_volume({.density = &empty, .extinction = 4e-3, .precision = render::DensityPrecision::F16, .rain = &rain});
    r.clear_sun();
    r.clear_static();
    r.set_channel({});
    const core::GridGeometry lg{{6, 6, 3}, 400.0, box().origin};
    constexpr int kDirs = 26;
    // Values spread over a decade and more by direction (a lobe's range), varying by node; one
    // node with a zero direction.
    const std::size_t zero_node = lg.index(2, 3, 1);
    const auto value = [&](int m, std::size_t c) {
        if (c == zero_node && m == 0) return 0.0f;
        return float(std::exp(0.18 * double(m)) * (1.0 + 0.01 * double(c)));
    };
    std::vector<std::vector<float>> cloud_s(kDirs), rain_s(kDirs);
    render::SourceUpload up, wet;
    up.geometry = wet.geometry = lg;
    up.direction_count = wet.direction_count = kDirs;
    for (int m = 0; m < kDirs; ++m) {
        cloud_s[std::size_t(m)].resize(lg.cell_count());
        rain_s[std::size_t(m)].resize(lg.cell_count());
        for (std::size_t c = 0; c < lg.cell_count(); ++c) {
            cloud_s[std::size_t(m)][c] = 2.0f * value(m, c);
            rain_s[std::size_t(m)][c] = value(m, c);
        }
        up.directions.push_back(m);
        wet.directions.push_back(m);
        up.values.push_back(std::span<const float>(cloud_s[std::size_t(m)]));
        wet.values.push_back(std::span<const float>(rain_s[std::size_t(m)]));
    }
    r.upload_source(up);
    r.upload_rain_source(wet);
    render::Settings st = sky_lit();
    st.direction_min_weight = 0.0;  // every direction with a non-zero weight
    // Far outside (a few directions for every node) and among the nodes (all 26).
    for (const bool among : {false, true}) {
        CAPTURE(among);
        render::Camera cam;
        cam.position = among ? glm::dvec3(100.0, 50.0, 700.0) : glm::dvec3(-9000.0, -7000.0, 4000.0);
        cam.target = {0.0, 0.0, 600.0};
        const render::FrameStats stats = render_at(r, cam, st, 32, 24);
        CHECK((stats.directions_used > 16) == among);
        const std::vector<float> flash = r.read_resolved_source(), wet_cam = r.read_resolved_rain_source();
        REQUIRE(flash.size() == lg.cell_count());
        REQUIRE(wet_cam.size() == lg.cell_count());
        double worst_rain = 0.0, worst_cloud = 0.0, apart = 0.0;
        for (std::size_t c = 0; c < lg.cell_count(); ++c) {
            const core::Int3 n = lg.unindex(c);
            const auto w = render::direction_weights(cam.position - lg.centre(n.x, n.y, n.z), kDirs);
            double lin = 0.0, log_sum = 0.0;
            bool positive = true;
            for (int k = 0; k < w.count; ++k) {
                const double wk = w.weight[std::size_t(k)], v = value(w.index[std::size_t(k)], c);
                lin += wk * v;
                if (wk > 0.0) {
                    positive = positive && v > 0.0;
                    if (v > 0.0) log_sum += wk * std::log(v);
                }
            }
            const double want = positive && !among ? std::exp(log_sum) : lin;
            worst_rain = std::max(worst_rain, std::abs(wet_cam[c] / want - 1.0));
            worst_cloud = std::max(worst_cloud, std::abs(flash[c] / (2.0 * lin) - 1.0));
            if (positive) apart = std::max(apart, std::abs(lin / std::exp(log_sum) - 1.0));
        }
        MESSAGE("rain's S against the " << std::string(among ? "arithmetic" : "geometric") << " mean: worst "
                                        << worst_rain << " (the two means up to " << apart
                                        << " apart); the cloud's: " << worst_cloud);
        // Float weights (smoothstep, normalize) and float log/exp against double: ~1e-6
        // relative, as the flash's resolve against the CPU weights (2e-5 there).
        CHECK(worst_rain < 2e-5);
        CHECK(worst_cloud < 2e-5);
        CHECK(apart > 0.01);  // the two means differ here: the check can fail
    }
    r.clear_rain_source();
    r.clear_source();
}
