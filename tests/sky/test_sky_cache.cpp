// The light file: round trip, stale keys named, corrupt and truncated files rejected with the
// file and byte offset (never a crash or an out-of-bounds read: also run under the sanitizers).
#include "sky/sky.h"

#include "support/test_support.h"

#include <doctest/doctest.h>

#include <sys/stat.h>

#include <fstream>
#include <iterator>

using namespace fulgur;

namespace {

std::vector<sky::NamedField> two_fields() {
    const core::GridGeometry g{{3, 2, 2}, 50.0, {1.0, -2.0, 0.5}};
    transport::SourceField a(g, transport::output_directions(6)), b(g, transport::output_directions(6));
    for (std::size_t i = 0; i < a.data.size(); ++i) {
        a.data[i] = float(i) * 0.25f;
        b.data[i] = 0.1f * float(i) - 0.5f;  // a lattice's field may dip below zero near a source
    }
    return {{"single", a}, {"zenith.multiple", b}};
}

void spit(const std::filesystem::path& p, const std::string& s) {
    std::ofstream o(p, std::ios::binary | std::ios::trunc);
    o.write(s.data(), std::streamsize(s.size()));
}

}  // namespace

TEST_CASE("light file: round trip, and a stale key names the first differing parameter") {
    const auto dir = test::scratch_dir("sky_cache");
    const auto path = dir / "x.sun.fgl";
    const basis::BakeKey key = basis::BakeKey::from_description("a=1\nsky.sun.direction=0,0,-1\n");
    const auto fields = two_fields();
    sky::write_light_file(path, key, fields);
    CHECK_FALSE(std::filesystem::exists(dir / "x.sun.fgl.tmp"));  // written atomically
    const std::vector<sky::NamedField> back = sky::read_light_file(path, &key);
    REQUIRE(back.size() == 2);
    for (std::size_t f = 0; f < 2; ++f) {
        CHECK(back[f].name == fields[f].name);
        CHECK(back[f].field.geom == fields[f].field.geom);
        CHECK(back[f].field.directions == fields[f].field.directions);
        CHECK(back[f].field.data == fields[f].field.data);  // bit for bit
    }
    const basis::BakeKey moved = basis::BakeKey::from_description("a=1\nsky.sun.direction=0.5,0,-1\n");
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &moved),
                         doctest::Contains("first difference at line 2: the file has \"sky.sun.direction=0,0,-1\""),
                         core::Error);
}

TEST_CASE("light file: every truncation and single-byte corruption is rejected with the file and a byte offset") {
    const auto dir = test::scratch_dir("sky_cache_bad");
    const auto good = dir / "good.fgl";
    const basis::BakeKey key = basis::BakeKey::from_description("k=v\n");
    sky::write_light_file(good, key, two_fields());
    const std::string bytes = fulgur::test::read_text(good);
    const auto bad = dir / "bad.fgl";
    for (std::size_t n = 0; n < bytes.size(); ++n) {
        spit(bad, bytes.substr(0, n));
        CHECK_THROWS_WITH_AS(sky::read_light_file(bad), doctest::Contains("bad.fgl"), core::Error);
    }
    for (std::size_t at = 0; at < bytes.size(); at += 3) {
        std::string c = bytes;
        c[at] = char(c[at] ^ 0x5a);
        spit(bad, c);
        CHECK_THROWS_WITH_AS(sky::read_light_file(bad), doctest::Contains("(byte "), core::Error);
    }
    CHECK_THROWS_WITH_AS(sky::read_light_file(dir / "missing.fgl"), doctest::Contains("cannot open"), core::Error);
}

TEST_CASE("light file: one for another grid or directions, or with values no solve writes, is refused") {
    const auto dir = test::scratch_dir("sky_cache_foreign");
    const auto path = dir / "x.sun.fgl";
    const basis::BakeKey key = basis::BakeKey::from_description("k=v\n");
    const auto fields = two_fields();
    sky::write_light_file(path, key, fields);
    const sky::LightFileShape shape{fields[0].field.geom, fields[0].field.directions, {"single", "zenith.multiple"}};
    CHECK(sky::read_light_file(path, &key, &shape).size() == 2);
    // A valid file with a valid checksum, solved on another grid: it once reached the
    // composition and aborted on an assertion; now it is refused and solved again.
    sky::LightFileShape other = shape;
    other.grid.dims.x = 4;
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key, &other),
                         doctest::Contains("x.sun.fgl: solved on a 3 x 2 x 2 grid of 50 m voxels, not this scene's"),
                         core::Error);
    other = shape;
    other.grid.voxel_size = 100.0;
    CHECK_THROWS_AS(sky::read_light_file(path, &key, &other), core::Error);
    other = shape;
    other.directions = transport::output_directions(18);
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key, &other), doctest::Contains("6 output directions, not"),
                         core::Error);
    other = shape;
    other.names = {"single"};
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key, &other),
                         doctest::Contains("\"zenith.multiple\" is not one this light has"), core::Error);
    // Values with a correct checksum that no solve writes: 3e38, -1e30, -0.01 everywhere.
    for (const float v : {3e38f, -1e30f, -0.01f}) {
        CAPTURE(v);
        std::vector<sky::NamedField> bad = two_fields();
        std::fill(bad[0].field.data.begin(), bad[0].field.data.end(), v);
        sky::write_light_file(path, key, bad);
        CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key, &shape), doctest::Contains("field \"single\": value 0"),
                             core::Error);
    }
    // Fields over no output directions (a checksummed file of empty fields; found by fuzz_fgl).
    std::vector<sky::NamedField> empty = two_fields();
    for (sky::NamedField& f : empty) {
        f.field.directions.clear();
        f.field.data.clear();
    }
    sky::write_light_file(path, key, empty);
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key), doctest::Contains("2 fields over no output directions"),
                         core::Error);
    // The file is sized against the shape before it is read: more bytes than the grid needs
    // are refused before any is read.
    sky::write_light_file(path, key, fields);
    spit(path, fulgur::test::read_text(path) + std::string(std::size_t(1) << 21, '\0'));
    CHECK_THROWS_WITH_AS(sky::read_light_file(path, &key, &shape), doctest::Contains("light file is"), core::Error);
}

TEST_CASE("light file: a FIFO, a device or a directory in its place is refused without reading") {
    const auto dir = test::scratch_dir("sky_cache_kinds");
    const auto fifo = dir / "fifo.fgl";
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);  // reading it would block forever
    CHECK_THROWS_WITH_AS(sky::read_light_file(fifo), doctest::Contains("expected a regular light file"), core::Error);
    CHECK_THROWS_WITH_AS(sky::read_light_file("/dev/zero"), doctest::Contains("expected a regular"), core::Error);
    std::filesystem::create_directories(dir / "d.fgl");
    CHECK_THROWS_AS(sky::read_light_file(dir / "d.fgl"), core::Error);
}
