#include "scene/scene.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <string>

using fulgur::core::Error;
using namespace fulgur::scene;

namespace {
const std::string kMinimal = R"({
  "fulgur_scene": 1,
  "medium": {"extinction": 0.01, "albedo": 0.9, "g": 0.5},
  "cloud": {"generator": {"seed": 3, "grid": [32, 32, 16]}}
})";

std::string with(const std::string& from, const std::string& to) {
    std::string s = kMinimal;
    const auto at = s.find(from);
    REQUIRE(at != std::string::npos);
    s.replace(at, from.size(), to);
    return s;
}
}  // namespace

TEST_CASE("a minimal scene parses with documented defaults") {
    const Scene s = parse_scene(kMinimal, "min.json");
    CHECK(s.medium.extinction == 0.01);
    CHECK(s.medium.albedo == 0.9);
    CHECK(s.cloud.kind == CloudSource::Kind::Generator);
    CHECK(s.cloud.generator.seed == 3);
    CHECK(s.cloud.generator.grid == fulgur::core::Int3{32, 32, 16});
    CHECK(s.directions == 26);
    CHECK(s.effective_directions() == 26);
    CHECK(s.transport.solver == TransportSettings::Solver::LatticeBoltzmann);
}

TEST_CASE("isotropic scattering needs one output direction") {
    const Scene s = parse_scene(with("\"g\": 0.5", "\"g\": 0"), "iso.json");
    CHECK(s.effective_directions() == 1);
}

TEST_CASE("bad scenes are rejected with the file, the field and the allowed range") {
    CHECK_THROWS_WITH_AS(parse_scene(with("\"albedo\": 0.9", "\"albedo\": 1.5"), "s.json"),
                         doctest::Contains("s.json: medium.albedo"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"albedo\": 0.9", "\"albedo\": 1.5"), "s.json"),
                         doctest::Contains("[0, 1]"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"g\": 0.5", "\"g\": 1"), "s.json"), doctest::Contains("medium.g"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"albedo\": 0.9", "\"albedo\": \"high\""), "s.json"),
                         doctest::Contains("expected a number"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"g\": 0.5", "\"g\": 0.5, \"colour\": 1"), "s.json"),
                         doctest::Contains("medium.colour: unknown key"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"grid\": [32, 32, 16]", "\"grid\": [32, 0, 16]"), "s.json"),
                         doctest::Contains("cloud.generator.grid"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"grid\": [32, 32, 16]", "\"grid\": [32, 32]"), "s.json"),
                         doctest::Contains("3 integers"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"fulgur_scene\": 1", "\"fulgur_scene\": 2"), "s.json"),
                         doctest::Contains("version"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("{\"fulgur_scene\": 1,", "s.json"), doctest::Contains("invalid JSON"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("[]", "s.json"), doctest::Contains("expected a JSON object"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"seed\": 3", "\"seed\": -3"), "s.json"), doctest::Contains("seed"), Error);
}

TEST_CASE("cloud needs exactly one of generator or file") {
    const std::string both = with("\"cloud\": {", "\"cloud\": {\"file\": \"x.nrrd\", ");
    CHECK_THROWS_WITH_AS(parse_scene(both, "s.json"), doctest::Contains("exactly one"), Error);
}

TEST_CASE("lights are points and at most one sun, and the sun effect needs a sun") {
    const std::string lights = with("\"cloud\"", R"("lights": [
        {"type": "point", "position": [0, 0, 1000], "intensity": 2},
        {"type": "sun", "direction": [0, 0, -2]}], "cloud")");
    const Scene s = parse_scene(lights, "l.json");
    REQUIRE(s.point_lights.size() == 1);
    CHECK(s.point_lights[0].intensity == 2.0);
    REQUIRE(s.sun.has_value());
    CHECK(s.sun->direction.z == doctest::Approx(-1.0));
    CHECK_THROWS_WITH_AS(parse_scene(with("\"cloud\"", "\"effects\": {\"sun\": true}, \"cloud\""), "s.json"),
                         doctest::Contains("sun"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(with("\"cloud\"", "\"lights\": [{\"type\": \"laser\"}], \"cloud\""), "s.json"),
        doctest::Contains("lights[0].type"), Error);
}

TEST_CASE("the default storm scene loads") {
    const Scene s = load_scene(fulgur::test::source_dir() / "content/scenes/storm.json");
    CHECK(s.effects.lightning);
    CHECK(s.medium.extinction > 0.0);
    CHECK(s.virtual_lights.h_usr == 800.0);
    CHECK(s.compression.mode == fulgur::basis::ThresholdMode::Energy);
    CHECK(s.compression.precision == fulgur::basis::Precision::Float16);
}

TEST_CASE("virtual_lights and compression sections: values, defaults and ranges") {
    const Scene d = parse_scene(kMinimal, "min.json");
    CHECK(d.virtual_lights.h_usr == fulgur::basis::VirtualLightParams{}.h_usr);
    CHECK(d.compression == fulgur::basis::CompressionParams{});
    const Scene s = parse_scene(with("\"cloud\"", R"("virtual_lights": {"h_usr": 500, "epsilon": 2e-7, "margin": 100,
        "ground_height": -50, "density_threshold": 0.1},
        "compression": {"threshold": "absolute", "xi": 5e-10, "precision": "float32"}, "cloud")"), "v.json");
    CHECK(s.virtual_lights.h_usr == 500.0);
    CHECK(s.virtual_lights.epsilon == 2e-7);
    CHECK(s.virtual_lights.margin == 100.0);
    CHECK(s.virtual_lights.ground_height == -50.0);
    CHECK(s.virtual_lights.density_threshold == 0.1);
    CHECK(s.compression.mode == fulgur::basis::ThresholdMode::Absolute);
    CHECK(s.compression.xi == 5e-10);
    CHECK(s.compression.precision == fulgur::basis::Precision::Float32);
    const Scene r = parse_scene(with("\"cloud\"", R"("compression": {"threshold": "relative_l2", "xi": 0.001}, "cloud")"), "r.json");
    CHECK(r.compression.mode == fulgur::basis::ThresholdMode::RelativeL2);
    CHECK(r.compression.precision == fulgur::basis::Precision::Float16);
    CHECK(r.compression.decomposition == fulgur::basis::Decomposition::NonStandard);
    const Scene st = parse_scene(with("\"cloud\"", R"("compression": {"decomposition": "standard"}, "cloud")"), "d.json");
    CHECK(st.compression.decomposition == fulgur::basis::Decomposition::Standard);

    auto bad = [](const std::string& section, const char* needle) {
        CHECK_THROWS_WITH_AS(parse_scene(with("\"cloud\"", section + ", \"cloud\""), "b.json"), doctest::Contains(needle), Error);
    };
    bad(R"("virtual_lights": {"h_usr": 0})", "b.json: virtual_lights.h_usr");
    bad(R"("virtual_lights": {"h_usr": -5})", "(0, 1000000]");
    bad(R"("virtual_lights": {"epsilon": -1e-9})", "virtual_lights.epsilon");
    bad(R"("virtual_lights": {"margin": "wide"})", "expected a number");
    bad(R"("virtual_lights": {"density_threshold": 1})", "virtual_lights.density_threshold");
    bad(R"("virtual_lights": {"spacing": 3})", "virtual_lights.spacing: unknown key");
    bad(R"("compression": {"threshold": "energy", "xi": 1.5})", "compression.xi");
    bad(R"("compression": {"threshold": "absolute"})", "compression.xi: required with threshold \"absolute\"");
    bad(R"("compression": {"threshold": "lossy", "xi": 1})", "compression.threshold");
    bad(R"("compression": {"xi": 0.99, "precision": "float8"})", "compression.precision");
    bad(R"("compression": {"threshold": "relative_l2", "xi": -0.1})", "compression.xi");
    bad(R"("compression": {"decomposition": "wavelet"})", "compression.decomposition");
}
