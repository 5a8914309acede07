// app::compare_radiance / difference_image: the image-space comparison of a render with its
// direct-solve reference (fulgur-shot --reference).
#include "common/image_compare.h"
#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <vector>

using namespace fulgur;

namespace {
// Grey RGBA pixels of luminance y (r = g = b: luminance = y exactly, the weights sum to 1).
std::vector<float> grey(const std::vector<float>& y) {
    std::vector<float> out;
    for (float v : y) out.insert(out.end(), {v, v, v, 1.0f});
    return out;
}
}  // namespace

TEST_CASE("compare_radiance: identical images differ by nothing") {
    const std::vector<float> a = grey({0.0f, 1.0f, 2.0f, 4.0f});
    const app::RadianceComparison c = app::compare_radiance(a, a);
    CHECK(c.relative_l2 == 0.0);
    CHECK(c.max_difference == 0.0);
    CHECK(c.fraction_over == 0.0);
    CHECK(c.reference_max == test::rel(4.0, 1e-6));  // Rec. 709 weights sum to 1 within float rounding
    CHECK(c.lit_pixels == 3);                        // the black pixel is below 1% of the maximum
}

TEST_CASE("compare_radiance: figures of a known perturbation") {
    const std::vector<float> ref = grey({10.0f, 10.0f, 10.0f, 10.0f, 0.0f});
    // One pixel 20% of the maximum too bright, one 5% too dark, the black one stays black.
    const std::vector<float> test = grey({12.0f, 9.5f, 10.0f, 10.0f, 0.0f});
    const app::RadianceComparison c = app::compare_radiance(test, ref);
    // sqrt(2^2 + 0.5^2) / sqrt(4 * 10^2); the 1e-6 allows the float luminance weights.
    CHECK(c.relative_l2 == test::rel(std::sqrt(4.25) / 20.0, 1e-6));
    CHECK(c.max_difference == test::rel(0.2, 1e-6));
    CHECK(c.lit_pixels == 4);
    CHECK(c.fraction_over == doctest::Approx(0.25));  // only the 20% pixel exceeds 10%
    CHECK(app::compare_radiance(test, ref, 0.01).fraction_over == doctest::Approx(0.5));
}

TEST_CASE("difference_image: 10% of the reference maximum is white, sign ignored") {
    const std::vector<float> ref = grey({10.0f, 10.0f, 10.0f});
    const std::vector<float> test = grey({11.0f, 9.4f, 30.0f});
    const std::vector<std::uint8_t> d = app::difference_image(test, ref);
    REQUIRE(d.size() == 12);
    CHECK(int(d[0]) == 255);  // |1| = 10% of 10
    CHECK(int(d[4]) == 153);  // |-0.6| = 6% of the maximum: 0.6 x 255
    CHECK(int(d[8]) == 255);  // clamped
    CHECK(int(d[3]) == 255);  // opaque
}

TEST_CASE("compare_radiance: bad input is rejected with a reason") {
    const std::vector<float> a = grey({1.0f, 2.0f}), b = grey({1.0f});
    CHECK_THROWS_AS(app::compare_radiance(a, b), core::Error);
    std::vector<float> nan = a;
    nan[0] = std::numeric_limits<float>::quiet_NaN();
    CHECK_THROWS_AS(app::compare_radiance(nan, a), core::Error);
    CHECK_THROWS_AS(app::difference_image(a, nan), core::Error);
    // A black reference: relative figures fall back to absolute ones (no division by 0).
    const std::vector<float> black = grey({0.0f, 0.0f});
    const app::RadianceComparison c = app::compare_radiance(a, black);
    CHECK(std::isfinite(c.relative_l2));
    CHECK(c.max_difference == test::rel(2.0, 1e-6));
}

TEST_CASE("compare_display: mean levels and pixels beyond the threshold") {
    // Two pixels: one identical, one off by (30, 10, 0) levels; alpha is ignored.
    const std::vector<std::uint8_t> a = {10, 20, 30, 255, 100, 100, 100, 255};
    const std::vector<std::uint8_t> b = {10, 20, 30, 0, 130, 90, 100, 0};
    const app::DisplayDifference d = app::compare_display(a, b);
    CHECK(d.mean_levels == doctest::Approx(40.0 / 6.0));
    CHECK(d.fraction_over == doctest::Approx(0.5));              // 30 > 25
    CHECK(app::compare_display(a, b, 30).fraction_over == 0.0);  // not strictly above 30
    CHECK_THROWS_AS(app::compare_display(a, std::vector<std::uint8_t>(4)), core::Error);
}
