// Golden-image comparison for GL tests (tests/render and the scene golden tests).
//
// Metric, on 8-bit RGBA images of equal size (alpha ignored):
//   * per pixel, d = max over R, G, B of |actual - expected|;
//   * max_diff = the largest d; a pixel FAILS when d > tolerance.pixel_threshold;
//   * failing_fraction = failing pixels / all pixels;
//   * mean_diff = mean of |actual - expected| over all RGB channels.
// The comparison passes when failing_fraction <= tolerance.max_failing_fraction,
// mean_diff <= tolerance.max_mean_diff and max_diff <= tolerance.max_diff.
// (Software rasterizers differ slightly between CPUs and Mesa versions: a few pixels may
// move by a few levels; a real regression moves many pixels or moves them far.)
//
// On failure it writes <name>.actual.png, <name>.expected.png and <name>.diff.png (d scaled
// x8, pseudo-coloured) into the output directory. Goldens are (re)generated only when the
// environment variable FULGUR_UPDATE_GOLDENS=1 is set: the actual image is then written as
// the expected one and the comparison reports `regenerated` and fails (nothing was checked).
// Under CI (the environment variable CI set, not "0" or "false") the switch is refused.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace fulgur::test {

struct GoldenTolerance {
    int pixel_threshold = 8;              ///< a pixel fails above this channel difference (levels)
    double max_failing_fraction = 0.002;  ///< of all pixels
    double max_mean_diff = 0.5;           ///< levels, over all RGB channels
    int max_diff = 255;                   ///< hard cap on the largest difference (255: none)
};

struct GoldenResult {
    bool passed = false;
    bool regenerated = false;
    int max_diff = 0;
    double failing_fraction = 0.0;
    double mean_diff = 0.0;
    std::string message;  ///< one line: figures, or why it failed, and where the images are
};

/// True when FULGUR_UPDATE_GOLDENS=1; throws core::Error when it is set under CI.
bool update_goldens_requested();

/// Compares `rgba` (width x height x 4, rows top to bottom) with the PNG `expected`.
/// Missing or differently sized goldens fail (unless regenerating).
GoldenResult compare_golden(const std::filesystem::path& expected, int width, int height,
                            std::span<const std::uint8_t> rgba, const GoldenTolerance& tolerance,
                            const std::filesystem::path& output_dir);

/// Reads an 8-bit PNG as RGBA (throws core::Error naming the file on failure).
std::vector<std::uint8_t> read_png_rgba(const std::filesystem::path& path, int& width, int& height);

}  // namespace fulgur::test
