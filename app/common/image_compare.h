// Comparing two renders of the same view that differ only in the cloud's radiance (the
// basis method against its reference, the direct solve): the paper judged its result from
// images and a difference image scaled so that 10% is white (Dobashi et al. 2007, Fig. 8).
// Works on float RGBA images (render::Renderer::read_march: rgb radiance, a transmittance),
// compared by luminance (Rec. 709 weights). Core-only, so unit tests need no GL.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace fulgur::app {

struct RadianceComparison {
    double relative_l2 = 0.0;     ///< ||Y_test - Y_ref|| / ||Y_ref|| over all pixels
    double max_difference = 0.0;  ///< max |Y_test - Y_ref| / max Y_ref
    /// Among lit pixels (Y_ref or Y_test above 1% of max Y_ref), the fraction whose
    /// |Y_test - Y_ref| exceeds `threshold` x max Y_ref (what the paper's difference image
    /// shows as white).
    double fraction_over = 0.0;
    double threshold = 0.1;
    double reference_max = 0.0;  ///< max Y_ref
    std::size_t lit_pixels = 0;
};

/// Both images RGBA float of the same size (throws core::Error otherwise, or when a value is
/// not finite). A black reference gives relative figures against 1 (absolute differences).
RadianceComparison compare_radiance(std::span<const float> test_rgba, std::span<const float> ref_rgba,
                                    double threshold = 0.1);

/// The displayed (tone-mapped, 8-bit RGBA) images of the same size (throws core::Error
/// otherwise): mean |difference| in levels over all RGB channels, and the fraction of pixels
/// whose largest channel difference exceeds `threshold_levels` (25: 10% of the range).
struct DisplayDifference {
    double mean_levels = 0.0, fraction_over = 0.0;
};
DisplayDifference compare_display(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b,
                                  int threshold_levels = 25);

/// The difference image, RGBA8: grey level |Y_test - Y_ref| / (full_scale x max Y_ref),
/// white at full_scale (default 10%, the paper's scaling) and above.
std::vector<std::uint8_t> difference_image(std::span<const float> test_rgba, std::span<const float> ref_rgba,
                                           double full_scale = 0.1);

}  // namespace fulgur::app
