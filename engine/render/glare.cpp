// The glare model (render.h): Spencer et al.'s photopic point-spread function, its energy
// within a radius, and its fit by the renderer's pyramid of Gaussians.
#include "render/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace fulgur::render {

namespace {

constexpr double kA = 0.02;  // degrees: the PSF's core scale
constexpr double kInf = std::numeric_limits<double>::infinity();
// Square degrees per steradian: f_i are per steradian with areas measured in square degrees.
constexpr double kDeg2PerSr = (180.0 / std::numbers::pi) * (180.0 / std::numbers::pi);

// Non-negative least squares min |A w - b|^2, w >= 0, by cyclic coordinate descent on the
// normal equations (G = A^T A, r = A^T b; n is the pyramid's level count, <= 16).
std::vector<double> nnls(const std::vector<double>& G, const std::vector<double>& r, std::size_t n) {
    std::vector<double> w(n, 0.0), g(n, 0.0);  // g = G w
    for (int sweep = 0; sweep < 2000; ++sweep) {
        double moved = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            const double gii = G[i * n + i];
            if (!(gii > 0.0)) continue;
            const double next = std::max(0.0, w[i] + (r[i] - g[i]) / gii);
            const double d = next - w[i];
            if (d == 0.0) continue;
            w[i] = next;
            moved = std::max(moved, std::abs(d));
            for (std::size_t j = 0; j < n; ++j) g[j] += G[j * n + i] * d;
        }
        if (moved < 1e-12) break;
    }
    return w;
}

}  // namespace

double glare_psf(double theta_deg) noexcept {
    const double t = std::max(theta_deg, 0.0), u = t + kA, q = t / kA;
    const double f0 = 2.61e6 * std::exp(-q * q), f1 = 20.91 / (u * u * u), f2 = 72.37 / (u * u);
    return 0.384 * f0 + 0.478 * f1 + 0.138 * f2;
}

double glare_energy_within(double theta_deg) noexcept {
    const double R = std::max(theta_deg, 0.0), q = R / kA, u = R + kA;
    // Integrals of 2 pi theta f_i(theta) from 0 to R, in square degrees.
    const double e0 = 2.61e6 * std::numbers::pi * kA * kA * -std::expm1(-q * q);
    const double e1 = 2.0 * std::numbers::pi * 20.91 * R * R / (2.0 * kA * u * u);
    const double e2 = 2.0 * std::numbers::pi * 72.37 * (std::log1p(q) + kA / u - 1.0);
    return (0.384 * e0 + 0.478 * e1 + 0.138 * e2) / kDeg2PerSr;
}

double glare_level_sigma(int k) noexcept {
    // Variance per axis, in level-j texels: a box downsample over 4 finer texels adds 1.25
    // finer texels^2 (0.3125 of level j's); an upsample from level j adds 0.1875 for the
    // bilinear weights (the finer texels sit a quarter texel off the coarser ones) plus its
    // taps': 0.25 for four taps half a texel either side, 0.5 for the nine-tap [1 2 1] tent
    // (onto levels kGlareWideFrom and coarser). Summed over the k steps down and back up, in
    // internal pixels^2 (4^j per level-j texel^2). Plus the texel's own box (1/12) and the
    // bilinear upsampling to the output (3/16).
    double chain = 0.0;
    for (int j = 1; j <= k; ++j) chain += (0.3125 + 0.1875 + (j - 1 >= kGlareWideFrom ? 0.5 : 0.25)) * std::pow(4.0, j);
    return std::sqrt(chain + 1.0 / 12.0 + 3.0 / 16.0);
}

GlareFit fit_glare(double output_pixel_deg, double internal_scale, int levels, double reach_deg) {
    FULGUR_ASSERT(output_pixel_deg > 0.0 && internal_scale > 0.0 && internal_scale <= 1.0 && levels >= 1 &&
                      reach_deg > output_pixel_deg / internal_scale,
                  "fit_glare: needs a positive pixel size, a scale in (0, 1], levels >= 1 and a reach past a pixel");
    GlareFit fit;
    fit.reach_deg = reach_deg;
    // The pyramid starts at the ray march's resolution: what P puts within half a ray-march
    // pixel stays in place.
    const double internal_pixel_deg = output_pixel_deg / internal_scale;
    fit.keep = glare_energy_within(0.5 * internal_pixel_deg);
    const std::size_t n = std::size_t(levels);
    std::vector<double> sigma_deg(n);
    for (std::size_t k = 0; k < n; ++k) {
        fit.sigma_px.push_back(glare_level_sigma(int(k)));
        sigma_deg[k] = fit.sigma_px[k] * internal_pixel_deg;
    }
    // Rows: the energy within radii log-spaced from one ray-march pixel to the reach, and,
    // weighted up, the light the levels spread in all (the pyramid clamps at the frame's edges,
    // so all of it stays in the frame): P's beyond the kept part, within the reach.
    constexpr int kRadii = 96;
    std::vector<double> G(n * n, 0.0), r(n, 0.0), row(n);
    auto add_row = [&](double radius, double weight) {
        const double target = glare_energy_within(std::min(radius, reach_deg)) - fit.keep;
        for (std::size_t k = 0; k < n; ++k)
            row[k] = radius == kInf ? 1.0 : -std::expm1(-radius * radius / (2.0 * sigma_deg[k] * sigma_deg[k]));
        for (std::size_t a = 0; a < n; ++a) {
            r[a] += weight * row[a] * target;
            for (std::size_t b = 0; b < n; ++b) G[a * n + b] += weight * row[a] * row[b];
        }
    };
    std::vector<double> radii(kRadii);
    for (int j = 0; j < kRadii; ++j)
        radii[std::size_t(j)] = internal_pixel_deg * std::pow(reach_deg / internal_pixel_deg, double(j) / (kRadii - 1));
    for (const double radius : radii) add_row(radius, 1.0);
    add_row(kInf, 64.0);
    fit.weights = nnls(G, r, n);
    for (const double radius : radii) {
        double m = fit.keep;
        for (std::size_t k = 0; k < n; ++k)
            m += fit.weights[k] * -std::expm1(-radius * radius / (2.0 * sigma_deg[k] * sigma_deg[k]));
        fit.max_error = std::max(fit.max_error, std::abs(m - glare_energy_within(radius)));
    }
    return fit;
}

}  // namespace fulgur::render
