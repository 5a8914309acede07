// app::write_exr / read_exr: the linear frames fulgur-shot --exr writes, read back exactly, and
// files that are not such frames refused with the file named.
#include "common/exr_image.h"
#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <limits>

using namespace fulgur;

namespace {
// A 5x3 frame: R, G, B spanning the radiances a frame holds (1e-9 sky to 1e7 channel core:
// float32, not half, whose largest value is 65504) and a one-channel layer.
std::vector<app::ExrLayer> sample_layers() {
    app::ExrLayer rgb{"", {"R", "G", "B"}, {}};
    app::ExrLayer t{"T", {"Y"}, {}};
    for (int p = 0; p < 15; ++p) {
        for (int c = 0; c < 3; ++c) rgb.values.push_back(float(std::pow(10.0, -9.0 + p + 0.1 * c)));
        t.values.push_back(float(p) / 14.0f);
    }
    return {rgb, t};
}
}  // namespace

TEST_CASE("write_exr / read_exr: float32 channels, layers and header round-trip exactly") {
    const std::filesystem::path f = test::scratch_dir("exr_image") / "frame.exr";
    const std::vector<app::ExrLayer> layers = sample_layers();
    app::ExrHeader h;
    h.text = {{"fulgurUnits", "W m^-2 sr^-1"}};
    h.numbers = {{"cameraVerticalFovDeg", 50.0}};
    h.vectors = {{"cameraPosition", {1.0, -30000.0, 3000.0}}};
    h.world_to_camera = glm::dmat4(1.0);
    app::write_exr(f, 5, 3, layers, h);
    const app::ExrImage img = app::read_exr(f);
    CHECK(img.width == 5);
    CHECK(img.height == 3);
    REQUIRE(img.channels.size() == 4);
    for (int p = 0; p < 15; ++p) {
        for (int c = 0; c < 3; ++c)
            CHECK(img.channels.at(std::string(1, "RGB"[c]))[std::size_t(p)] ==
                  layers[0].values[std::size_t(3 * p + c)]);
        CHECK(img.channels.at("T.Y")[std::size_t(p)] == layers[1].values[std::size_t(p)]);
    }
    CHECK(img.text.at("fulgurUnits") == "W m^-2 sr^-1");
    CHECK(img.numbers.at("cameraVerticalFovDeg") == 50.0);
    CHECK(img.vectors.at("cameraPosition") == glm::dvec3(1.0, -30000.0, 3000.0));
}

TEST_CASE("write_exr refuses a non-finite value, naming the file and the layer") {
    std::vector<app::ExrLayer> layers = sample_layers();
    layers[1].values[4] = std::numeric_limits<float>::quiet_NaN();
    const std::filesystem::path f = test::scratch_dir("exr_image") / "nan.exr";
    CHECK_THROWS_WITH_AS(app::write_exr(f, 5, 3, layers, {}), doctest::Contains("nan.exr"), core::Error);
    CHECK_FALSE(std::filesystem::exists(f));
}

TEST_CASE("read_exr refuses what is not a bounded float frame, naming the file") {
    const std::filesystem::path dir = test::scratch_dir("exr_image");
    const std::filesystem::path good = dir / "good.exr";
    app::write_exr(good, 5, 3, sample_layers(), {});
    std::string bytes;
    {
        std::ifstream in(good, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    // Truncated in the pixels, in the header, and not an EXR at all.
    for (const std::size_t keep : {bytes.size() - 20, std::size_t(40), std::size_t(0)}) {
        const std::filesystem::path bad = dir / ("cut_" + std::to_string(keep) + ".exr");
        std::ofstream(bad, std::ios::binary).write(bytes.data(), std::streamsize(keep));
        CHECK_THROWS_WITH_AS(app::read_exr(bad), doctest::Contains(bad.string().c_str()), core::Error);
    }
    // More pixels than the caller allows: refused before any is read.
    CHECK_THROWS_WITH_AS(app::read_exr(good, 14), doctest::Contains("larger than 14"), core::Error);
    CHECK_THROWS_AS(app::read_exr(dir / "missing.exr"), core::Error);
}
