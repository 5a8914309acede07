// The OpenGL renderer through OSMesa (llvmpipe): analytic checks of the ray marcher, the
// direction resolve, empty-space skipping, upsampling alignment, attenuation of the bolt by
// the cloud, determinism, and error reporting.
#include "gl_fixture.h"

#include "support/synthetic_storm.h"
#include "support/test_support.h"
#include "transport/transport.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

using namespace fulgur;
using test::gl_renderer;
using test::render_at;

namespace {

/// Uploads S(x, s_m) = value(m, cell) for every direction of the set.
template <class F>
void upload_all(render::Renderer& r, const core::GridGeometry& g, int count, F value) {
    std::vector<std::vector<float>> data(std::size_t(count), std::vector<float>(g.cell_count()));
    render::SourceUpload up;
    up.geometry = g;
    up.direction_count = count;
    for (int m = 0; m < count; ++m) {
        for (std::size_t c = 0; c < g.cell_count(); ++c) data[std::size_t(m)][c] = value(m, c);
        up.directions.push_back(m);
        up.values.emplace_back(data[std::size_t(m)]);
    }
    r.upload_source(up);
}

struct Image {
    std::vector<float> rgba;
    int w = 0, h = 0;
    const float* px(int x, int y) const { return &rgba[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4]; }
};

Image read_march(render::Renderer& r) {
    Image im;
    im.rgba = r.read_march(im.w, im.h);
    return im;
}

// What draws the channel's core alone: no sky, ground, glow, glare, stars or dither.
render::Settings core_only() {
    render::Settings st;
    st.sky = st.ground = st.glow = st.glare = false;
    st.bolt = true;
    st.dither = false;
    st.star_radiance = 0.0;
    return st;
}

// Level with z = 3 km, 8 km from the x-z plane the core tests draw their channels in, 40 degrees.
render::Camera core_camera() {
    render::Camera cam;
    cam.position = {0, -8000, 3000};
    cam.target = {0, 0, 3000};
    cam.vertical_fov_deg = 40.0;
    return cam;
}

std::string read_text(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

}  // namespace

TEST_CASE("homogeneous box with constant S: L = S (1 - exp(-tau)) for any step") {
    render::Renderer& r = gl_renderer();
    const double rho = 0.5, kappa = 1.25e-3, S = 2.0, voxel = 100.0;
    // 16 voxels of 100 m: a chord of 1.6 km has tau = 1.
    const auto density = test::make_grid({16, 16, 16}, voxel, {0, 0, 0}, [&](int, int, int) { return float(rho); });
    // F16 stores 0.5 exactly (U8 would store 128/255).
    r.set_volume({.density = &density, .extinction = kappa, .precision = render::DensityPrecision::F16});
    core::GridGeometry lg = density.geom;
    lg.dims = {4, 4, 4};
    lg.voxel_size = 400.0;
    upload_all(r, lg, 26, [&](int, std::size_t) { return float(S); });
    render::Camera cam;
    cam.position = {-1500.0, -2600.0, 2300.0};
    cam.target = {800.0, 800.0, 800.0};
    cam.vertical_fov_deg = 45.0;
    const int W = 80, H = 60;
    for (double step : {0.37, 1.0, 2.5}) {
        CAPTURE(step);
        render::Settings st = test::volume_only();
        st.step_voxels = step;
        st.jitter = true;
        st.early_exit = false;
        render_at(r, cam, st, W, H);
        const Image im = read_march(r);
        REQUIRE(im.w == W);
        // The sample intervals are clipped to the chord, so the Riemann sum of a constant
        // medium is exact whatever the step: the only errors are float rounding (chord ends
        // at ~3e-4 m, products of ~40 factors at ~2e-6 relative). The tolerance is 1/1000 of
        // the contribution of one step, far below a one-step error (which is what an
        // unclipped first or last sample would make).
        const double tol = 1e-3 * S * (1.0 - std::exp(-kappa * rho * step * voxel));
        int inside = 0, wx = 0, wy = 0;
        double worst = 0.0, w_chord = 0.0, w_got = 0.0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const glm::dvec3 d = test::pixel_ray(cam, x, y, W, H);
                double t0 = 0, t1 = 1e300;  // the ray from the camera on
                const double chord =
                    core::clip_ray_to_box(cam.position, d, density.geom.origin, density.geom.upper(), t0, t1) ? t1 - t0
                                                                                                              : 0.0;
                const double T = std::exp(-kappa * rho * chord);
                const float* p = im.px(x, y);
                if (std::abs(double(p[0]) - S * (1.0 - T)) > worst) {
                    worst = std::abs(double(p[0]) - S * (1.0 - T));
                    wx = x;
                    wy = y;
                    w_chord = chord;
                    w_got = p[0];
                }
                CHECK(std::abs(double(p[0]) - S * (1.0 - T)) <= tol);
                CHECK(std::abs(double(p[3]) - T) <= tol / S);
                inside += chord > 0.0;
            }
        CHECK(inside > W * H / 5);  // the box covers a good part of the view
        MESSAGE("step " << step << " voxels: worst |L - S(1-exp(-tau))| = " << worst << " (tolerance " << tol
                        << ") at pixel (" << wx << ", " << wy << "), chord " << w_chord << " m, L " << w_got);
    }
}

TEST_CASE("negative S (the lattice's signed phase fit, truncated Haar coefficients) renders as zero") {
    render::Renderer& r = gl_renderer();
    const auto density = test::make_grid({16, 16, 16}, 100.0, {0, 0, 0}, [&](int, int, int) { return 0.5f; });
    r.set_volume({.density = &density, .extinction = 1.25e-3, .precision = render::DensityPrecision::F16});
    core::GridGeometry lg = density.geom;
    lg.dims = {4, 4, 4};
    lg.voxel_size = 400.0;
    render::Camera cam;
    cam.position = {-1500.0, -2600.0, 2300.0};
    cam.target = {800.0, 800.0, 800.0};
    cam.vertical_fov_deg = 45.0;
    render::Settings st = test::volume_only();
    st.jitter = false;
    auto frame = [&](float S) {
        upload_all(r, lg, 26, [&](int, std::size_t) { return S; });
        render_at(r, cam, st, 40, 30);
        return read_march(r);
    };
    const Image zero = frame(0.0f), negative = frame(-3.0f);
    // Clamped at zero where the march consumes S: the same pixels exactly (radiance 0,
    // transmittance unchanged), never a dark cloud with negative radiance.
    REQUIRE(zero.w == negative.w);
    int differ = 0;
    for (int y = 0; y < zero.h; ++y)
        for (int x = 0; x < zero.w; ++x)
            for (int c = 0; c < 4; ++c) differ += zero.px(x, y)[c] != negative.px(x, y)[c];
    CHECK(differ == 0);
}

TEST_CASE("linear density gradient: midpoint-rule error within kappa |rho'| dt^2 bounds") {
    render::Renderer& r = gl_renderer();
    const int n = 32;
    const double voxel = 100.0, kappa = 6.25e-4, S = 2.0;
    // rho = (2i + 1) / 64 along x: exact in half precision, linear between voxel centres.
    const auto density =
        test::make_grid({n, 8, 8}, voxel, {0, 0, 0}, [&](int i, int, int) { return float((2 * i + 1) / 64.0); });
    r.set_volume({.density = &density, .extinction = kappa, .precision = render::DensityPrecision::F16});
    core::GridGeometry lg = density.geom;
    lg.dims = {2, 2, 2};
    lg.voxel_size = 1600.0;
    upload_all(r, lg, 1, [&](int, std::size_t) { return float(S); });
    // Integral of the clamped, piecewise linear rho(x) from 0 to x (x in metres).
    const double c0 = 0.5 * voxel, c1 = (n - 0.5) * voxel, r0 = 1.0 / 64.0, r1 = (2.0 * n - 1.0) / 64.0;
    const double slope = (r1 - r0) / (c1 - c0);
    auto F = [&](double x) {
        const double a = std::clamp(x, 0.0, c0), b = std::clamp(x, c0, c1), c = std::clamp(x, c1, n * voxel);
        return r0 * a + (r0 * (b - c0) + 0.5 * slope * (b - c0) * (b - c0)) + r1 * (c - c1);
    };
    render::Camera cam;
    cam.position = {-2500.0, 350.0, 420.0};
    cam.target = {1600.0, 400.0, 400.0};
    cam.vertical_fov_deg = 20.0;
    const int W = 64, H = 48;
    for (double step : {0.5, 1.0, 2.0}) {
        CAPTURE(step);
        render::Settings st = test::volume_only();
        st.step_voxels = step;
        st.early_exit = false;
        render_at(r, cam, st, W, H);
        const Image im = read_march(r);
        const double dt = step * voxel;
        double worst = 0.0, worst_tol = 0.0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const glm::dvec3 d = test::pixel_ray(cam, x, y, W, H);
                double t0 = 0, t1 = 1e300;  // the ray from the camera on
                if (!core::clip_ray_to_box(cam.position, d, density.geom.origin, density.geom.upper(), t0, t1))
                    continue;
                const double x0 = cam.position.x + t0 * d.x, x1 = cam.position.x + t1 * d.x;
                const double tau = kappa * (F(x1) - F(x0)) / d.x;
                const double expected = S * (1.0 - std::exp(-tau));
                // Pieces are sampled at their midpoints, which is exact for linear rho; the only
                // errors come from the two pieces containing a kink of rho (the first and last
                // voxel centres, where the clamped interpolation turns constant): the midpoint
                // rule errs by <= |jump of slope| dt^2 / 8 there, so |d tau| <= kappa |rho'_t| dt^2 / 4
                // and |dL| <= S |d tau|. Plus 1e-5 S for float rounding.
                const double tol = S * 0.25 * kappa * slope * std::abs(d.x) * dt * dt + 1e-5 * S;
                const double err = std::abs(double(im.px(x, y)[0]) - expected);
                if (err / tol > worst / std::max(worst_tol, 1e-300)) {
                    worst = err;
                    worst_tol = tol;
                }
                CHECK(err <= tol);
            }
        MESSAGE("step " << step << " voxels: worst error " << worst << " against tolerance " << worst_tol);
    }
}

TEST_CASE("an empty volume transmits everything: T = 1 and the sky is unchanged") {
    render::Renderer& r = gl_renderer();
    render::Camera cam = render::Camera::orbit({0, 0, 3000}, 15000, 30, 10, 50);
    render::Settings st;  // sky, ground, stars on
    st.glow = st.bolt = false;
    st.internal_scale = 0.5;
    r.clear_source();
    r.clear_volume();
    render_at(r, cam, st, 96, 64);
    const std::vector<float> sky = r.read_hdr();
    const Image no_volume = read_march(r);
    const auto empty = test::make_grid({24, 24, 16}, 200.0, {-2400, -2400, 0}, [](int, int, int) { return 0.0f; });
    r.set_volume({.density = &empty, .extinction = 0.01});
    core::GridGeometry lg = empty.geom;
    lg.dims = {6, 6, 4};
    lg.voxel_size = 800.0;
    upload_all(r, lg, 1, [](int, std::size_t) { return 5.0f; });
    render_at(r, cam, st, 96, 64);
    const Image m = read_march(r);
    // exp(-0) = 1 exactly: T = 1 and no in-scattering although S = 5 everywhere, so the
    // march output (which carries the smooth background times T) equals the one without a
    // volume bit for bit.
    for (std::size_t i = 3; i < m.rgba.size(); i += 4) REQUIRE(m.rgba[i] == 1.0f);
    CHECK(m.rgba == no_volume.rgba);
    CHECK(r.read_hdr() == sky);
}

TEST_CASE("same inputs give identical pixels; the frame index only moves the jitter") {
    render::Renderer& r = gl_renderer();
    const auto density = synthetic::cumulus({40, 40, 30}, 300.0, 5);
    r.set_volume({.density = &density, .extinction = 0.004});
    const auto lg = synthetic::lighting_geometry(density.geom, 4);
    const auto S = synthetic::point_flash_source(density, 0.004, lg, 6, {0, 0, 3000}, 1e6);
    render::SourceUpload up{lg, 6, {0, 1, 2, 3, 4, 5}, {}};
    for (int m = 0; m < 6; ++m) up.values.emplace_back(S.data() + std::size_t(m) * lg.cell_count(), lg.cell_count());
    r.upload_source(up);
    r.set_channel(synthetic::bolt(9, {0, 0, 3000}, 300.0));
    const render::Camera cam = render::Camera::orbit({0, 0, 4000}, 20000, -60, 8, 50);
    render::Settings st;
    st.exposure = 3000.0;
    st.frame_index = 3;
    auto frame = [&] {
        render_at(r, cam, st, 120, 68);
        return std::make_pair(test::gl_context().read_rgba8(), r.read_hdr());
    };
    const auto a = frame(), b = frame();
    CHECK(a.first == b.first);
    CHECK(a.second == b.second);
    st.frame_index = 4;
    const auto c = frame();
    CHECK(c.second != a.second);  // the jitter pattern moved (a test that can fail)
}

TEST_CASE("the GPU resolve matches the CPU direction weights") {
    render::Renderer& r = gl_renderer();
    const auto density = test::make_grid({24, 20, 16}, 100.0, {-1200, -1000, 0}, [](int, int, int) { return 0.3f; });
    r.set_volume({.density = &density, .extinction = 1e-3});
    core::GridGeometry lg = density.geom;
    lg.dims = {6, 5, 4};
    lg.voxel_size = 400.0;
    for (int count : {26, 18, 6}) {
        CAPTURE(count);
        auto value = [](int m, std::size_t c) { return float(1.0 + m + 0.01 * double(c)); };
        upload_all(r, lg, count, value);
        // Outside but close (directions vary strongly over the grid), then inside the grid.
        for (glm::dvec3 pos : {glm::dvec3(-3000, -2500, 2200), glm::dvec3(100, 50, 700)}) {
            CAPTURE(pos.x);
            render::Camera cam;
            cam.position = pos;
            cam.target = {0, 0, 800};
            render::Settings st = test::volume_only();
            st.direction_min_weight = 0.0;  // every direction with a non-zero weight
            const auto stats = render_at(r, cam, st, 32, 24);
            CHECK(stats.missing_weight == 0.0);
            const std::vector<float> gpu = r.read_resolved_source();
            REQUIRE(gpu.size() == lg.cell_count());
            std::vector<double> expected(lg.cell_count());
            for (std::size_t c = 0; c < lg.cell_count(); ++c) {
                const core::Int3 n = lg.unindex(c);
                const glm::dvec3 x = lg.centre(n.x, n.y, n.z);
                const auto w = render::direction_weights(pos - x, count);
                for (int k = 0; k < w.count; ++k)
                    expected[c] += w.weight[std::size_t(k)] * value(w.index[std::size_t(k)], c);
                // float weights (smoothstep, normalize) vs double: ~1e-6 relative.
                CHECK(gpu[c] == test::rel(expected[c], 2e-5));
            }
            // With the default threshold, directions of weight < 1e-3 are left out and the rest
            // renormalized: the error is below 1e-3 times the spread of S over directions
            // (here <= count), relative to S >= 1.
            st.direction_min_weight = render::kDirectionMinWeight;
            render_at(r, cam, st, 32, 24);
            const std::vector<float> thresholded = r.read_resolved_source();
            for (std::size_t c = 0; c < lg.cell_count(); ++c)
                CHECK(std::abs(thresholded[c] - expected[c]) <= 2.0 * render::kDirectionMinWeight * count);
        }
    }
}

TEST_CASE("the resolve covers the tiles near the cloud and leaves the rest zero") {
    // A cloud in one corner of a 40 x 36 x 3 lighting grid: the resolve runs only over the
    // 8 x 8 node tiles holding a node near it. Every node a march can read where the density
    // is non-zero must match the CPU weights; the nodes of skipped tiles stay exactly zero.
    render::Renderer& r = gl_renderer();
    const auto density = test::make_grid({40, 36, 3}, 100.0, {-2000, -1800, 0},
                                         [](int i, int j, int) { return i < 6 && j < 6 ? 0.5f : 0.0f; });
    r.set_volume({.density = &density, .extinction = 1e-3});
    const core::GridGeometry lg = density.geom;
    auto value = [](int m, std::size_t c) { return float(1.0 + m + 0.01 * double(c)); };
    upload_all(r, lg, 26, value);
    render::Camera cam;
    cam.position = {-1500, -6000, 1500};
    cam.target = {-1500, -1500, 150};
    render::Settings st = test::volume_only();
    st.direction_min_weight = 0.0;
    render_at(r, cam, st, 32, 24);
    const std::vector<float> gpu = r.read_resolved_source();
    REQUIRE(gpu.size() == lg.cell_count());
    std::size_t near = 0, skipped = 0;
    for (std::size_t c = 0; c < lg.cell_count(); ++c) {
        const core::Int3 n = lg.unindex(c);
        CHECK(std::isfinite(gpu[c]));
        if (n.x < 8 && n.y < 8) {  // the cloud's tile: every node resolved
            const auto w = render::direction_weights(cam.position - lg.centre(n.x, n.y, n.z), 26);
            double expected = 0.0;
            for (int k = 0; k < w.count; ++k) expected += w.weight[std::size_t(k)] * value(w.index[std::size_t(k)], c);
            CHECK(gpu[c] == test::rel(expected, 2e-5));  // float vs double weights, as above
            ++near;
        } else if (n.x >= 16 || n.y >= 16) {  // >= 10 voxels from the cloud: never resolved
            CHECK(gpu[c] == 0.0f);
            ++skipped;
        }
    }
    CHECK(near == 8 * 8 * 3);
    CHECK(skipped > lg.cell_count() / 2);
}

TEST_CASE("uploading only the needed directions gives the same image; a missing one is reported") {
    render::Renderer& r = gl_renderer();
    const auto density = synthetic::cumulus({40, 40, 30}, 300.0, 2);
    r.set_volume({.density = &density, .extinction = 0.004});
    const auto lg = synthetic::lighting_geometry(density.geom, 4);
    const auto S = synthetic::point_flash_source(density, 0.004, lg, 26, {500, 0, 3500}, 1e6);
    const render::Camera cam = render::Camera::orbit({0, 0, 4000}, 22000, 35, 12, 50);
    render::Settings st = test::volume_only();
    st.internal_scale = 0.5;
    auto upload = [&](const std::vector<int>& dirs) {
        render::SourceUpload up{lg, 26, dirs, {}};
        for (int m : dirs) up.values.emplace_back(S.data() + std::size_t(m) * lg.cell_count(), lg.cell_count());
        r.upload_source(up);
    };
    std::vector<int> all(26);
    for (int m = 0; m < 26; ++m) all[std::size_t(m)] = m;
    upload(all);
    render_at(r, cam, st, 128, 72);
    const Image full = read_march(r);
    const auto need = r.needed_directions(cam, lg, 26);
    REQUIRE(!need.empty());
    CHECK(need.size() < 26);
    std::vector<int> needed;
    for (const auto& u : need) needed.push_back(u.index);
    upload(needed);
    const auto stats = render_at(r, cam, st, 128, 72);
    CHECK(stats.missing_weight == 0.0);
    CHECK(stats.directions_used == int(need.size()));
    const Image part = read_march(r);
    double peak = 0.0, diff = 0.0;
    for (std::size_t i = 0; i < full.rgba.size(); ++i) {
        peak = std::max(peak, double(full.rgba[i]));
        diff = std::max(diff, std::abs(double(full.rgba[i]) - double(part.rgba[i])));
    }
    // Same terms, summed in another grouping (batches of four directions): float rounding.
    CHECK(diff <= 1e-5 * peak);
    const int dropped = needed.back();
    needed.pop_back();
    upload(needed);
    CHECK(render_at(r, cam, st, 128, 72).missing_weight > 0.0);
    // Uploading just the missing direction with keep_others completes S again.
    render::SourceUpload one{lg, 26, {dropped}, {}, true};
    one.values.emplace_back(S.data() + std::size_t(dropped) * lg.cell_count(), lg.cell_count());
    r.upload_source(one);
    CHECK(render_at(r, cam, st, 128, 72).missing_weight == 0.0);
    double diff2 = 0.0;
    const Image again = read_march(r);
    for (std::size_t i = 0; i < full.rgba.size(); ++i)
        diff2 = std::max(diff2, std::abs(double(full.rgba[i]) - double(again.rgba[i])));
    CHECK(diff2 <= 1e-5 * peak);
}

TEST_CASE("empty-space skipping is exact; early exit errs by at most T_min * S_max") {
    render::Renderer& r = gl_renderer();
    const auto density = synthetic::cumulus({48, 48, 36}, 250.0, 3);
    r.set_volume({.density = &density, .extinction = 0.006});
    const auto lg = synthetic::lighting_geometry(density.geom, 4);
    const auto S = synthetic::point_flash_source(density, 0.006, lg, 1, {0, 0, 3000}, 1e6);
    r.upload_source({lg, 1, {0}, {S}});
    const double s_max = *std::max_element(S.begin(), S.end());
    for (const render::Camera& cam : {render::Camera::orbit({0, 0, 4000}, 20000, -60, 8, 50),
                                      render::Camera::orbit({0, 0, 3000}, 1500, 20, 5, 70)}) {  // inside
        render::Settings st = test::volume_only();
        st.early_exit = false;
        st.skip_empty = false;
        render_at(r, cam, st, 96, 64);
        const Image plain = read_march(r);
        st.skip_empty = true;
        render_at(r, cam, st, 96, 64);
        const Image skip = read_march(r);
        st.early_exit = true;
        render_at(r, cam, st, 96, 64);
        const Image early = read_march(r);
        double d_skip = 0.0, d_early = 0.0;
        for (std::size_t i = 0; i < plain.rgba.size(); i += 4) {
            d_skip = std::max(d_skip, std::abs(double(plain.rgba[i]) - double(skip.rgba[i])));
            d_early = std::max(d_early, std::abs(double(plain.rgba[i]) - double(early.rgba[i])));
        }
        // Skipped samples have exactly zero density: identical arithmetic on the rest.
        CHECK(d_skip == 0.0);
        // After exit the remaining integral is <= T_exit * S_max (plus float rounding).
        CHECK(d_early <= st.min_transmittance * s_max * 1.001);
        CHECK(d_early > 0.0);  // the dense cloud does trigger early exits
    }
}

TEST_CASE("internal-scale upsampling does not shift the image") {
    render::Renderer& r = gl_renderer();
    // A smooth, optically thin Gaussian puff off the image centre, lit uniformly: its image is
    // smooth at every internal scale, so sampling does not move its centroid (a hard-edged
    // object would: its edges alias differently at each resolution).
    const auto density = test::gaussian_puff({-60, -640, 1680});
    r.set_volume({.density = &density, .extinction = 2e-4, .precision = render::DensityPrecision::F16});
    core::GridGeometry lg = density.geom;
    lg.dims = {2, 2, 2};
    lg.voxel_size = 640.0;
    upload_all(r, lg, 1, [](int, std::size_t) { return 1.0f; });
    render::Camera cam;
    cam.position = {0, -6000, 2000};
    cam.target = {0, 0, 2000};
    cam.vertical_fov_deg = 30.0;
    const int W = 160, H = 120;
    auto centroid = [&](double scale) {
        render::Settings st = test::volume_only();
        st.internal_scale = scale;
        st.jitter = false;
        render_at(r, cam, st, W, H);
        const std::vector<float> hdr = r.read_hdr();
        double sx = 0, sy = 0, s = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const double v = hdr[(std::size_t(y) * W + std::size_t(x)) * 3];
                sx += v * (x + 0.5);
                sy += v * (y + 0.5);
                s += v;
            }
        REQUIRE(s > 0.0);
        return glm::dvec2(sx / s, sy / s);
    };
    const glm::dvec2 full = centroid(1.0);
    for (double scale : {0.5, 0.25, 0.7}) {
        CAPTURE(scale);
        const glm::dvec2 c = centroid(scale);
        // A half-pixel misalignment of the internal grid moves the centroid by 0.5/scale
        // output pixels; bilinear reconstruction of a symmetric blob keeps it within a few
        // hundredths of a pixel.
        CHECK(std::abs(c.x - full.x) < 0.1);
        CHECK(std::abs(c.y - full.y) < 0.1);
        MESSAGE("scale " << scale << ": centroid shift (" << c.x - full.x << ", " << c.y - full.y << ") px");
    }
}

TEST_CASE("bolt core and glow are attenuated by the cloud in front of them, not behind") {
    render::Renderer& r = gl_renderer();
    // A slab 1 km thick across the whole view: tau = kappa * 1000 = 1.
    const auto slab = test::view_slab(1.0f);
    r.clear_source();
    const render::Camera cam = test::slab_camera();
    render::Settings st = test::volume_only();
    st.bolt = st.glow = true;
    st.glow_radius = 300.0;
    st.air_scattering = 1e-3;
    auto energy = [&](double bolt_y, bool with_cloud) {
        render::LitChannel b;
        for (int i = 0; i < 20; ++i)
            b.segments.push_back(
                {{0.0f, float(bolt_y), float(2500 + 50 * i)}, {0.0f, float(bolt_y), float(2550 + 50 * i)}, 1.0f, 2.0f});
        r.set_channel(b);
        if (with_cloud)
            r.set_volume({.density = &slab, .extinction = 1e-3, .precision = render::DensityPrecision::F16});
        else
            r.clear_volume();
        render_at(r, cam, st, 160, 120);
        double e = 0.0;
        for (float v : r.read_hdr()) e += v;
        return e;
    };
    // Behind the slab: both the core (per-vertex T) and the glow (per-pixel T at the glow
    // depth) see T = exp(-1) along rays within 6 degrees of the axis (chord factor <= 1.006).
    const double behind = energy(2000.0, true) / energy(2000.0, false);
    CHECK(behind == test::rel(std::exp(-1.0), 0.02));
    // In front of the slab: unattenuated (the cloud does not emit: S is absent).
    const double front = energy(-2000.0, true) / energy(-2000.0, false);
    CHECK(front == test::rel(1.0, 0.002));
    MESSAGE("bolt behind a tau = 1 slab keeps " << behind << " of its light (exp(-1) = " << std::exp(-1.0) << ")");
    r.set_channel({});
}

TEST_CASE("a bolt's core leaves nothing where it was: the next bolt's frame is a fresh renderer's") {
    // The core target is cleared only over the last bolt's footprint on screen: a moved
    // channel, one passing beside the camera (clipped at the near plane, projected far off
    // screen), a thick one and a frame with no channel before the next bolt.
    render::Renderer& r = gl_renderer();
    r.clear_volume();
    r.clear_source();
    const render::Settings st = core_only();
    const render::Camera cam = core_camera();
    auto channel = [](glm::vec3 a, glm::vec3 b, float radius) {
        render::LitChannel c;
        for (int i = 0; i < 8; ++i)
            c.segments.push_back(
                {a + (b - a) * (float(i) / 8.0f), a + (b - a) * (float(i + 1) / 8.0f), 100.0f, radius});
        return c;
    };
    const render::LitChannel left = channel({-2000, 0, 1000}, {-2500, 0, 5000}, 2.0f);
    const render::LitChannel right = channel({1500, 0, 500}, {1200, 500, 4500}, 2.0f);
    const render::LitChannel beside = channel({40, -9500, 2990}, {300, -6000, 3100}, 2.0f);
    const render::LitChannel thick = channel({0, 0, 1000}, {100, 0, 5000}, 150.0f);
    const int w = 96, h = 64;
    auto frame = [&](const render::LitChannel& c) {
        r.set_channel(c);
        render_at(r, cam, st, w, h);
        return r.read_hdr();
    };
    auto fresh = [&](const render::LitChannel& c) {
        r.set_channel({});
        render_at(r, cam, st, w + 1, h);  // another size: new targets, cleared whole
        return frame(c);
    };
    const std::vector<float> right_fresh = fresh(right);
    for (const render::LitChannel* before : {&left, &beside, &thick}) {
        fresh(*before);
        CHECK(frame(right) == right_fresh);
        fresh(*before);
        frame({});  // a frame without a channel between
        CHECK(frame(right) == right_fresh);
    }
    // The fixture is meaningful: the channels before light pixels the right one does not.
    CHECK(fresh(beside) != right_fresh);
    CHECK(fresh(thick) != right_fresh);
    r.set_channel({});
}

TEST_CASE("the core's flux is the channel's: bends and free ends add none") {
    // Forty stretches of 121 m (~5 pixels at 8 km, 40 degrees over 240 rows), 30 degrees off
    // vertical: in one straight line, as a zigzag turning 60 degrees at each joint, and apart
    // (each with two free ends). The same length of channel at the same intensity: the same
    // flux, whatever the joints. A ribbon reaching half its width past every end (as the core
    // was drawn before) gives the zigzag 1.066 and the pieces apart 1.294 of the straight line
    // (measured).
    render::Renderer& r = gl_renderer();
    r.clear_volume();
    r.clear_source();
    const render::Settings st = core_only();
    const render::Camera cam = core_camera();
    const float len = 121.0f, sx = len * 0.5f, sz = len * 0.8660254f;
    auto flux = [&](int kind) {
        render::LitChannel c;
        glm::vec3 p{-1200.0f, 0.0f, 1100.0f};
        for (int i = 0; i < 40; ++i) {
            const glm::vec3 step{kind == 1 && i % 2 == 1 ? -sx : sx, 0.0f, sz};
            c.segments.push_back({p, p + step, 100.0f, 2.0f});
            p += kind == 2 ? 2.0f * step : step;  // apart: a gap as long as each piece
        }
        if (kind == 2)  // the pieces apart span twice the height: half of them, twice as bright
            for (std::size_t i = 20; i < c.segments.size(); ++i) c.segments[i].intensity = 0.0f;
        r.set_channel(c);
        render_at(r, cam, st, 320, 240);
        double e = 0.0;
        for (float v : r.read_hdr()) e += v;
        return kind == 2 ? 2.0 * e : e;
    };
    const double straight = flux(0), zigzag = flux(1), apart = flux(2);
    MESSAGE("core flux, zigzag / straight " << zigzag / straight << ", pieces apart / straight " << apart / straight);
    // Sampling a 1.5-pixel ribbon's profile at pixel centres varies with its position across
    // the pixels (by up to 11% for a line along the pixel grid); lines 30 degrees off it average
    // that out: measured 1.015 (zigzag) and 1.010 (apart), so 3%, twice the larger.
    CHECK(zigzag / straight == test::rel(1.0, 0.03));
    CHECK(apart / straight == test::rel(1.0, 0.03));
    r.set_channel({});
}

TEST_CASE("hard cases give finite images") {
    render::Renderer& r = gl_renderer();
    auto finite = [&] {
        for (float v : r.read_hdr())
            if (!std::isfinite(v) || v < 0.0f) return false;
        return true;
    };
    render::Settings st;
    st.exposure = 1e3;
    // A single-voxel cloud, a 1x1x1 lighting grid, the camera inside the voxel.
    const auto one = test::make_grid({1, 1, 1}, 500.0, {-250, -250, 1000}, [](int, int, int) { return 1.0f; });
    r.set_volume({.density = &one, .extinction = 0.05});
    upload_all(r, one.geom, 26, [](int m, std::size_t) { return float(m); });
    render::LitChannel b;
    b.segments.push_back({{0, 0, 1200}, {0, 0, 1200}, 5.0f, 1.0f});  // zero length
    b.segments.push_back({{0, 0, 1200}, {10, 0, 900}, 0.0f, 1.0f});  // zero intensity
    b.segments.push_back({{0, 0, 1100}, {0, 0, 0}, 100.0f, 1e-3f});  // very thin, to the ground
    b.segments.push_back({{0, 0, -50}, {0, 0, -20}, 100.0f, 1.0f});  // under the ground
    r.set_channel(b);
    render::Camera inside;
    inside.position = {0, 0, 1250};
    inside.target = {100, 0, 1250};
    render_at(r, inside, st, 48, 32);
    CHECK(finite());
    // The camera exactly on the lighting node and looking straight down the bolt.
    render::Camera on_node;
    on_node.position = {0, 0, 1250};
    on_node.target = {0, 0, 0};
    on_node.up = {0, 1, 0};
    render_at(r, on_node, st, 48, 32);
    CHECK(finite());
    // Far away, the cloud smaller than a pixel; a huge extinction (opaque voxel).
    r.set_volume({.density = &one, .extinction = 1e3});
    render_at(r, render::Camera::orbit({0, 0, 1250}, 4e5, 10, 1, 30), st, 48, 32);
    CHECK(finite());
    // No volume, no source, no bolt at all.
    r.clear_volume();
    r.clear_source();
    r.set_channel({});
    render_at(r, inside, st, 48, 32);
    CHECK(finite());
}

TEST_CASE("a shader compile error names the file and the line") {
    test::gl_context();
    const auto dir = test::scratch_dir("broken_shaders");
    std::filesystem::copy(render::default_shader_dir(), dir, std::filesystem::copy_options::recursive);
    // Break the line of an included file that opens ray_box (always compiled; volume.glsl is
    // included by march_pixel.glsl).
    std::istringstream in(read_text(dir / "volume.glsl"));
    std::string line, out;
    int broken_line = 0;
    for (int n = 1; std::getline(in, line); ++n) {
        const bool here = broken_line == 0 && line.starts_with("bool ray_box(");
        if (here) broken_line = n;
        out += here ? "this is not glsl;\n" : line + "\n";
    }
    REQUIRE(broken_line > 0);
    test::write_text(dir / "volume.glsl", out);
    const std::string where = "volume.glsl:" + std::to_string(broken_line);
    try {
        render::Renderer broken(test::gl_context().get_proc_address(), dir);
        FAIL("the broken shader compiled");
    } catch (const core::Error& e) {
        CHECK(e.where() == where);
        CHECK(std::string(e.what()).find(where) != std::string::npos);
        MESSAGE(std::string(e.what()));
    }
    // A top-level file, and a missing file.
    std::filesystem::copy_file(render::default_shader_dir() / "volume.glsl", dir / "volume.glsl",
                               std::filesystem::copy_options::overwrite_existing);
    test::write_text(dir / "composite.frag", "#version 450 core\nout vec4 o;\nvoid main() {\n  o = vec3(1.0);\n}\n");
    try {
        render::Renderer broken(test::gl_context().get_proc_address(), dir);
        FAIL("the broken shader compiled");
    } catch (const core::Error& e) {
        CHECK(e.where() == "composite.frag:4");
    }
    std::filesystem::remove(dir / "composite.frag");
    CHECK_THROWS_WITH_AS(render::Renderer(test::gl_context().get_proc_address(), dir),
                         doctest::Contains("composite.frag"), core::Error);
    CHECK_THROWS_AS(render::Renderer(test::gl_context().get_proc_address(), dir / "nope"), core::Error);
}

TEST_CASE("bad inputs are rejected with errors naming the field") {
    render::Renderer& r = gl_renderer();
    auto density = test::make_grid({4, 4, 4}, 100.0, {0, 0, 0}, [](int, int, int) { return 0.5f; });
    density.at(1, 2, 3) = std::nanf("");
    CHECK_THROWS_WITH_AS(r.set_volume({.density = &density, .extinction = 0.01}), doctest::Contains("(1, 2, 3)"),
                         core::Error);
    density.at(1, 2, 3) = 0.5f;
    CHECK_THROWS_AS(r.set_volume({.density = &density, .extinction = -1.0}), core::Error);
    for (const double share : {0.0, -0.5, std::numeric_limits<double>::infinity(), std::nan("")}) {
        CHECK_THROWS_WITH_AS(r.set_volume({.density = &density, .extinction = 0.01, .rain_solved_share = share}),
                             doctest::Contains("rain_solved_share"), core::Error);
        CHECK_THROWS_WITH_AS(r.set_rain_solved_share(share), doctest::Contains("rain_solved_share"), core::Error);
    }
    CHECK_THROWS_AS(r.set_volume({.density = nullptr}), core::Error);
    r.set_volume({.density = &density, .extinction = 0.01});
    core::GridGeometry lg = density.geom;
    std::vector<float> values(lg.cell_count(), 1.0f), short_values(3, 1.0f);
    CHECK_THROWS_AS(r.upload_source({lg, 26, {26}, {values}}), core::Error);            // index out of range
    CHECK_THROWS_AS(r.upload_source({lg, 26, {1, 1}, {values, values}}), core::Error);  // listed twice
    CHECK_THROWS_AS(r.upload_source({lg, 26, {1}, {short_values}}), core::Error);       // wrong size
    CHECK_THROWS_AS(r.upload_source({lg, 7, {0}, {values}}), core::Error);              // bad direction count
    values[5] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH_AS(r.upload_source({lg, 1, {0}, {values}}), doctest::Contains("cell 5"), core::Error);
    render::LitChannel b;
    b.segments.push_back({{0, 0, 0}, {0, 0, 10}, -1.0f, 1.0f});
    CHECK_THROWS_WITH_AS(r.set_channel(b), doctest::Contains("segment 0"), core::Error);
    const render::Camera cam;
    render::Settings st;
    st.internal_scale = 0.0;
    CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("internal_scale"), core::Error);
    st = {};
    st.step_voxels = std::nan("");
    CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("step_voxels"), core::Error);
    for (const int block : {1, 3, 8, -2}) {
        st = {};
        st.temporal_moving_block = block;
        CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("temporal_moving_block"), core::Error);
    }
    for (const int block : {0, 1, 3, 8, -4}) {
        st = {};
        st.temporal_flash_block = block;
        CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("temporal_flash_block"), core::Error);
    }
    // Enumerations set from an integer out of their range.
    for (const int v : {-1, 2, 7}) {
        st = {};
        st.temporal_reshape = render::TemporalReshape(v);
        CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("temporal_reshape"), core::Error);
    }
    for (const int v : {-1, 3}) {
        st = {};
        st.temporal_light = render::TemporalLight(v);
        CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("temporal_light"), core::Error);
    }
    for (const int stride : {0, -1, 9}) {
        st = {};
        st.auto_exposure = true;
        st.meter_stride = stride;
        CHECK_THROWS_WITH_AS(render_at(r, cam, st, 32, 32), doctest::Contains("meter_stride"), core::Error);
    }
    st = {};
    CHECK_THROWS_AS(render_at(r, cam, st, 0, 32), core::Error);
    render::Camera degenerate;
    degenerate.target = degenerate.position;
    CHECK_THROWS_AS(render_at(r, degenerate, st, 32, 32), core::Error);
}
