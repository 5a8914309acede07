// Hostile scene files: each input class is refused with the file and the field (or byte) named,
// in bounded time and memory, or handled as documented (docs/scene-format.md).
#include "scene/scene.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <sys/stat.h>

#include <string>
#include <utility>
#include <vector>

using fulgur::core::Error;
using namespace fulgur::scene;

namespace {
const std::string kScene = R"({
  "fulgur_scene": 1,
  "name": "hostile",
  "medium": {"extinction": 0.01, "albedo": 0.9, "g": 0.5},
  "cloud": {"generator": {"seed": 3, "grid": [32, 32, 24], "voxel_size": 500, "base_height": 1000,
                          "tower_radius": 2000, "anvil_radius": 4500, "anvil_offset": 500}},
  "lights": [{"type": "point", "position": [0, 0, 1000], "intensity": 1}]
})";

std::string hostile_with(const std::string& from, const std::string& to) {
    return fulgur::test::replace_once(kScene, from, to);
}
}  // namespace

TEST_CASE("deeply nested JSON is refused at a fixed depth, naming the field, without recursing") {
    // 100,000 levels once overflowed the stack in the error description (value dump).
    const std::string deep = std::string(100000, '[') + std::string(100000, ']');
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"hostile\"", deep), "d.json"),
                         doctest::Contains("d.json: /name/0/0"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"hostile\"", deep), "d.json"),
                         doctest::Contains("nesting deeper than 32"), Error);
    const std::string objects = [] {
        std::string s;
        for (int i = 0; i < 100000; ++i) s += "{\"a\":";
        return s + "1" + std::string(100000, '}');
    }();
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"hostile\"", objects), "d.json"), doctest::Contains("/name/a/a/a"),
                         Error);
    // A container that is merely the wrong type is described by its size, not dumped.
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"hostile\"", "[[1, 2], [3]]"), "d.json"),
                         doctest::Contains("an array of 2 element(s)"), Error);
}

TEST_CASE("a key given twice in one object is refused, naming the field") {
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"albedo\": 0.9", "\"albedo\": 0.9, \"albedo\": 0.5"), "k.json"),
                         doctest::Contains("k.json: /medium/albedo: duplicate key"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"type\": \"point\"", "\"type\": \"point\", \"type\": \"sun\""), "k.json"),
        doctest::Contains("k.json: /lights/0/type: duplicate key"), Error);
    // The same key in two different objects is fine.
    CHECK_NOTHROW(parse_scene(hostile_with("\"name\": \"hostile\"", "\"name\": \"seed\""), "k.json"));
}

TEST_CASE("a number beyond the range of a double is refused, naming the field") {
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"albedo\": 0.9", "\"albedo\": 1e400"), "n.json"),
                         doctest::Contains("n.json: /medium/albedo: number out of range"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"position\": [0, 0, 1000]", "\"position\": [0, -1e400, 1000]"), "n.json"),
        doctest::Contains("n.json: /lights/0/position/1: number out of range"), Error);
    // Never nlohmann's raw text.
    try {
        parse_scene(hostile_with("\"albedo\": 0.9", "\"albedo\": 1e400"), "n.json");
        FAIL("1e400 was accepted");
    } catch (const Error& e) {
        CHECK(std::string(e.what()).find("json.exception") == std::string::npos);
    }
}

TEST_CASE("byte-order marks: UTF-8 is skipped, UTF-16 is refused; a NUL in a string is refused") {
    const Scene s = parse_scene("\xEF\xBB\xBF" + kScene, "bom.json");
    CHECK(s.name == "hostile");
    CHECK_THROWS_WITH_AS(parse_scene("\xFF\xFE" + kScene, "u16.json"), doctest::Contains("u16.json (byte 0): UTF-16"),
                         Error);
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"hostile\"", "\"a\\u0000b\""), "z.json"),
                         doctest::Contains("z.json: /name: the string holds a NUL"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"generator\": {", "\"file\": \"x\\u0000.nrrd\", \"nope\": {"), "z.json"),
        doctest::Contains("z.json: /cloud/file: the string holds a NUL"), Error);
    // An escaped NUL in a key: the whole key is named, the NUL shown as its escape (a NUL in
    // the message would cut it where it is printed).
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"name\"", "\"na\\u0000me\": 1, \"name\""), "k.json"),
                         doctest::Contains("k.json: /na\\u0000me: unknown key"), Error);
    // A raw NUL byte is invalid JSON: the byte offset is named.
    std::string raw = kScene;
    raw[raw.find("hostile")] = '\0';
    CHECK_THROWS_WITH_AS(parse_scene(raw, "raw.json"), doctest::Contains("raw.json (byte "), Error);
}

TEST_CASE("a scene is read only from a regular file of bounded size") {
    const auto dir = fulgur::test::scratch_dir("scene_hostile_files");
    const auto fifo = dir / "fifo.json";
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    // A FIFO would block the reader forever; it is refused before it is opened.
    CHECK_THROWS_WITH_AS(load_scene(fifo), doctest::Contains("is a FIFO, expected a regular scene file"), Error);
    CHECK_THROWS_WITH_AS(load_scene(dir), doctest::Contains("is a directory"), Error);
    // /dev/zero never ends: refused before a byte is read (it once grew to 4.7 GB).
    CHECK_THROWS_WITH_AS(load_scene("/dev/zero"), doctest::Contains("is a character device"), Error);
    const auto big = dir / "big.json";
    fulgur::test::write_text(big, kScene + std::string(kMaxSceneBytes, ' '));
    CHECK_THROWS_WITH_AS(load_scene(big), doctest::Contains("the limit is 1048576 bytes"), Error);
    fulgur::test::write_text(dir / "ok.json", kScene);
    CHECK(load_scene(dir / "ok.json").name == "hostile");
}

TEST_CASE("documented values that the solver cannot run are refused at parse time, naming the field") {
    // 6 output directions are not lattice directions: the lattice-Boltzmann solver used to fail
    // deep in the bake with no file or field named.
    const std::string six = hostile_with("\"g\": 0.5}", "\"g\": 0.5}, \"lighting\": {\"directions\": 6}");
    CHECK_THROWS_WITH_AS(parse_scene(six, "six.json"), doctest::Contains("six.json: /lighting/directions"), Error);
    // ... but run with Monte Carlo, without multiple scattering, or when g = 0 needs one direction.
    const std::string mc = hostile_with("\"g\": 0.5}",
                                        "\"g\": 0.5}, \"lighting\": {\"directions\": 6}, "
                                        "\"transport\": {\"solver\": \"monte_carlo\"}");
    CHECK(parse_scene(mc, "mc.json").effective_directions() == 6);
    const std::string ss = hostile_with("\"g\": 0.5}",
                                        "\"g\": 0.5}, \"lighting\": {\"directions\": 6}, "
                                        "\"effects\": {\"multiple_scattering\": false}");
    CHECK(parse_scene(ss, "ss.json").effective_directions() == 6);
    const std::string iso = hostile_with("\"g\": 0.5}", "\"g\": 0}, \"lighting\": {\"directions\": 6}");
    CHECK(parse_scene(iso, "iso.json").effective_directions() == 1);
}

TEST_CASE("the cost of a scene is known before anything is allocated, and refused past its limits") {
    // A 1024^3 generator grid (documented as allowed) once died with std::bad_alloc after 8.4 GB.
    const std::string huge = hostile_with("\"grid\": [32, 32, 24]", "\"grid\": [1024, 1024, 1024]");
    const Scene big =
        parse_scene(hostile_with("\"lights\"", "\"limits\": {\"memory_gib\": 8}, \"lights\""), "big.json");
    CHECK(big.limits.memory_bytes == 8.0 * (1ull << 30));
    Scene s = parse_scene(huge, "huge.json");
    const Cost c = estimate_cost(s, 1, 1);
    // 16 bytes per cell while generating: 2^30 cells need at least 16 GiB.
    CHECK(c.density_bytes >= (std::uint64_t(16) << 30));
    s.limits.memory_bytes = 8.0 * (1ull << 30);
    CHECK_THROWS_WITH_AS(make_density(s), doctest::Contains("limits.memory_gib: the bake would need about"), Error);
    CHECK_THROWS_WITH_AS(make_density(s), doctest::Contains("raise \"limits\""), Error);
    // The limit can be raised: the estimate then passes (nothing is allocated by the check).
    s.limits.memory_bytes = 1e15;
    CHECK_NOTHROW(check_cost(s, c));

    // "paths": 2^40 once hung the plan's sample lights; refused by the lower bound on time.
    const std::string mc = hostile_with("\"lights\"",
                                        "\"transport\": {\"solver\": \"monte_carlo\", \"monte_carlo\": {\"paths\": "
                                        "1099511627776}}, \"lights\"");
    const Scene m = parse_scene(mc, "mc.json");
    CHECK_THROWS_WITH_AS(make_density(m), doctest::Contains("limits.bake_hours: the bake would take at least"), Error);
    // The same scene with a tiny time limit for an ordinary bake.
    Scene small = parse_scene(kScene, "small.json");
    CHECK_NOTHROW(check_cost(small, estimate_cost(small)));
    small.limits.bake_seconds = 1e-9;
    CHECK_THROWS_WITH_AS(check_cost(small, estimate_cost(small)), doctest::Contains("limits.bake_hours"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"lights\"", "\"limits\": {\"bake_hours\": 0}, \"lights\""), "z.json"),
        doctest::Contains("z.json: /limits/bake_hours"), Error);
    // A lighting grid past what a bake file holds (2^26 cells: here 1024 x 1024 x 128 at
    // downsample 2 of a 2048 x 2048 x 256 grid) is refused from the sizes, naming the field,
    // before gigabytes of density are made (a VDB's small density_voxel_size once loaded
    // 3.2 GB first).
    Scene fine = parse_scene(kScene, "fine.json");
    fine.cloud.generator.grid = {2048, 2048, 256};
    fine.lighting_downsample = 2;
    fine.limits.memory_bytes = 1e15;
    fine.limits.bake_seconds = 1e15;
    CHECK_THROWS_WITH_AS(
        check_cost(fine, estimate_cost(fine, 1, 1)),
        doctest::Contains("lighting.downsample: 2: the lighting grid would be 1024 x 1024 x 128 cells"), Error);
    fine.lighting_downsample = 4;  // 2^24 cells: accepted
    CHECK_NOTHROW(check_cost(fine, estimate_cost(fine, 1, 1)));
}

TEST_CASE("a ground at or above the top of the cloud's grid is refused with the file, before any bolt") {
    // The hostile scene's grid is 24 voxels of 500 m: its top is at z = 12000 m.
    const Scene s =
        parse_scene(hostile_with("\"lights\"", "\"lightning\": {\"ground_height\": 50000}, \"lights\""), "g.json");
    CHECK_THROWS_WITH_AS(make_density(s), doctest::Contains("scene: /lightning/ground_height: 50000 m: the ground"),
                         Error);
    CHECK_NOTHROW(make_density(parse_scene(kScene, "ok.json")));
}

TEST_CASE("the sky dome's knobs are bounded: sky_samples in [1, 1024], sky_paths 0 or [1000, 2^27]") {
    const auto sky = [](const std::string& knobs) {
        return parse_scene(hostile_with("\"lights\"", "\"transport\": {\"static_light\": {" + knobs + "}}, \"lights\""),
                           "sky.json");
    };
    const Scene ok = sky("\"sky_samples\": 64, \"sky_paths\": 3000000");
    CHECK(ok.transport.static_sky_samples == 64);
    CHECK(ok.transport.static_sky_paths == 3'000'000);
    CHECK(parse_scene(kScene, "plain.json").transport.static_sky_paths ==
          2'000'000);  // the default: the dome by Monte Carlo
    CHECK_THROWS_WITH_AS(sky("\"sky_samples\": 0"), doctest::Contains("sky.json: /transport/static_light/sky_samples"),
                         Error);
    CHECK_THROWS_WITH_AS(sky("\"sky_samples\": 100000"), doctest::Contains("/transport/static_light/sky_samples"),
                         Error);
    CHECK_THROWS_WITH_AS(sky("\"sky_paths\": 500"), doctest::Contains("/transport/static_light/sky_paths"), Error);
    CHECK_THROWS_WITH_AS(sky("\"sky_paths\": 4294967296"), doctest::Contains("/transport/static_light/sky_paths"),
                         Error);
}

TEST_CASE("every knob that scales a solve's work is in the cost: order-2 paths, a preset's per-strike paths") {
    // order2_paths 2^32 with exact_orders 2 once ran with no output and no end: its paths are
    // part of each light's lower bound (2e-7 s per path: 859 s a light).
    const Scene o = parse_scene(hostile_with("\"lights\"",
                                             "\"transport\": {\"lattice_boltzmann\": {\"exact_orders\": 2, "
                                             "\"order2_paths\": 4294967296}}, \"lights\""),
                                "o2.json");
    const Scene plain = parse_scene(kScene, "plain.json");
    CHECK(estimate_cost(o, 1, 1).seconds_per_light - estimate_cost(plain, 1, 1).seconds_per_light >=
          4294967296.0 * 2e-7 * (1.0 - 1e-12));
    CHECK_THROWS_WITH_AS(check_cost(o, estimate_cost(o, 1000, 2)), doctest::Contains("scene: limits.bake_hours"),
                         Error);
    // A preset's paths at 2^32: each strike's solve would run for hours while a frame waits.
    const Scene q = parse_scene(
        hostile_with("\"lights\"",
                     "\"quality\": {\"preset\": \"per_strike_mc\", \"single_paths\": 4294967296}, \"lights\""),
        "q.json");
    CHECK_THROWS_WITH_AS(check_cost(q, estimate_cost(q)), doctest::Contains("scene: limits.strike_minutes"), Error);
    CHECK_THROWS_WITH_AS(check_cost(q, estimate_cost(q)), doctest::Contains("4294967296 single-scattering paths"),
                         Error);
    // The shipped presets pass, the paper preset costs nothing per strike, and the limit is a key.
    for (const std::string_view p : kQualityPresets) {
        CAPTURE(p);
        const Scene k =
            parse_scene(hostile_with("\"lights\"", "\"quality\": \"" + std::string(p) + "\", \"lights\""), "k.json");
        const Cost c = estimate_cost(k);
        CHECK_NOTHROW(check_cost(k, c));
        CHECK((c.seconds_per_strike == 0.0) == (p == "paper"));
    }
    const Scene tight =
        parse_scene(hostile_with("\"lights\"",
                                 "\"quality\": \"per_strike_mc\", \"limits\": {\"strike_minutes\": 1e-9}, \"lights\""),
                    "t.json");
    CHECK_THROWS_WITH_AS(check_cost(tight, estimate_cost(tight)), doctest::Contains("limits.strike_minutes"), Error);
}

TEST_CASE("a cloud file is sized from its header: a header promising more data than the file holds is refused") {
    const auto dir = fulgur::test::scratch_dir("scene_hostile_cost");
    // A NRRD header claiming 1024^3 voxels over 16 bytes of data: refused by the size check,
    // never allocated (it once asked the allocator for 4 GB).
    fulgur::test::write_text(dir / "liar.nrrd",
                             "NRRD0004\ntype: float\ndimension: 3\nsizes: 1024 1024 1024\nendian: little\n"
                             "encoding: raw\n\n" +
                                 std::string(16, '\0'));
    fulgur::test::write_text(dir / "s.json",
                             R"({"fulgur_scene": 1, "medium": {"extinction": 0.01}, "cloud": {"file": "liar.nrrd"},
        "lights": [{"type": "point", "position": [0, 0, 1000]}]})");
    const Scene s = load_scene(dir / "s.json");
    CHECK_THROWS_WITH_AS(make_density(s), doctest::Contains("liar.nrrd (byte "), Error);
    CHECK_THROWS_WITH_AS(make_density(s), doctest::Contains("data truncated"), Error);
}

TEST_CASE("settings that would make a bake useless are refused at parse time, naming the field") {
    // No light scatters more than the albedo's fraction of its power: drop_below at or above
    // it drops every light.
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"lights\"", "\"virtual_lights\": {\"drop_below\": 1}, \"lights\""), "d.json"),
        doctest::Contains("d.json: /virtual_lights/drop_below"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(hostile_with("\"lights\"", "\"virtual_lights\": {\"drop_below\": 0.95}, \"lights\""), "d.json"),
        doctest::Contains("drops every light"), Error);
    CHECK_NOTHROW(
        parse_scene(hostile_with("\"lights\"", "\"virtual_lights\": {\"drop_below\": 0.5}, \"lights\""), "d.json"));
    // xi keeping no coefficient: energy 0, relative_l2 1 (no |B| exceeds ||B||).
    CHECK_THROWS_WITH_AS(parse_scene(hostile_with("\"lights\"", "\"compression\": {\"xi\": 0}, \"lights\""), "x.json"),
                         doctest::Contains("x.json: /compression/xi"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(
            hostile_with("\"lights\"", "\"compression\": {\"threshold\": \"relative_l2\", \"xi\": 1}, \"lights\""),
            "x.json"),
        doctest::Contains("x.json: /compression/xi"), Error);
}

TEST_CASE("sub-voxel detail is optional; its values are bounded, naming the field") {
    CHECK_FALSE(parse_scene(kScene, "plain.json").cloud.detail.has_value());
    const std::string cloud_end = "\"anvil_offset\": 500}";
    auto detail = [&](const std::string& body) {
        return hostile_with(cloud_end, cloud_end + ", \"detail\": {" + body + "}");
    };
    const Scene s = parse_scene(detail("\"seed\": 9, \"scale\": 250, \"octaves\": 4, \"strength\": 0.7"), "d.json");
    REQUIRE(s.cloud.detail.has_value());
    CHECK(s.cloud.detail->seed == 9);
    CHECK(s.cloud.detail->scale == 250.0);
    CHECK(s.cloud.detail->octaves == 4);
    CHECK(s.cloud.detail->strength == 0.7);
    CHECK(parse_scene(detail(""), "defaults.json").cloud.detail->octaves == 3);
    for (const auto& bad :
         std::vector<std::pair<std::string, std::string>>{{"\"scale\": 0", "/cloud/detail/scale"},
                                                          {"\"scale\": 1e9", "/cloud/detail/scale"},
                                                          {"\"octaves\": 0", "/cloud/detail/octaves"},
                                                          {"\"octaves\": 5", "/cloud/detail/octaves"},
                                                          {"\"octaves\": 2.5", "/cloud/detail/octaves"},
                                                          {"\"strength\": -0.5", "/cloud/detail/strength"},
                                                          {"\"strength\": 2", "/cloud/detail/strength"},
                                                          {"\"strength\": \"high\"", "/cloud/detail/strength"},
                                                          {"\"sclae\": 100", "/cloud/detail/sclae"}}) {
        // (a named reference: clang before 16 refuses a structured binding inside doctest's lambda)
        const std::string& body = bad.first;
        CAPTURE(body);
        const std::string where = "bad.json: " + bad.second;
        CHECK_THROWS_WITH_AS(parse_scene(detail(body), "bad.json"), doctest::Contains(where.c_str()), Error);
    }
}

TEST_CASE("rain is optional; its values are bounded, naming the field") {
    CHECK_FALSE(parse_scene(kScene, "dry.json").rain.has_value());
    auto rain = [&](const std::string& body) {
        return hostile_with("\"lights\":", "\"rain\": {" + body + "}, \"lights\":");
    };
    const Scene s = parse_scene(rain("\"rate\": 30, \"shear\": [300, -100], \"streak_strength\": 0.2"), "r.json");
    REQUIRE(s.rain.has_value());
    CHECK(s.rain->rate == 30.0);
    CHECK(s.rain->shear == glm::dvec2(300.0, -100.0));
    CHECK(s.rain->streak_strength == 0.2);
    CHECK(parse_scene(rain(""), "defaults.json").rain->rate == 20.0);
    for (const auto& bad :
         std::vector<std::pair<std::string, std::string>>{{"\"rate\": 0", "/rain/rate"},
                                                          {"\"rate\": 5000", "/rain/rate"},
                                                          {"\"threshold\": 1", "/rain/threshold"},
                                                          {"\"shear\": [1, 2, 3]", "/rain/shear"},
                                                          {"\"shear\": [9000, 0]", "/rain/shear"},
                                                          {"\"shear\": \"east\"", "/rain/shear"},
                                                          {"\"streak_scale\": 0.5", "/rain/streak_scale"},
                                                          {"\"streak_strength\": -1", "/rain/streak_strength"},
                                                          {"\"g\": 1", "/rain/g"},
                                                          {"\"albedo\": 1.5", "/rain/albedo"},
                                                          {"\"drizzle\": true", "/rain/drizzle"}}) {
        // (a named reference: clang before 16 refuses a structured binding inside doctest's lambda)
        const std::string& body = bad.first;
        CAPTURE(body);
        const std::string where = "bad.json: " + bad.second;
        CHECK_THROWS_WITH_AS(parse_scene(rain(body), "bad.json"), doctest::Contains(where.c_str()), Error);
    }
}

TEST_CASE("quality.directions \"camera\": only where a strike is solved ahead by Monte Carlo alone") {
    const auto quality = [](const std::string& q) {
        return hostile_with("\"lights\"", "\"quality\": " + q + ", \"lights\"");
    };
    // Paper and instant solve no strike ahead; per_strike's lattice solves fixed directions.
    for (const std::string p : {"paper", "instant", "per_strike"}) {
        CAPTURE(p);
        CHECK_THROWS_WITH_AS(parse_scene(quality(R"({"preset": ")" + p + R"(", "directions": "camera"})"), "d.json"),
                             doctest::Contains("d.json: /quality/directions"), Error);
    }
    CHECK_THROWS_WITH_AS(parse_scene(quality(R"({"preset": "per_strike_mc", "directions": "eye"})"), "d.json"),
                         doctest::Contains("d.json: /quality/directions"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(quality(R"({"preset": "per_strike_mc", "multiple": "lattice", "directions": "camera"})"), "d.json"),
        doctest::Contains("the lattice solves fixed directions"), Error);
    for (const std::string p : {"hybrid", "per_strike_mc", "reference"}) {
        CAPTURE(p);
        CHECK(parse_scene(quality(R"({"preset": ")" + p + R"(", "directions": "camera"})"), "d.json")
                  .quality.toward_camera);
    }
    CHECK_FALSE(parse_scene(quality(R"({"preset": "per_strike_mc"})"), "d.json").quality.toward_camera);
}

TEST_CASE("quality.grid \"transport\": refused where nothing is kept or the grid is not finer; bounded by memory") {
    const auto quality = [](const std::string& q) {
        return hostile_with("\"lights\"", "\"quality\": " + q + ", \"lights\"");
    };
    // The paper and instant presets keep no solved strike's light.
    for (const std::string p : {"paper", "instant"}) {
        CAPTURE(p);
        CHECK_THROWS_WITH_AS(parse_scene(quality(R"({"preset": ")" + p + R"(", "grid": "transport"})"), "g.json"),
                             doctest::Contains("g.json: /quality/grid"), Error);
    }
    // transport.refine and quality.refine 1: the per-strike transport grid is the lighting grid.
    CHECK_THROWS_WITH_AS(parse_scene(quality(R"({"preset": "per_strike_mc", "grid": "transport"})"), "g.json"),
                         doctest::Contains("which here is the lighting grid"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(quality(R"({"preset": "per_strike_mc", "grid": "fine", "refine": 4})"), "g.json"),
                         doctest::Contains("g.json: /quality/grid"), Error);
    // Accepted on a finer grid; each strike then costs its light on that grid (5 fields of 26
    // directions: single and multiple of two groups, and the frame's copy) beside the lighting
    // grid's.
    const Scene kept =
        parse_scene(quality(R"({"preset": "per_strike_mc", "grid": "transport", "refine": 4})"), "k.json");
    const Scene plain = parse_scene(quality(R"({"preset": "per_strike_mc", "refine": 4})"), "p.json");
    CHECK(kept.quality.keep_transport_grid);
    CHECK_FALSE(plain.quality.keep_transport_grid);
    const Cost ck = estimate_cost(kept), cp = estimate_cost(plain);
    // The light the cloud scatters onto the ground, two groups of floats on the strike's ground
    // cells: the 8 x 8 lighting voxels of 2 km and 20 km around, in cells of two voxels, 14 x 14.
    const double ground = 2.0 * 4.0 * 14.0 * 14.0;
    CHECK(cp.strike_light_bytes == std::uint64_t(4.0 * 26.0 * 4.0 * 8.0 * 8.0 * 6.0 + ground));  // 32 x 32 x 24 / 4
    Scene no_ground = plain;
    no_ground.effects.ground = false;
    CHECK(estimate_cost(no_ground).strike_light_bytes == std::uint64_t(4.0 * 26.0 * 4.0 * 8.0 * 8.0 * 6.0));
    CHECK(ck.strike_light_bytes - cp.strike_light_bytes == std::uint64_t(5.0 * 26.0 * 4.0 * 32.0 * 32.0 * 24.0));
    // Tallied toward the camera, a strike holds one direction; the frame's copy keeps 26.
    const Scene toward = parse_scene(
        quality(R"({"preset": "per_strike_mc", "grid": "transport", "refine": 4, "directions": "camera"})"), "t.json");
    CHECK(estimate_cost(toward).strike_light_bytes ==
          std::uint64_t(4.0 * 4.0 * 8.0 * 8.0 * 6.0 + (4.0 + 26.0) * 4.0 * 32.0 * 32.0 * 24.0 + ground));
    // Refused before anything is solved when a strike kept that way does not fit, with a limit
    // the bake itself fits in.
    Scene tight = kept;
    tight.limits.memory_bytes = double(ck.memory_bytes) * 1.01;
    CHECK_NOTHROW(check_cost(plain, estimate_cost(plain)));
    CHECK_THROWS_WITH_AS(check_cost(tight, estimate_cost(tight)), doctest::Contains("scene: /quality/grid"), Error);
}
