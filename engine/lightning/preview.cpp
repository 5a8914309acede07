// A side-view sketch of lit bolt segments over the cloud's projected density: the visual
// check that generated bolts look like lightning (jagged, branching, thinning toward the
// tips). Not the renderer: no camera, no scattering, just an orthographic x-z projection.
#include "lightning/lightning.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>

namespace fulgur::lightning {

std::vector<std::uint8_t> draw_side_view(std::span<const LitSegment> lit, const core::Grid3<float>* density,
                                         const Box& view, int width, int& height, double reference) {
    FULGUR_ASSERT(width >= 16 && width <= 8192, "draw_side_view: width must be in [16, 8192]");
    const double wx = view.hi.x - view.lo.x, wz = view.hi.z - view.lo.z;
    FULGUR_ASSERT(wx > 0.0 && wz > 0.0, "draw_side_view: empty view box");
    height = std::clamp(int(std::lround(width * wz / wx)), 16, 8192);
    const std::size_t W = std::size_t(width), H = std::size_t(height);
    const double px_per_m = double(width) / wx;
    auto to_px = [&](const glm::dvec3& p) {
        return glm::dvec2((p.x - view.lo.x) * px_per_m, (view.hi.z - p.z) * double(height) / wz);
    };

    // Background: night sky, the cloud's optical look (1 - exp(-column density)), dark ground.
    std::vector<float> rgb(W * H * 3, 0.0f);
    std::vector<float> column;
    int nx = 0, nz = 0;
    if (density) {
        nx = density->dims().x;
        nz = density->dims().z;
        column.assign(std::size_t(nx) * std::size_t(nz), 0.0f);
        for (int k = 0; k < nz; ++k)
            for (int j = 0; j < density->dims().y; ++j)
                for (int i = 0; i < nx; ++i)
                    column[std::size_t(i) + std::size_t(nx) * std::size_t(k)] += density->at(i, j, k);
        for (float& c : column) c = float(density->geom.voxel_size) * c;  // metres of density-1 cloud
    }
    for (std::size_t y = 0; y < H; ++y)
        for (std::size_t x = 0; x < W; ++x) {
            const double wxm = view.lo.x + (double(x) + 0.5) / px_per_m;
            const double wzm = view.hi.z - (double(y) + 0.5) * wz / double(height);
            float r = 0.015f, g = 0.018f, b = 0.035f;
            if (density) {
                const glm::dvec3 u = density->geom.to_voxel(glm::dvec3(wxm, 0.0, wzm));
                const int i = int(std::floor(u.x)), k = int(std::floor(u.z));
                if (i >= 0 && i < nx && k >= 0 && k < nz) {
                    // 1 / 3000 m: a few km of cloud look opaque; a sketch, not a transport result.
                    const float a =
                        1.0f - std::exp(-column[std::size_t(i) + std::size_t(nx) * std::size_t(k)] / 3000.0f);
                    r += 0.16f * a, g += 0.17f * a, b += 0.21f * a;
                }
            }
            if (wzm < view.lo.z + 1e-9) r = 0.03f, g = 0.025f, b = 0.02f;
            float* o = &rgb[3 * (y * W + x)];
            o[0] = r, o[1] = g, o[2] = b;
        }

    // Bolt: additive Gaussian footprints along each stretch; width ~ sqrt(intensity).
    double imax = 0.0;
    for (const LitSegment& l : lit) imax = std::max(imax, l.intensity);
    if (reference > 0.0) imax = reference;
    std::vector<float> glow(W * H, 0.0f);
    if (imax > 0.0) {
        for (const LitSegment& l : lit) {
            const double rel = std::min(1.0, l.intensity / imax);
            if (!(rel > 0.0)) continue;
            const double sigma = 0.35 + 0.85 * std::sqrt(rel);  // px
            const double amp = std::pow(rel, 0.6);              // compresses the range: dim branches stay visible
            const glm::dvec2 a = to_px(l.a), b = to_px(l.b);
            const double len = glm::length(b - a);
            const int steps = std::max(1, int(std::ceil(len / 0.3)));
            const int rad = int(std::ceil(3.0 * sigma));
            const double per_step = amp * (len / steps) / (sigma * 2.5066282746310002);  // line density
            for (int s = 0; s <= steps; ++s) {
                const glm::dvec2 p = a + (b - a) * (double(s) / steps);
                const int cx = int(std::floor(p.x)), cy = int(std::floor(p.y));
                for (int dy = -rad; dy <= rad; ++dy)
                    for (int dx = -rad; dx <= rad; ++dx) {
                        const int x = cx + dx, y = cy + dy;
                        if (x < 0 || y < 0 || x >= width || y >= height) continue;
                        const double ddx = x + 0.5 - p.x, ddy = y + 0.5 - p.y;
                        const double w = std::exp(-(ddx * ddx + ddy * ddy) / (2.0 * sigma * sigma));
                        glow[std::size_t(y) * W + std::size_t(x)] += float(per_step * w);
                    }
            }
        }
    }
    std::vector<std::uint8_t> out(W * H * 3);
    for (std::size_t i = 0; i < W * H; ++i) {
        const float v = 1.0f - std::exp(-1.6f * glow[i]);  // soft saturation
        const float tint[3] = {0.88f, 0.9f, 1.0f};
        for (int c = 0; c < 3; ++c) {
            const float x = std::min(1.0f, rgb[3 * i + std::size_t(c)] + v * tint[c]);
            out[3 * i + std::size_t(c)] = std::uint8_t(std::lround(255.0f * std::sqrt(x)));  // ~sRGB
        }
    }
    return out;
}

}  // namespace fulgur::lightning
