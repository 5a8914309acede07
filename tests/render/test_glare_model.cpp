// The glare model (render.h): Spencer et al.'s point-spread function, its closed-form energy
// within a radius, and the pyramid's fit to it.
#include "render/render.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

using namespace fulgur;

namespace {

// The energy within R by the midpoint rule on a log-spaced grid (dOmega = 2 pi theta dtheta,
// theta in radians): an independent check of the closed forms.
double energy_numeric(double R_deg) {
    const double to_rad = std::numbers::pi / 180.0;
    double sum = 0.0;
    const int n = 200000;
    const double lo = 1e-6, ratio = std::pow(R_deg / lo, 1.0 / n);
    sum += render::glare_psf(0.0) * std::numbers::pi * (lo * to_rad) * (lo * to_rad);  // the disc below lo
    for (int i = 0; i < n; ++i) {
        const double a = lo * std::pow(ratio, i), b = a * ratio, m = std::sqrt(a * b);
        sum += render::glare_psf(m) * 2.0 * std::numbers::pi * (m * to_rad) * ((b - a) * to_rad);
    }
    return sum;
}

}  // namespace

TEST_CASE("glare: the energy within a radius is the integral of the point-spread function") {
    for (const double R : {0.005, 0.02, 0.05, 0.3, 2.0, 10.0, 40.0}) {
        CAPTURE(R);
        // 2e5 log-spaced midpoints: the quadrature's own error is below 1e-6 of the value.
        CHECK(render::glare_energy_within(R) == test::rel(energy_numeric(R), 1e-5));
    }
    CHECK(render::glare_energy_within(0.0) == 0.0);
    // f0 and f1 hold one unit each, f2's log tail reaches it at ~80 degrees: the whole PSF
    // holds 1 there (Spencer's normalization), within the closed forms' 0.2% of f0 and f1.
    CHECK(render::glare_energy_within(80.0) == test::rel(1.0, 0.01));
    double last = 0.0;
    for (double R = 1e-4; R < 90.0; R *= 1.3) {
        const double e = render::glare_energy_within(R);
        CHECK(e > last);
        last = e;
    }
}

TEST_CASE("glare: the pyramid's Gaussians fit the point-spread function") {
    struct View {
        double fov;
        int height;
        double scale;
    };
    for (const View v : {View{50.0, 360, 0.5}, View{50.0, 720, 0.5}, View{50.0, 1080, 0.5}, View{20.0, 256, 1.0},
                         View{70.0, 720, 0.25}}) {
        const double pixel = v.fov / v.height;
        const double aspect = 16.0 / 9.0;
        const double reach = std::atan(std::tan(v.fov * std::numbers::pi / 360.0) * std::sqrt(1.0 + aspect * aspect)) *
                             180.0 / std::numbers::pi;
        int levels = 1;
        while (levels < 10 && (int(v.height * v.scale) >> levels) >= 2) ++levels;
        const render::GlareFit f = render::fit_glare(pixel, v.scale, levels, reach);
        CAPTURE(v.fov);
        CAPTURE(v.height);
        CAPTURE(v.scale);
        CHECK(f.keep == doctest::Approx(render::glare_energy_within(0.5 * pixel / v.scale)));
        double sum = f.keep;
        for (const double w : f.weights) {
            CHECK(w >= 0.0);
            sum += w;
        }
        // What the frame holds is conserved: the kept light and the levels' weights add up to
        // P's energy within the reach (weighted 64x in the fit: within 0.5%).
        CHECK(sum == test::rel(render::glare_energy_within(reach), 0.005));
        // Sums of Gaussians doubling in width follow P's energy-within-radius curve within
        // 0.02 of the point's light from one pixel to the frame's corner (measured 0.004-0.011).
        CHECK(f.max_error <= 0.02);
        MESSAGE("fov " << v.fov << " height " << v.height << " scale " << v.scale << ": keep " << f.keep << ", levels "
                       << levels << ", largest error " << f.max_error);
    }
}
