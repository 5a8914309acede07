// Quick-look images of a density: a vertical slice, a top-down maximum projection and a
// side view of optical depth, and a sunlit side view. For people and docs; the renderer lives in engine/render.
#include "cloud/cloud.h"

#include <algorithm>
#include <cmath>

namespace fulgur::cloud {

namespace {

void put(Image& img, int x, int y, int scale, const std::uint8_t rgb[3]) {
    for (int b = 0; b < scale; ++b)
        for (int a = 0; a < scale; ++a) {
            const std::size_t o =
                3 * (std::size_t(y * scale + b) * std::size_t(img.width) + std::size_t(x * scale + a));
            img.rgb[o] = rgb[0];
            img.rgb[o + 1] = rgb[1];
            img.rgb[o + 2] = rgb[2];
        }
}

Image blank(int w, int h, int scale) {
    Image img;
    img.width = w * scale;
    img.height = h * scale;
    img.rgb.assign(std::size_t(img.width) * std::size_t(img.height) * 3, 0);
    return img;
}

// Side view with attenuated sunlight: for each voxel the sun's transmittance, marched
// towards the sun in half-voxel steps (nearest voxel), then front-to-back compositing along
// +y of (sun * transmittance + ambient), over a sky gradient. Gamma 2.2 for display.
Image render_lit(const core::Grid3<float>& density, double extinction, int scale) {
    const core::Int3 d = density.dims();
    const double tau_voxel = extinction * density.geom.voxel_size;
    const double sun[3] = {-0.62, -0.26, 0.74};  // towards the sun (unit): upper left, slightly in front
    constexpr double kStep = 0.5;                // voxels
    constexpr double kOpaque = 20.0;             // optical depth beyond which the sun is gone (e^-20)
    std::vector<float> sunlight(density.size(), 0.0f);
    core::parallel_for(0, d.z, [&](std::int64_t kk) {
        const int k = int(kk);
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) {
                if (density.at(i, j, k) <= 0.0f) continue;
                double x = i + 0.5, y = j + 0.5, z = k + 0.5, tau = 0.0;
                for (;;) {
                    x += sun[0] * kStep;
                    y += sun[1] * kStep;
                    z += sun[2] * kStep;
                    if (x < 0.0 || y < 0.0 || z < 0.0 || x >= d.x || y >= d.y || z >= d.z || tau > kOpaque) break;
                    tau += double(density.at(int(x), int(y), int(z))) * tau_voxel * kStep;
                }
                sunlight[density.geom.index(i, j, k)] = float(std::exp(-tau));
            }
    });
    Image img = blank(d.x, d.z, scale);
    std::uint8_t rgb[3];
    for (int k = 0; k < d.z; ++k) {
        const double h = double(k) / double(d.z);
        const double sky[3] = {0.30 + 0.1 * (1.0 - h), 0.40 + 0.1 * (1.0 - h), 0.62};
        for (int i = 0; i < d.x; ++i) {
            double trans = 1.0, radiance = 0.0;
            for (int j = 0; j < d.y && trans > 1e-4; ++j) {
                const double a = 1.0 - std::exp(-double(density.at(i, j, k)) * tau_voxel);
                if (a <= 0.0) continue;
                const double ambient = 0.12 + 0.18 * h;  // sky light, brighter aloft
                radiance += trans * a * (double(sunlight[density.geom.index(i, j, k)]) + ambient);
                trans *= 1.0 - a;
            }
            for (int c = 0; c < 3; ++c) {
                const double v = std::clamp(radiance * (c == 2 ? 0.97 : 1.0) + trans * sky[c], 0.0, 1.0);
                rgb[c] = std::uint8_t(std::lround(255.0 * std::pow(v, 1.0 / 2.2)));
            }
            put(img, i, d.z - 1 - k, scale, rgb);
        }
    }
    return img;
}

}  // namespace

Image render_preview(const core::Grid3<float>& density, PreviewKind kind, double extinction, int scale) {
    FULGUR_ASSERT(scale >= 1 && scale <= 64, "preview scale must be in [1, 64]");
    FULGUR_ASSERT(density.size() == density.geom.cell_count() && density.size() > 0, "density grid is malformed");
    const core::Int3 d = density.dims();
    std::uint8_t rgb[3];
    switch (kind) {
        case PreviewKind::SliceXZ: {
            Image img = blank(d.x, d.z, scale);
            const int j = d.y / 2;
            for (int k = 0; k < d.z; ++k)
                for (int i = 0; i < d.x; ++i) {
                    core::pseudo_colour(density.at(i, j, k), rgb);
                    put(img, i, d.z - 1 - k, scale, rgb);
                }
            return img;
        }
        case PreviewKind::TopMax: {
            Image img = blank(d.x, d.y, scale);
            for (int j = 0; j < d.y; ++j)
                for (int i = 0; i < d.x; ++i) {
                    float m = 0.0f;
                    for (int k = 0; k < d.z; ++k) m = std::max(m, density.at(i, j, k));
                    core::pseudo_colour(m, rgb);
                    put(img, i, d.y - 1 - j, scale, rgb);
                }
            return img;
        }
        case PreviewKind::SideDepth: {
            Image img = blank(d.x, d.z, scale);
            const double step = extinction * density.geom.voxel_size;
            for (int k = 0; k < d.z; ++k)
                for (int i = 0; i < d.x; ++i) {
                    double tau = 0.0;
                    for (int j = 0; j < d.y; ++j) tau += density.at(i, j, k);
                    const double v = 1.0 - std::exp(-tau * step);
                    const auto g = std::uint8_t(std::clamp(std::lround(255.0 * v), 0L, 255L));
                    rgb[0] = rgb[1] = rgb[2] = g;
                    put(img, i, d.z - 1 - k, scale, rgb);
                }
            return img;
        }
        case PreviewKind::SideLit:
            return render_lit(density, extinction, scale);
    }
    FULGUR_ASSERT(false, "unknown preview kind");
    return {};
}

void write_preview_png(const std::filesystem::path& path, const core::Grid3<float>& density,
                       std::span<const PreviewKind> kinds, double extinction, int scale) {
    FULGUR_ASSERT(!kinds.empty(), "at least one preview kind");
    std::vector<Image> parts;
    for (PreviewKind k : kinds) parts.push_back(render_preview(density, k, extinction, scale));
    constexpr int kGap = 4;
    int w = 0, h = 0;
    for (const Image& p : parts) {
        w += p.width;
        h = std::max(h, p.height);
    }
    w += kGap * int(parts.size() - 1);
    std::vector<std::uint8_t> out(std::size_t(w) * std::size_t(h) * 3, 255);  // white gaps and padding
    int x0 = 0;
    for (const Image& p : parts) {
        for (int y = 0; y < p.height; ++y) {
            // Bottom-align the panels so the side views share the ground line.
            const int yo = y + (h - p.height);
            std::copy_n(p.rgb.data() + std::size_t(y) * std::size_t(p.width) * 3, std::size_t(p.width) * 3,
                        out.data() + (std::size_t(yo) * std::size_t(w) + std::size_t(x0)) * 3);
        }
        x0 += p.width + kGap;
    }
    core::write_png(path, w, h, 3, out);
}

}  // namespace fulgur::cloud
