// The image of a homogeneous layer lit by the sun against an independent Monte Carlo of the
// radiance leaving it: the whole path from the sun's truth to the pixel (the truth's orders
// >= 2 on the lighting grid, interpolated between its 26 directions and along the ray by the
// march; order 1 drawn at full resolution from the sun's transmittance) at g = 0 and at the
// day cumulus's 0.8, where the interpolation between directions is known to lose light
// (docs/blender.md, "A third estimate: a homogeneous slab"). The figures are pinned where they
// are, short of 1: the test says how far the image of a cloud with voxels one optical depth
// thick falls short, and moves when the renderer's reading of S at surfaces changes.
#include "gl_fixture.h"
#include "support/layer_monte_carlo.h"
#include "support/test_support.h"

#include "sky/sky.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <doctest/doctest.h>

#include <glm/trigonometric.hpp>

#include <cmath>
#include <vector>

using namespace fulgur;

namespace {

// The middle of the image, pixels [x0, x1) x [y0, y1): the mean of the march's green channel.
double box_mean(const std::vector<float>& m, int w, int x0, int x1, int y0, int y1) {
    double s = 0.0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) s += double(m[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4 + 1]);
    return s / double((x1 - x0) * (y1 - y0));
}

}  // namespace

TEST_CASE("the image of a sunlit homogeneous layer against the layer's own Monte Carlo of its radiance") {
    // The layer: 10 voxels of 100 m at 0.01 per metre (optical depth 10, 1 per voxel), albedo
    // 0.99, 100 x 100 voxels wide, S on the density's own voxels. The sun at 32 degrees; the
    // camera 3 km from the middle of the top, 35 degrees above it, 20 degrees field of view: the
    // middle 16 x 12 of its 32 x 24 pixels see about 0.7 x 0.9 km of the top, over 4 km (8
    // transport mean free paths at g = 0.8) from the edges, i.e. an infinite layer.
    const int nx = 100, layers = 10, W = 32, H = 24;
    const double voxel = 100.0, sigma = 0.01, albedo = 0.99, top = voxel * layers;
    const double el = glm::radians(32.0), az = glm::radians(25.0);
    const glm::dvec3 sun = -glm::dvec3(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    render::Camera cam;
    cam.target = {0.0, 0.0, top};
    const double ce = glm::radians(35.0);
    cam.position = cam.target + 3000.0 * glm::dvec3(0.0, -std::cos(ce), std::sin(ce));
    cam.vertical_fov_deg = 20.0;
    const int x0 = W / 4, x1 = 3 * W / 4, y0 = H / 4, y1 = 3 * H / 4;
    // Toward the camera from where 3 x 3 pixels spread over the box meet the top.
    std::vector<glm::dvec3> views;
    for (const int y : {y0, (y0 + y1) / 2, y1 - 1})
        for (const int x : {x0, (x0 + x1) / 2, x1 - 1}) views.push_back(-test::pixel_ray(cam, x, y, W, H));

    render::Renderer& r = test::gl_renderer();
    r.clear_source();
    for (const double g : {0.0, 0.8}) {
        CAPTURE(g);
        // Two empty layers above the cloud, as every cloud has: the march reads the density
        // trilinearly, so its top falls to 0 over the voxel around the face.
        const core::GridGeometry geom{{nx, nx, layers + 2}, voxel, {-0.5 * nx * voxel, -0.5 * nx * voxel, 0.0}};
        transport::LightingMedium m;
        m.density = core::Grid3<float>(geom, 0.0f);
        for (int k = 0; k < layers; ++k)
            for (int j = 0; j < nx; ++j)
                for (int i = 0; i < nx; ++i) m.density.at(i, j, k) = 1.0f;
        m.optics = {sigma, albedo, g};
        const solve::Media media{m, m, 1, m, {}};
        const std::vector<glm::dvec3> dirs = transport::output_directions(26);
        sky::TruthOptions to;
        to.paths = 1'000'000;
        const sky::TruthField truth = sky::sun_truth(media, sun, dirs, to);

        // The static light: the truth's orders >= 2, grey; the sun's order 1 at full resolution.
        // The layer is the same in every column far from its edges, so each layer's S is the
        // mean over the middle 40 x 40 columns, in every column: the truth's expected value
        // there with 1/1600 of a voxel's variance (the camera sees only the middle).
        const std::size_t cells = geom.cell_count();
        std::vector<std::vector<float>> rgb(dirs.size(), std::vector<float>(cells * 3));
        for (std::size_t d = 0; d < dirs.size(); ++d)
            for (int k = 0; k < geom.dims.z; ++k) {
                const float mean =
                    float(test::middle_columns_mean(truth.field.multiple, d, k, nx / 2 - 20, nx / 2 + 20));
                for (int j = 0; j < nx; ++j)
                    for (int i = 0; i < nx; ++i)
                        for (int c = 0; c < 3; ++c) rgb[d][3 * geom.index(i, j, k) + std::size_t(c)] = mean;
            }
        r.set_volume({.density = &m.density, .extinction = sigma, .precision = render::DensityPrecision::F16});
        render::StaticUpload up;
        up.geometry = geom;
        up.direction_count = 26;
        for (const std::vector<float>& v : rgb) up.rgb.emplace_back(v.data(), v.size());
        r.upload_static(up);
        const core::Grid3<float> tsun = sky::sun_transmittance(m.density, sigma, sun);
        render::SunDesc sd;
        sd.direction = sun;
        sd.irradiance_rgb = {1.0, 1.0, 1.0};
        sd.albedo = albedo;
        sd.g = g;
        sd.transmittance = &tsun;
        r.set_sun(sd);
        render::Settings st = test::volume_only();
        st.jitter = false;
        const auto shot = [&] {
            test::render_at(r, cam, st, W, H);
            int w = 0, h = 0;
            const std::vector<float> march = r.read_march(w, h);
            return box_mean(march, w, x0, x1, y0, y1);
        };
        const double image = shot();
        r.clear_sun();
        const double image_static = shot();

        const test::LayerEstimate ref =
            test::layer_monte_carlo({sigma, albedo, g, voxel, layers, sun, voxel}, {}, views, 50'000, 20);
        // The box's radiance: the mean over the 3 x 3 directions, order 1 and orders >= 2.
        double mc1 = 0.0, mcm = 0.0, se1 = 0.0, sem = 0.0;
        for (std::size_t v = 0; v < views.size(); ++v) {
            mc1 += ref.radiance[0][v] / double(views.size());
            mcm += ref.radiance[1][v] / double(views.size());
            se1 += ref.radiance_se[0][v] / double(views.size());  // the directions share photons
            sem += ref.radiance_se[1][v] / double(views.size());
        }
        const double total = image / (mc1 + mcm), single = (image - image_static) / mc1;
        MESSAGE("g " << g << ": image / layer Monte Carlo " << total << " (order 1 " << single << ", orders >= 2 "
                     << image_static / mcm << "); the Monte Carlo's relative SE: order 1 " << se1 / mc1
                     << ", orders >= 2 " << sem / mcm);
        // Pinned, not 1: where the layer meets the empty voxels above it, S and the sun's
        // transmittance vary over a voxel of one optical depth, and the march reads them at the
        // voxels' centres; at g = 0.8 S also peaks between the baked directions toward this
        // camera. Measured (2026-12-01): totals 0.9468 / 0.8977, orders 1 0.9547 / 0.9476.
        // Bounds: the totals' spread over three seeds of the truth is 0.16% and 0.09% (the
        // layer's S averaged over 1600 columns), the layer Monte Carlo's standard error 0.1-0.3%
        // (printed); 1% is four or more of those combined, and what a better read of S at
        // surfaces moves. Order 1 is deterministic on the image's side (the transmittance by
        // exact traversal, no paths) and the Monte Carlo's is within 0.04-0.07%: 0.3% also
        // covers the float phase function and half-float transmittance.
        const double pinned_total = g == 0.0 ? 0.9468 : 0.8977, pinned_single = g == 0.0 ? 0.9547 : 0.9476;
        CHECK(total == test::rel(pinned_total, 0.01));
        CHECK(single == test::rel(pinned_single, 0.003));
        r.clear_static();
        r.clear_sun();
    }
}
