// Quick-look images of a density: a vertical slice, a top-down maximum projection and a
// side view of optical depth. For people and docs; the renderer lives in engine/render.
#include "cloud/cloud.h"

#include <algorithm>
#include <cmath>

namespace fulgur::cloud {

namespace {

void put(Image& img, int x, int y, int scale, const std::uint8_t rgb[3]) {
    for (int b = 0; b < scale; ++b)
        for (int a = 0; a < scale; ++a) {
            const std::size_t o = 3 * (std::size_t(y * scale + b) * std::size_t(img.width) + std::size_t(x * scale + a));
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
    }
    FULGUR_ASSERT(false, "unknown preview kind");
    return {};
}

void write_preview_png(const std::filesystem::path& path, const core::Grid3<float>& density, double extinction,
                       int scale) {
    const Image parts[3] = {render_preview(density, PreviewKind::SliceXZ, extinction, scale),
                            render_preview(density, PreviewKind::SideDepth, extinction, scale),
                            render_preview(density, PreviewKind::TopMax, extinction, scale)};
    constexpr int kGap = 4;
    int w = 0, h = 0;
    for (const Image& p : parts) {
        w += p.width;
        h = std::max(h, p.height);
    }
    w += 2 * kGap;
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
