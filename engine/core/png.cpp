#include "core/core.h"

#include <algorithm>
#include <array>
#include <vector>

#include <stb_image_write.h>

namespace fulgur::core {

void write_png(const std::filesystem::path& path, int width, int height, int channels,
               std::span<const std::uint8_t> pixels) {
    FULGUR_ASSERT(width > 0 && height > 0 && (channels == 3 || channels == 4), "bad PNG dimensions");
    FULGUR_ASSERT(pixels.size() == std::size_t(width) * std::size_t(height) * std::size_t(channels),
                  "pixel buffer size does not match the image");
    // Encoded in memory, then written through AtomicFile (checked, atomic, never half a PNG).
    std::vector<std::uint8_t> png;
    auto append = [](void* ctx, void* data, int size) {
        auto* out = static_cast<std::vector<std::uint8_t>*>(ctx);
        const auto* p = static_cast<const std::uint8_t*>(data);
        out->insert(out->end(), p, p + size);
    };
    if (!stbi_write_png_to_func(append, &png, width, height, channels, pixels.data(), width * channels))
        throw Error(path.string(), "cannot encode the PNG");
    AtomicFile out(path);
    out.write(png.data(), png.size());
    out.commit();
}

void pseudo_colour(double t, std::uint8_t rgb[3]) noexcept {
    // Piecewise-linear viridis through 9 control points (perceptually ordered, colour-blind safe).
    static constexpr std::array<std::array<double, 3>, 9> k = {{{0.267, 0.005, 0.329},
                                                                {0.283, 0.141, 0.458},
                                                                {0.254, 0.265, 0.530},
                                                                {0.207, 0.372, 0.553},
                                                                {0.164, 0.471, 0.558},
                                                                {0.128, 0.567, 0.551},
                                                                {0.135, 0.659, 0.518},
                                                                {0.478, 0.821, 0.318},
                                                                {0.993, 0.906, 0.144}}};
    if (!(t > 0.0)) t = 0.0;  // NaN maps to the bottom of the scale
    t = std::min(t, 1.0) * double(k.size() - 1);
    const std::size_t i = std::min<std::size_t>(std::size_t(t), k.size() - 2);
    const double f = t - double(i);
    for (int c = 0; c < 3; ++c)
        rgb[c] = std::uint8_t(std::clamp((k[i][c] + (k[i + 1][c] - k[i][c]) * f) * 255.0 + 0.5, 0.0, 255.0));
}

}  // namespace fulgur::core
