#include "image_compare.h"

#include "core/core.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

namespace fulgur::app {

namespace {

double luminance(std::span<const float> rgba, std::size_t p) {
    return 0.2126 * double(rgba[4 * p]) + 0.7152 * double(rgba[4 * p + 1]) + 0.0722 * double(rgba[4 * p + 2]);
}

// Checks sizes and finiteness; returns the pixel count and max Y_ref (1 when the reference
// is black, so relative figures fall back to absolute ones).
std::size_t check_pair(std::span<const float> a, std::span<const float> b, double& ref_max) {
    if (a.size() != b.size() || a.size() % 4 != 0)
        throw core::Error("compare_radiance", "images of different sizes or not RGBA (" + std::to_string(a.size()) +
                                                  " and " + std::to_string(b.size()) + " floats)");
    const std::size_t n = a.size() / 4;
    ref_max = 0.0;
    for (std::size_t p = 0; p < n; ++p) {
        const double ya = luminance(a, p), yb = luminance(b, p);
        if (!std::isfinite(ya) || !std::isfinite(yb))
            throw core::Error("compare_radiance", "non-finite radiance at pixel " + std::to_string(p));
        ref_max = std::max(ref_max, yb);
    }
    return n;
}

}  // namespace

RadianceComparison compare_radiance(std::span<const float> test_rgba, std::span<const float> ref_rgba,
                                    double threshold) {
    FULGUR_ASSERT(threshold > 0.0, "threshold must be positive");
    RadianceComparison c;
    c.threshold = threshold;
    const std::size_t n = check_pair(test_rgba, ref_rgba, c.reference_max);
    const double scale = c.reference_max > 0.0 ? c.reference_max : 1.0;
    // Compensated double sums: ~10^5-10^6 pixels whose squares span many orders of magnitude.
    core::RelativeL2 l2;
    std::size_t over = 0;
    double max_d = 0.0;
    for (std::size_t p = 0; p < n; ++p) {
        const double yt = luminance(test_rgba, p), yr = luminance(ref_rgba, p), d = std::abs(yt - yr);
        l2.add(yt, yr);
        max_d = std::max(max_d, d);
        if (std::max(yt, yr) > 0.01 * scale) {
            ++c.lit_pixels;
            if (d > threshold * scale) ++over;
        }
    }
    c.relative_l2 = l2.value();
    c.max_difference = max_d / scale;
    c.fraction_over = c.lit_pixels ? double(over) / double(c.lit_pixels) : 0.0;
    return c;
}

DisplayDifference compare_display(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b,
                                  int threshold_levels) {
    if (a.size() != b.size() || a.size() % 4 != 0)
        throw core::Error("compare_display", "images of different sizes or not RGBA (" + std::to_string(a.size()) +
                                                 " and " + std::to_string(b.size()) + " bytes)");
    DisplayDifference d;
    std::size_t over = 0;
    double sum = 0.0;
    for (std::size_t p = 0; p < a.size(); p += 4) {
        int mx = 0;
        for (std::size_t c = 0; c < 3; ++c) {
            const int v = std::abs(int(a[p + c]) - int(b[p + c]));
            sum += v;
            mx = std::max(mx, v);
        }
        over += mx > threshold_levels;
    }
    const std::size_t px = a.size() / 4;
    d.mean_levels = px ? sum / double(3 * px) : 0.0;
    d.fraction_over = px ? double(over) / double(px) : 0.0;
    return d;
}

std::vector<std::uint8_t> difference_image(std::span<const float> test_rgba, std::span<const float> ref_rgba,
                                           double full_scale) {
    FULGUR_ASSERT(full_scale > 0.0, "full_scale must be positive");
    double ref_max = 0.0;
    const std::size_t n = check_pair(test_rgba, ref_rgba, ref_max);
    const double k = 255.0 / (full_scale * (ref_max > 0.0 ? ref_max : 1.0));
    std::vector<std::uint8_t> out(4 * n);
    for (std::size_t p = 0; p < n; ++p) {
        const double d = std::abs(luminance(test_rgba, p) - luminance(ref_rgba, p));
        const auto v = std::uint8_t(std::clamp(std::lround(d * k), 0L, 255L));
        out[4 * p] = out[4 * p + 1] = out[4 * p + 2] = v;
        out[4 * p + 3] = 255;
    }
    return out;
}

}  // namespace fulgur::app
