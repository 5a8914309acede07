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
  "cloud": {"generator": {"seed": 3, "grid": [32, 32, 24], "voxel_size": 500, "base_height": 1000,
                          "tower_radius": 2000, "anvil_radius": 4500, "anvil_offset": 500}}
})";

std::string with(const std::string& from, const std::string& to) {
    return fulgur::test::replace_once(kMinimal, from, to);
}
}  // namespace

TEST_CASE("a minimal scene parses with documented defaults") {
    const Scene s = parse_scene(kMinimal, "min.json");
    CHECK(s.medium.extinction == 0.01);
    CHECK(s.medium.albedo == 0.9);
    CHECK(s.cloud.kind == CloudSource::Kind::Generator);
    CHECK(s.cloud.generator.seed == 3);
    CHECK(s.cloud.generator.grid == fulgur::core::Int3{32, 32, 24});
    CHECK(s.cloud.generator.voxel_size == 500.0);
    CHECK(s.cloud.generator.anvil_radius == 4500.0);
    CHECK(s.cloud.generator.top_height == fulgur::cloud::CumulonimbusParams{}.top_height);  // default
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
    CHECK_THROWS_WITH_AS(parse_scene(with("\"albedo\": 0.9", "\"albedo\": 1.5"), "s.json"), doctest::Contains("[0, 1]"),
                         Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"g\": 0.5", "\"g\": 1"), "s.json"), doctest::Contains("medium.g"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"albedo\": 0.9", "\"albedo\": \"high\""), "s.json"),
                         doctest::Contains("expected a number"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"g\": 0.5", "\"g\": 0.5, \"colour\": 1"), "s.json"),
                         doctest::Contains("medium.colour: unknown key"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"grid\": [32, 32, 24]", "\"grid\": [32, 0, 24]"), "s.json"),
                         doctest::Contains("cloud.generator.grid"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"grid\": [32, 32, 24]", "\"grid\": [32, 32]"), "s.json"),
                         doctest::Contains("3 integers"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"fulgur_scene\": 1", "\"fulgur_scene\": 2"), "s.json"),
                         doctest::Contains("version"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("{\"fulgur_scene\": 1,", "s.json"), doctest::Contains("invalid JSON"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("[]", "s.json"), doctest::Contains("expected a JSON object"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"seed\": 3", "\"seed\": -3"), "s.json"), doctest::Contains("seed"), Error);
}

TEST_CASE("every cloud generator field is read, range-checked and cross-checked") {
    const Scene s = parse_scene(with("\"seed\": 3", R"("seed": 3, "cells": 12, "shear": -300, "flanking_towers": 1,
        "anvil": false, "anvil_thickness": 900, "overshoot": 0, "edge_softness": 0.7, "steps": 20,
        "p_ext": 0.3, "p_hum": 0.25, "p_act": 0.05, "average_steps": 5, "smoothing_radius": 2, "density_gain": 1.1)"),
                                "g.json");
    const auto& g = s.cloud.generator;
    CHECK(g.cells == 12);
    CHECK(g.shear == -300.0);
    CHECK(g.flanking_towers == 1);
    CHECK_FALSE(g.anvil);
    CHECK(g.anvil_thickness == 900.0);
    CHECK(g.overshoot == 0.0);
    CHECK(g.edge_softness == 0.7);
    CHECK(g.steps == 20);
    CHECK(g.p_ext == 0.3);
    CHECK(g.p_hum == 0.25);
    CHECK(g.p_act == 0.05);
    CHECK(g.average_steps == 5);
    CHECK(g.smoothing_radius == 2);
    CHECK(g.density_gain == 1.1);
    // Single-field ranges name the field and the range.
    CHECK_THROWS_WITH_AS(parse_scene(with("\"seed\": 3", "\"seed\": 3, \"edge_softness\": 0"), "s.json"),
                         doctest::Contains("s.json: cloud.generator.edge_softness"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"seed\": 3", "\"seed\": 3, \"p_act\": 0"), "s.json"),
                         doctest::Contains("(0, 1]"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"seed\": 3", "\"seed\": 3, \"flanking_towers\": 12"), "s.json"),
                         doctest::Contains("cloud.generator.flanking_towers"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"anvil_radius\": 4500", "\"anvil_radius\": 1e9"), "s.json"),
                         doctest::Contains("cloud.generator.anvil_radius"), Error);
    // Inconsistent fields are caught at load time too, with the file and the field.
    CHECK_THROWS_WITH_AS(parse_scene(with("\"anvil_radius\": 4500", "\"anvil_radius\": 1500"), "s.json"),
                         doctest::Contains("s.json: cloud.generator.anvil_radius: must be larger than tower_radius"),
                         Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"base_height\": 1000", "\"base_height\": 9500"), "s.json"),
                         doctest::Contains("s.json: cloud.generator.top_height"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(with("\"voxel_size\": 500", "\"voxel_size\": 100"), "s.json"),
                         doctest::Contains("s.json: cloud.generator.top_height: 9000 m does not fit in the grid"),
                         Error);
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
    CHECK_THROWS_WITH_AS(parse_scene(with("\"cloud\"", "\"lights\": [{\"type\": \"laser\"}], \"cloud\""), "s.json"),
                         doctest::Contains("lights[0].type"), Error);
}

TEST_CASE("the default storm scene loads") {
    const Scene s = load_scene(fulgur::test::source_dir() / "content/scenes/storm.json");
    CHECK(s.effects.lightning);
    CHECK(s.medium.extinction > 0.0);
    CHECK(s.virtual_lights.h_usr == 1500.0);  // docs/bake.md: chosen for bake time and file size
    CHECK(s.lighting_downsample == 6);
    CHECK(s.separate_components);
    CHECK(s.transport.ss_tolerance == 1e-2);
    CHECK(s.compression.mode == fulgur::basis::ThresholdMode::Energy);
    CHECK(s.compression.precision == fulgur::basis::Precision::Float16);
    CHECK(s.lightning.bolt.kind == fulgur::lightning::Kind::CloudToGround);
    CHECK_NOTHROW(fulgur::lightning::validate(s.lightning));
    CHECK(s.cloud.kind == CloudSource::Kind::Generator);
    CHECK(s.cloud.generator.grid == fulgur::core::Int3{144, 144, 80});
    CHECK(s.cloud.generator.anvil);
}

TEST_CASE("virtual_lights and compression sections: values, defaults and ranges") {
    const Scene d = parse_scene(kMinimal, "min.json");
    CHECK(d.virtual_lights.h_usr == fulgur::basis::VirtualLightParams{}.h_usr);
    CHECK(d.compression == fulgur::basis::CompressionParams{});
    const Scene s = parse_scene(with("\"cloud\"", R"("virtual_lights": {"h_usr": 500, "epsilon": 2e-7, "margin": 100,
        "ground_height": -50, "density_threshold": 0.1},
        "compression": {"threshold": "absolute", "xi": 5e-10, "precision": "float32"}, "cloud")"),
                                "v.json");
    CHECK(s.virtual_lights.h_usr == 500.0);
    CHECK(s.virtual_lights.epsilon == 2e-7);
    CHECK(s.virtual_lights.margin == 100.0);
    CHECK(s.virtual_lights.ground_height == -50.0);
    CHECK(s.virtual_lights.density_threshold == 0.1);
    CHECK(s.compression.mode == fulgur::basis::ThresholdMode::Absolute);
    CHECK(s.compression.xi == 5e-10);
    CHECK(s.compression.precision == fulgur::basis::Precision::Float32);
    const Scene r = parse_scene(
        with("\"cloud\"", R"("compression": {"threshold": "relative_l2", "xi": 0.001}, "cloud")"), "r.json");
    CHECK(r.compression.mode == fulgur::basis::ThresholdMode::RelativeL2);
    CHECK(r.compression.precision == fulgur::basis::Precision::Float16);
    CHECK(r.compression.decomposition == fulgur::basis::Decomposition::NonStandard);
    const Scene st =
        parse_scene(with("\"cloud\"", R"("compression": {"decomposition": "standard"}, "cloud")"), "d.json");
    CHECK(st.compression.decomposition == fulgur::basis::Decomposition::Standard);
    CHECK(r.compression.entropy == fulgur::basis::Entropy::Deflate);
    const Scene plain = parse_scene(with("\"cloud\"", R"("compression": {"entropy": "none"}, "cloud")"), "e.json");
    CHECK(plain.compression.entropy == fulgur::basis::Entropy::None);

    auto bad = [](const std::string& section, const char* needle) {
        CHECK_THROWS_WITH_AS(parse_scene(with("\"cloud\"", section + ", \"cloud\""), "b.json"),
                             doctest::Contains(needle), Error);
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
    bad(R"("compression": {"entropy": "zstd"})", "compression.entropy");
}

TEST_CASE("transport.lattice_boltzmann.thick_voxels: default, both values, unknown value names the field") {
    CHECK(parse_scene(kMinimal, "min.json").transport.lb_thick_voxels == "diffusion_matched");
    const Scene m = parse_scene(
        with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"thick_voxels": "diffusion_matched"}}, "cloud")"),
        "t.json");
    CHECK(m.transport.lb_thick_voxels == "diffusion_matched");
    const Scene s = parse_scene(
        with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"thick_voxels": "saturate"}}, "cloud")"), "t.json");
    CHECK(s.transport.lb_thick_voxels == "saturate");
    CHECK_THROWS_WITH_AS(
        parse_scene(with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"thick_voxels": "subgrid"}}, "cloud")"),
                    "t.json"),
        doctest::Contains("transport.lattice_boltzmann.thick_voxels"), Error);
}

TEST_CASE("lightning section: defaults, every field, and ranges naming the field") {
    const Scene d = parse_scene(kMinimal, "min.json");
    CHECK(d.lightning.bolt.kind == fulgur::lightning::Kind::CloudToGround);
    CHECK(d.lightning.bolt.angle_mean_deg == 16.0);
    CHECK(d.lightning.schedule.strike_rate == 0.2);

    const std::string full = with("\"cloud\"", R"("lightning": {
        "kind": "intra_cloud", "seed": 9, "intensity": 2e5, "start_density_threshold": 0.4,
        "ground_height": 120, "angle_mean": 20, "angle_spread": 6, "segment_length_mean": 150,
        "segment_length_spread": 30, "target_bias": 0.5, "wander": 0.25, "zigzag": 0.5, "max_segments": 5000,
        "branches": {"probability": 0.1, "angle_mean": 40, "length_fraction": 0.5, "intensity_decay": 0.3, "max_depth": 2},
        "timing": {"leader_speed": 3e5, "leader_brightness": 0.05, "rise_time": 2e-4, "decay_time": 0.02,
                   "restrikes": 4, "restrikes_max": 6, "restrike_interval": 0.07, "restrike_brightness": 0.4,
                   "dart_leader_speed": 2e7, "dark_threshold": 0.002},
        "strike_rate": 1.5, "first_strike": 2}, "cloud")");
    const Scene s = parse_scene(full, "l.json");
    const auto& l = s.lightning;
    CHECK(l.bolt.kind == fulgur::lightning::Kind::IntraCloud);
    CHECK(l.seed == 9);
    CHECK(l.bolt.intensity == 2e5);
    CHECK(l.bolt.start_density_threshold == 0.4);
    CHECK(l.bolt.ground_height == 120.0);
    CHECK(l.bolt.angle_mean_deg == 20.0);
    CHECK(l.bolt.angle_spread_deg == 6.0);
    CHECK(l.bolt.segment_length_mean == 150.0);
    CHECK(l.bolt.segment_length_spread == 30.0);
    CHECK(l.bolt.target_bias == 0.5);
    CHECK(l.bolt.wander == 0.25);
    CHECK(l.bolt.zigzag == 0.5);
    CHECK(l.bolt.max_segments == 5000);
    CHECK(l.bolt.branch_probability == 0.1);
    CHECK(l.bolt.branch_angle_mean_deg == 40.0);
    CHECK(l.bolt.branch_length_fraction == 0.5);
    CHECK(l.bolt.branch_intensity_decay == 0.3);
    CHECK(l.bolt.max_depth == 2);
    CHECK(l.timing.leader_speed == 3e5);
    CHECK(l.timing.leader_brightness == 0.05);
    CHECK(l.timing.rise_time == 2e-4);
    CHECK(l.timing.decay_time == 0.02);
    CHECK(l.timing.restrikes == 4.0);
    CHECK(l.timing.restrikes_max == 6);
    CHECK(l.timing.restrike_interval == 0.07);
    CHECK(l.timing.restrike_brightness == 0.4);
    CHECK(l.timing.dart_leader_speed == 2e7);
    CHECK(l.timing.dark_threshold == 0.002);
    CHECK(l.schedule.strike_rate == 1.5);
    CHECK(l.schedule.first_strike == 2.0);

    auto bad = [&](const std::string& section, const char* field) {
        CHECK_THROWS_WITH_AS(parse_scene(with("\"cloud\"", "\"lightning\": " + section + ", \"cloud\""), "s.json"),
                             doctest::Contains(field), Error);
    };
    bad(R"({"kind": "ball"})", "s.json: lightning.kind");
    bad(R"({"angle_mean": -3})", "s.json: lightning.angle_mean");
    bad(R"({"angle_mean": 400})", "lightning.angle_mean");
    bad(R"({"segment_length_mean": 0})", "lightning.segment_length_mean");
    bad(R"({"target_bias": 1.2})", "lightning.target_bias");
    bad(R"({"zigzag": 5})", "lightning.zigzag");
    bad(R"({"intensity": -1})", "lightning.intensity");
    bad(R"({"start_density_threshold": 1})", "lightning.start_density_threshold");
    bad(R"({"max_segments": 0})", "lightning.max_segments");
    bad(R"({"branches": {"probability": 2}})", "lightning.branches.probability");
    bad(R"({"branches": {"max_depth": 50}})", "lightning.branches.max_depth");
    bad(R"({"branches": {"length_fraction": 0}})", "lightning.branches.length_fraction");
    bad(R"({"timing": {"decay_time": 0}})", "lightning.timing.decay_time");
    bad(R"({"timing": {"leader_speed": 1e12}})", "lightning.timing.leader_speed");
    bad(R"({"timing": {"restrikes": 1e9}})", "lightning.timing.restrikes");
    bad(R"({"timing": {"restrikes_max": 2.5}})", "lightning.timing.restrikes_max");
    bad(R"({"strike_rate": -1})", "lightning.strike_rate");
    bad(R"({"first_strike": "soon"})", "lightning.first_strike");
    bad(R"({"thunder": true})", "lightning.thunder: unknown key");
    bad(R"({"timing": {"boom": 1}})", "lightning.timing.boom: unknown key");
}
