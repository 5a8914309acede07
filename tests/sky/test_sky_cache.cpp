// The light file: round trip, stale keys named, corrupt and truncated files rejected with the
// file and byte offset (never a crash or an out-of-bounds read: also run under the sanitizers).
#include "sky/sky.h"

#include "support/test_support.h"

#include <doctest/doctest.h>

#include <fstream>
#include <iterator>

using namespace fulgur;

namespace {

std::vector<sky::NamedField> two_fields() {
    const core::GridGeometry g{{3, 2, 2}, 50.0, {1.0, -2.0, 0.5}};
    transport::SourceField a(g, transport::output_directions(6)), b(g, transport::output_directions(6));
    for (std::size_t i = 0; i < a.data.size(); ++i) {
        a.data[i] = float(i) * 0.25f;
        b.data[i] = -float(i);
    }
    return {{"single", a}, {"zenith.multiple", b}};
}

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
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
    const std::string bytes = slurp(good);
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
