// Density import/export, base/top measurements and previews.
#include "cloud/cloud.h"
#include "support/grids.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <limits>

using namespace fulgur;
using fulgur::test::scratch_dir;

namespace {
core::Grid3<float> ramp_grid() {
    core::Grid3<float> d = test::uniform_grid({6, 5, 4}, 50.0, {-150.0, -125.0, 0.0});
    for (std::size_t i = 0; i < d.size(); ++i) d.data[i] = float(i) / float(d.size() - 1);  // 0 .. 1 inclusive
    return d;
}
}  // namespace

TEST_CASE("save_density / load_density round trip is bit-exact, with geometry") {
    const auto dir = scratch_dir("density_roundtrip");
    const core::Grid3<float> d = ramp_grid();
    cloud::save_density(dir / "d.nrrd", d);
    const core::Grid3<float> r = cloud::load_density(dir / "d.nrrd");
    CHECK(r.geom.dims == d.geom.dims);
    CHECK(r.geom.voxel_size == d.geom.voxel_size);
    CHECK(r.geom.origin.x == doctest::Approx(d.geom.origin.x));
    CHECK(r.geom.origin.y == doctest::Approx(d.geom.origin.y));
    CHECK(r.geom.origin.z == doctest::Approx(d.geom.origin.z));
    CHECK(r.data == d.data);
}

TEST_CASE("a generated cloud survives the round trip") {
    const auto dir = scratch_dir("density_generated");
    cloud::CumulonimbusParams p;
    p.grid = {32, 32, 24};
    p.voxel_size = 500.0;
    p.base_height = 1000.0;
    p.top_height = 9000.0;
    p.tower_radius = 2000.0;
    p.anvil_radius = 4500.0;
    p.anvil_offset = 500.0;
    const core::Grid3<float> d = cloud::generate_cumulonimbus(p);
    cloud::save_density(dir / "cb.nrrd", d);
    const core::Grid3<float> r = cloud::load_density(dir / "cb.nrrd");
    CHECK(r.data == d.data);
    CHECK(r.geom.dims == d.geom.dims);
}

TEST_CASE("load_density rejects densities outside [0, 1], naming the file and the voxel") {
    const auto dir = scratch_dir("density_bad");
    core::Grid3<float> d = ramp_grid();
    SUBCASE("above 1") {
        d.at(2, 1, 3) = 1.5f;
        core::write_nrrd(dir / "hot.nrrd", d);
        CHECK_THROWS_WITH_AS(cloud::load_density(dir / "hot.nrrd"), doctest::Contains("hot.nrrd: voxel (2,1,3)"),
                             core::Error);
        CHECK_THROWS_WITH_AS(cloud::load_density(dir / "hot.nrrd"), doctest::Contains("outside [0, 1]"), core::Error);
    }
    SUBCASE("negative") {
        d.at(5, 4, 0) = -0.25f;
        core::write_nrrd(dir / "neg.nrrd", d);
        CHECK_THROWS_WITH_AS(cloud::load_density(dir / "neg.nrrd"), doctest::Contains("voxel (5,4,0)"), core::Error);
    }
    SUBCASE("NaN (caught by the NRRD reader with its byte offset)") {
        // write_nrrd refuses NaN: patch the written file's bytes.
        core::write_nrrd(dir / "nan.nrrd", d);
        const std::uint64_t at = core::read_nrrd_header(dir / "nan.nrrd").data_offset + d.geom.index(1, 0, 0) * 4;
        std::fstream f(dir / "nan.nrrd", std::ios::in | std::ios::out | std::ios::binary);
        const float nan = std::numeric_limits<float>::quiet_NaN();
        f.seekp(std::streamoff(at));
        f.write(reinterpret_cast<const char*>(&nan), sizeof nan);
        f.close();
        CHECK_THROWS_WITH_AS(cloud::load_density(dir / "nan.nrrd"), doctest::Contains("non-finite"), core::Error);
    }
    SUBCASE("missing file") {
        CHECK_THROWS_WITH_AS(cloud::load_density(dir / "none.nrrd"), doctest::Contains("none.nrrd"), core::Error);
    }
}

TEST_CASE("save_density refuses what load_density would refuse") {
    const auto dir = scratch_dir("density_save_bad");
    core::Grid3<float> d = ramp_grid();
    d.at(3, 2, 1) = 2.0f;
    CHECK_THROWS_WITH_AS(cloud::save_density(dir / "x.nrrd", d), doctest::Contains("voxel (3,2,1)"), core::Error);
    d.at(3, 2, 1) = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH_AS(cloud::save_density(dir / "x.nrrd", d), doctest::Contains("voxel (3,2,1)"), core::Error);
    CHECK_FALSE(std::filesystem::exists(dir / "x.nrrd"));  // nothing half-written
}

TEST_CASE("cloud base and top heights") {
    core::GridGeometry g;
    g.dims = {4, 4, 10};
    g.voxel_size = 100.0;
    g.origin = {0.0, 0.0, 200.0};
    core::Grid3<float> d(g, 0.0f);
    CHECK(cloud::cloud_base_height(d) == g.upper().z);  // empty: base at the top ...
    CHECK(cloud::cloud_top_height(d) == g.origin.z);    // ... and top at the bottom
    d.at(1, 2, 3) = 0.5f;
    d.at(3, 3, 6) = 0.04f;  // below the default threshold 0.05
    CHECK(cloud::cloud_base_height(d) == 200.0 + 300.0);
    CHECK(cloud::cloud_top_height(d) == 200.0 + 400.0);  // upper face of layer 3
    CHECK(cloud::cloud_top_height(d, 0.01f) == 200.0 + 700.0);
}

TEST_CASE("previews have the documented sizes and show the cloud") {
    const core::Grid3<float> d = test::single_voxel_cloud({12, 8, 6}, 100.0, {6, 4, 2});
    const cloud::Image slice = cloud::render_preview(d, cloud::PreviewKind::SliceXZ, 0.004, 2);
    CHECK(slice.width == 24);
    CHECK(slice.height == 12);
    CHECK(slice.rgb.size() == 24u * 12u * 3u);
    const cloud::Image top = cloud::render_preview(d, cloud::PreviewKind::TopMax);
    CHECK(top.width == 12);
    CHECK(top.height == 8);
    // The voxel (6,4,2) shows in the top view at column 6, row 8-1-4 = 3, brighter than an
    // empty pixel (pseudo-colour: high values are yellow).
    auto lum = [](const cloud::Image& im, int x, int y) {
        const std::size_t o = 3 * (std::size_t(y) * std::size_t(im.width) + std::size_t(x));
        return int(im.rgb[o]) + im.rgb[o + 1] + im.rgb[o + 2];
    };
    CHECK(lum(top, 6, 3) > lum(top, 0, 0) + 200);
    const cloud::Image side = cloud::render_preview(d, cloud::PreviewKind::SideDepth, 0.01);
    CHECK(lum(side, 6, 6 - 1 - 2) > 0);  // tau = 0.01 * 100 = 1: 1 - e^-1 = 0.63
    CHECK(lum(side, 0, 0) == 0);
    const cloud::Image lit = cloud::render_preview(d, cloud::PreviewKind::SideLit, 0.01);
    CHECK(lit.width == 12);
    const auto dir = scratch_dir("previews");
    const cloud::PreviewKind kinds[] = {cloud::PreviewKind::SliceXZ, cloud::PreviewKind::TopMax,
                                        cloud::PreviewKind::SideLit};
    cloud::write_preview_png(dir / "p.png", d, kinds);
    CHECK(std::filesystem::file_size(dir / "p.png") > 0);
}
