#include "golden.h"

#include "core/core.h"

#include <stb_image.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <vector>

namespace fulgur::test {

bool update_goldens_requested() {
    const char* e = std::getenv("FULGUR_UPDATE_GOLDENS");
    return e && std::strcmp(e, "1") == 0;
}

std::vector<std::uint8_t> read_png_rgba(const std::filesystem::path& path, int& width, int& height) {
    int channels = 0;
    unsigned char* data = stbi_load(path.string().c_str(), &width, &height, &channels, 4);
    if (!data) throw core::Error(path.string(), std::string("cannot read PNG: ") + stbi_failure_reason());
    std::vector<std::uint8_t> out(data, data + std::size_t(width) * std::size_t(height) * 4);
    stbi_image_free(data);
    return out;
}

GoldenResult compare_golden(const std::filesystem::path& expected, int width, int height,
                            std::span<const std::uint8_t> rgba, const GoldenTolerance& tol,
                            const std::filesystem::path& output_dir) {
    FULGUR_ASSERT(rgba.size() == std::size_t(width) * std::size_t(height) * 4, "compare_golden: size mismatch");
    GoldenResult r;
    const std::string name = expected.stem().string();
    if (update_goldens_requested()) {
        std::filesystem::create_directories(expected.parent_path());
        core::write_png(expected, width, height, 4, rgba);
        r.passed = true;
        r.regenerated = true;
        r.message = "regenerated " + expected.string();
        return r;
    }
    auto write_actual = [&] {
        std::filesystem::create_directories(output_dir);
        core::write_png(output_dir / (name + ".actual.png"), width, height, 4, rgba);
    };
    if (!std::filesystem::exists(expected)) {
        write_actual();
        r.message = "golden " + expected.string() +
                    " is missing (run with FULGUR_UPDATE_GOLDENS=1 to create it); actual: " +
                    (output_dir / (name + ".actual.png")).string();
        return r;
    }
    int ew = 0, eh = 0;
    const std::vector<std::uint8_t> exp = read_png_rgba(expected, ew, eh);
    if (ew != width || eh != height) {
        write_actual();
        r.message = "golden " + expected.string() + " is " + std::to_string(ew) + "x" + std::to_string(eh) +
                    ", the image " + std::to_string(width) + "x" + std::to_string(height);
        return r;
    }
    const std::size_t pixels = std::size_t(width) * std::size_t(height);
    std::vector<std::uint8_t> diff(pixels * 3);
    std::size_t failing = 0;
    double sum = 0.0;
    for (std::size_t p = 0; p < pixels; ++p) {
        int d = 0;
        for (int c = 0; c < 3; ++c) {
            const int v = std::abs(int(rgba[p * 4 + std::size_t(c)]) - int(exp[p * 4 + std::size_t(c)]));
            d = std::max(d, v);
            sum += v;
        }
        r.max_diff = std::max(r.max_diff, d);
        if (d > tol.pixel_threshold) ++failing;
        core::pseudo_colour(std::min(1.0, d * 8.0 / 255.0), &diff[p * 3]);
        if (d == 0) diff[p * 3] = diff[p * 3 + 1] = diff[p * 3 + 2] = 0;
    }
    r.failing_fraction = double(failing) / double(pixels);
    r.mean_diff = sum / double(pixels * 3);
    r.passed = r.failing_fraction <= tol.max_failing_fraction && r.mean_diff <= tol.max_mean_diff &&
               r.max_diff <= tol.max_diff;
    std::ostringstream msg;
    msg << name << ": max_diff " << r.max_diff << ", failing " << r.failing_fraction * 100.0 << "% (> "
        << tol.pixel_threshold << " levels), mean " << r.mean_diff;
    if (!r.passed) {
        write_actual();
        core::write_png(output_dir / (name + ".expected.png"), width, height, 4, exp);
        core::write_png(output_dir / (name + ".diff.png"), width, height, 3, diff);
        msg << " -- FAILED; see " << (output_dir / (name + ".{actual,expected,diff}.png")).string();
    }
    r.message = msg.str();
    return r;
}

}  // namespace fulgur::test
