#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <fstream>

namespace fulgur::test {

std::filesystem::path source_dir() { return FULGUR_SOURCE_DIR; }

std::filesystem::path scratch_dir(const std::string& name) {
    const std::filesystem::path p = std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / name;
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    return p;
}

double relative_l2(std::span<const float> x, std::span<const float> ref) {
    REQUIRE(x.size() == ref.size());
    double d = 0, n = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        d += (double(x[i]) - double(ref[i])) * (double(x[i]) - double(ref[i]));
        n += double(ref[i]) * double(ref[i]);
    }
    return n > 0 ? std::sqrt(d / n) : std::sqrt(d);
}

void write_text(const std::filesystem::path& path, const std::string& text) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

}  // namespace fulgur::test
