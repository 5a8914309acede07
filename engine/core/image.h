// fulgur::core — 8-bit image output (PNG through stb_image_write) and a pseudo-colour map.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>

namespace fulgur::core {

/// Writes an 8-bit RGB or RGBA PNG (channels 3 or 4), rows top to bottom.
void write_png(const std::filesystem::path& path, int width, int height, int channels,
               std::span<const std::uint8_t> pixels);

/// Maps a scalar in [0,1] to a perceptual pseudo-colour (viridis-like), 8-bit RGB.
void pseudo_colour(double t, std::uint8_t rgb[3]) noexcept;

}  // namespace fulgur::core
