#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cstring>
#include <fstream>
#include <limits>

using namespace fulgur::core;
using fulgur::test::scratch_dir;

namespace {
Grid3<float> sample_grid() {
    GridGeometry g;
    g.dims = {5, 4, 3};
    g.voxel_size = 12.5;
    g.origin = {-100.0, 20.0, 0.0};
    Grid3<float> grid(g);
    for (std::size_t i = 0; i < grid.size(); ++i) grid.data[i] = float(i) * 0.01f;
    return grid;
}

}  // namespace

TEST_CASE("NRRD round trip keeps data and geometry bit-exact") {
    const auto dir = scratch_dir("nrrd_roundtrip");
    const Grid3<float> g = sample_grid();
    write_nrrd(dir / "g.nrrd", g, "test");
    const Grid3<float> r = read_nrrd(dir / "g.nrrd");
    CHECK(r.geom.dims == g.geom.dims);
    CHECK(r.geom.voxel_size == g.geom.voxel_size);
    CHECK(r.geom.origin.x == doctest::Approx(g.geom.origin.x));
    CHECK(r.geom.origin.z == doctest::Approx(g.geom.origin.z));
    CHECK(r.data == g.data);
}

TEST_CASE("NRRD reader rejects bad files with the file and offset in the message") {
    const auto dir = scratch_dir("nrrd_bad");
    const Grid3<float> g = sample_grid();
    write_nrrd(dir / "g.nrrd", g);
    const std::string good = fulgur::test::read_text(dir / "g.nrrd");
    const auto data_start = good.find("\n\n") + 2;

    SUBCASE("missing file") {
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "none.nrrd"), doctest::Contains("none.nrrd"), Error);
    }
    SUBCASE("bad magic") {
        fulgur::test::write_text(dir / "b.nrrd", "P6\n" + good.substr(9));
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "b.nrrd"), doctest::Contains("not a NRRD"), Error);
    }
    SUBCASE("every truncation is rejected") {
        for (std::size_t len = 0; len < good.size(); len += 7) {
            fulgur::test::write_text(dir / "t.nrrd", good.substr(0, len));
            CHECK_THROWS_AS(read_nrrd(dir / "t.nrrd"), Error);
        }
    }
    SUBCASE("trailing bytes") {
        fulgur::test::write_text(dir / "t.nrrd", good + "xx");
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "t.nrrd"), doctest::Contains("trailing"), Error);
    }
    SUBCASE("wrong type") {
        std::string s = good;
        s.replace(s.find("type: float"), 11, "type: int16");
        fulgur::test::write_text(dir / "t.nrrd", s);
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "t.nrrd"), doctest::Contains("type"), Error);
    }
    SUBCASE("huge sizes are refused before allocating") {
        std::string s = good;
        s.replace(s.find("sizes: 5 4 3"), 12, "sizes: 5 4 99999999");
        fulgur::test::write_text(dir / "t.nrrd", s);
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "t.nrrd"), doctest::Contains("sizes"), Error);
    }
    SUBCASE("NaN voxel names its byte offset") {
        std::string s = good;
        const float nan = std::numeric_limits<float>::quiet_NaN();
        std::memcpy(s.data() + data_start + 8, &nan, 4);
        fulgur::test::write_text(dir / "t.nrrd", s);
        CHECK_THROWS_WITH_AS(read_nrrd(dir / "t.nrrd"),
                             doctest::Contains(("byte " + std::to_string(data_start + 8)).c_str()), Error);
    }
}
