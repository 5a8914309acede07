// The golden-image comparison utility.
#include "golden.h"

#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

using namespace fulgur;

namespace {
std::vector<std::uint8_t> gradient(int w, int h) {
    std::vector<std::uint8_t> v(std::size_t(w) * std::size_t(h) * 4);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            std::uint8_t* p = &v[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4];
            p[0] = std::uint8_t(x * 255 / (w - 1));
            p[1] = std::uint8_t(y * 255 / (h - 1));
            p[2] = 128;
            p[3] = 255;
        }
    return v;
}
}  // namespace

TEST_CASE("golden comparison: identical passes, perturbed fails and writes images") {
    // These cases must not run in regeneration mode (they rely on the comparison itself).
    if (test::update_goldens_requested()) return;
    const auto dir = test::scratch_dir("golden");
    const int w = 64, h = 32;
    const auto img = gradient(w, h);
    core::write_png(dir / "ref.png", w, h, 4, img);
    const test::GoldenTolerance tol;  // defaults: 8 levels, 0.2% pixels, mean 0.5

    const auto same = test::compare_golden(dir / "ref.png", w, h, img, tol, dir / "out");
    CHECK(same.passed);
    CHECK(same.max_diff == 0);
    CHECK(!std::filesystem::exists(dir / "out" / "ref.diff.png"));

    // A few pixels off by a few levels: within tolerance.
    auto small = img;
    small[0] = std::uint8_t(small[0] + 3);
    const auto s = test::compare_golden(dir / "ref.png", w, h, small, tol, dir / "out");
    CHECK(s.passed);
    CHECK(s.max_diff == 3);

    // A block of 40 pixels off by 40 levels (2% of the image): fails, images written.
    auto big = img;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 10; ++x) big[(std::size_t(y) * w + std::size_t(x)) * 4 + 2] = 168;
    const auto b = test::compare_golden(dir / "ref.png", w, h, big, tol, dir / "out");
    CHECK(!b.passed);
    CHECK(b.max_diff == 40);
    CHECK(b.failing_fraction == doctest::Approx(40.0 / (w * h)));
    CHECK(std::filesystem::exists(dir / "out" / "ref.actual.png"));
    CHECK(std::filesystem::exists(dir / "out" / "ref.expected.png"));
    CHECK(std::filesystem::exists(dir / "out" / "ref.diff.png"));

    // A hard cap on the largest difference catches a single wild pixel.
    test::GoldenTolerance capped = tol;
    capped.max_diff = 2;
    CHECK(!test::compare_golden(dir / "ref.png", w, h, small, capped, dir / "out").passed);

    // Missing golden and wrong size fail.
    CHECK(!test::compare_golden(dir / "missing.png", w, h, img, tol, dir / "out").passed);
    const auto other = gradient(32, 32);
    CHECK(!test::compare_golden(dir / "ref.png", 32, 32, other, tol, dir / "out").passed);
}

TEST_CASE("golden regeneration only with FULGUR_UPDATE_GOLDENS=1, never under CI, never reported as a pass") {
    const auto dir = test::scratch_dir("golden_update");
    const auto img = gradient(16, 16);
    // Saved and restored: the suite may itself run under CI.
    auto saved = [](const char* n) -> std::optional<std::string> {
        const char* v = std::getenv(n);
        return v ? std::optional<std::string>(v) : std::nullopt;
    };
    const auto old_update = saved("FULGUR_UPDATE_GOLDENS"), old_ci = saved("CI");
    ::setenv("FULGUR_UPDATE_GOLDENS", "0", 1);
    ::unsetenv("CI");
    CHECK(!test::update_goldens_requested());
    CHECK(!test::compare_golden(dir / "new.png", 16, 16, img, {}, dir / "out").passed);
    CHECK(!std::filesystem::exists(dir / "new.png"));
    ::setenv("FULGUR_UPDATE_GOLDENS", "1", 1);
    const auto r = test::compare_golden(dir / "new.png", 16, 16, img, {}, dir / "out");
    CHECK_FALSE(r.passed);  // it wrote the reference; it checked nothing
    CHECK(r.regenerated);
    CHECK(std::filesystem::exists(dir / "new.png"));
    // Under CI the switch is refused and nothing is written.
    ::setenv("CI", "true", 1);
    CHECK_THROWS_WITH_AS(test::compare_golden(dir / "ci.png", 16, 16, img, {}, dir / "out"),
                         doctest::Contains("refused under CI"), core::Error);
    CHECK(!std::filesystem::exists(dir / "ci.png"));
    auto restore = [](const char* n, const std::optional<std::string>& v) {
        if (v)
            ::setenv(n, v->c_str(), 1);
        else
            ::unsetenv(n);
    };
    restore("FULGUR_UPDATE_GOLDENS", old_update);
    restore("CI", old_ci);
    int w = 0, h = 0;
    CHECK(test::read_png_rgba(dir / "new.png", w, h) == img);
}
