#include "scene/scene.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cmath>
#include <filesystem>
#include <numbers>
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

std::string minimal_with(const std::string& from, const std::string& to) {
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
    const Scene s = parse_scene(minimal_with("\"g\": 0.5", "\"g\": 0"), "iso.json");
    CHECK(s.effective_directions() == 1);
}

TEST_CASE("bad scenes are rejected with the file, the field and the allowed range") {
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"albedo\": 0.9", "\"albedo\": 1.5"), "s.json"),
                         doctest::Contains("s.json: /medium/albedo"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"albedo\": 0.9", "\"albedo\": 1.5"), "s.json"),
                         doctest::Contains("[0, 1]"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"g\": 0.5", "\"g\": 1"), "s.json"), doctest::Contains("/medium/g"),
                         Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"albedo\": 0.9", "\"albedo\": \"high\""), "s.json"),
                         doctest::Contains("expected a number"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"g\": 0.5", "\"g\": 0.5, \"colour\": 1"), "s.json"),
                         doctest::Contains("/medium/colour: unknown key"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"grid\": [32, 32, 24]", "\"grid\": [32, 0, 24]"), "s.json"),
                         doctest::Contains("/cloud/generator/grid"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"grid\": [32, 32, 24]", "\"grid\": [32, 32]"), "s.json"),
                         doctest::Contains("3 integers"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"fulgur_scene\": 1", "\"fulgur_scene\": 2"), "s.json"),
                         doctest::Contains("version"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("{\"fulgur_scene\": 1,", "s.json"), doctest::Contains("invalid JSON"), Error);
    CHECK_THROWS_WITH_AS(parse_scene("[]", "s.json"), doctest::Contains("expected a JSON object"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"seed\": 3", "\"seed\": -3"), "s.json"), doctest::Contains("seed"),
                         Error);
}

TEST_CASE("every cloud generator field is read, range-checked and cross-checked") {
    const Scene s =
        parse_scene(minimal_with("\"seed\": 3", R"("seed": 3, "cells": 12, "shear": -300, "flanking_towers": 1,
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
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"seed\": 3", "\"seed\": 3, \"edge_softness\": 0"), "s.json"),
                         doctest::Contains("s.json: /cloud/generator/edge_softness"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"seed\": 3", "\"seed\": 3, \"p_act\": 0"), "s.json"),
                         doctest::Contains("(0, 1]"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"seed\": 3", "\"seed\": 3, \"flanking_towers\": 12"), "s.json"),
                         doctest::Contains("/cloud/generator/flanking_towers"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"anvil_radius\": 4500", "\"anvil_radius\": 1e9"), "s.json"),
                         doctest::Contains("/cloud/generator/anvil_radius"), Error);
    // Inconsistent fields are caught at load time too, with the file and the field.
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"anvil_radius\": 4500", "\"anvil_radius\": 1500"), "s.json"),
                         doctest::Contains("s.json: /cloud/generator/anvil_radius: must be larger than tower_radius"),
                         Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"base_height\": 1000", "\"base_height\": 9500"), "s.json"),
                         doctest::Contains("s.json: /cloud/generator/top_height"), Error);
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"voxel_size\": 500", "\"voxel_size\": 100"), "s.json"),
                         doctest::Contains("s.json: /cloud/generator/top_height: 9000 m does not fit in the grid"),
                         Error);
}

TEST_CASE("cloud needs exactly one of generator or file") {
    const std::string both = minimal_with("\"cloud\": {", "\"cloud\": {\"file\": \"x.nrrd\", ");
    CHECK_THROWS_WITH_AS(parse_scene(both, "s.json"), doctest::Contains("exactly one"), Error);
}

TEST_CASE("lights are points and at most one sun, and the sun effect needs a sun") {
    const std::string lights = minimal_with("\"cloud\"", R"("lights": [
        {"type": "point", "position": [0, 0, 1000], "intensity": 2},
        {"type": "sun", "direction": [0, 0, -2]}], "cloud")");
    const Scene s = parse_scene(lights, "l.json");
    REQUIRE(s.point_lights.size() == 1);
    CHECK(s.point_lights[0].intensity == 2.0);
    REQUIRE(s.sun.has_value());
    CHECK(s.sun->direction.z == doctest::Approx(-1.0));
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"cloud\"", "\"effects\": {\"sun\": true}, \"cloud\""), "s.json"),
                         doctest::Contains("sun"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(minimal_with("\"cloud\"", "\"lights\": [{\"type\": \"laser\"}], \"cloud\""), "s.json"),
        doctest::Contains("/lights/0/type"), Error);
}

TEST_CASE("a sun (or moon): direction or elevation and azimuth, irradiance, colour of luminance 1") {
    const Scene d = parse_scene(minimal_with("\"cloud\"", R"("lights": [{"type": "sun", "elevation": 30, "azimuth": 90,
        "irradiance": 2.5e-3, "colour": [0.5, 0.6, 1.0], "name": "moon"}], "cloud")"),
                                "m.json");
    REQUIRE(d.sun.has_value());
    // Light from the sun at 30 degrees above the horizon toward +y travels down and toward -y.
    CHECK(std::fabs(d.sun->direction.x) < 1e-12);  // cos(90 deg) rounding only
    CHECK(d.sun->direction.y == fulgur::test::rel(-std::cos(std::numbers::pi / 6), 1e-12));
    CHECK(d.sun->direction.z == fulgur::test::rel(-0.5, 1e-12));
    CHECK(d.sun->irradiance == 2.5e-3);
    CHECK(d.sun->name == "moon");
    CHECK(luminance(d.sun->colour) == fulgur::test::rel(1.0, 1e-12));           // normalized on load
    CHECK(d.sun->colour.z / d.sun->colour.x == fulgur::test::rel(2.0, 1e-12));  // the tint is kept
    CHECK(d.effects.sun);  // a declared sun is called for unless effects says otherwise
    CHECK_FALSE(d.effects.sky);
    double el = 0.0, az = 0.0;
    sun_angles(d.sun->direction, el, az);
    CHECK(el == fulgur::test::rel(30.0, 1e-12));  // the round trip, rounding only
    CHECK(az == fulgur::test::rel(90.0, 1e-12));

    const Scene off = parse_scene(
        minimal_with("\"cloud\"",
                     R"("lights": [{"type": "sun", "direction": [1, 0, -1]}], "effects": {"sun": false}, "cloud")"),
        "o.json");
    CHECK(off.sun.has_value());
    CHECK_FALSE(off.effects.sun);
    CHECK(off.sun->colour == glm::dvec3(1.0));

    auto bad = [](const std::string& lights, const char* needle) {
        CHECK_THROWS_WITH_AS(
            parse_scene(minimal_with("\"cloud\"", "\"lights\": [" + lights + "], \"cloud\""), "b.json"),
            doctest::Contains(needle), Error);
    };
    bad(R"({"type": "sun"})", "b.json: /lights/0/direction: give either");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "elevation": 10, "azimuth": 0})", "/lights/0/direction");
    // A propagation direction along or above the horizon: the sun would stand at or below it.
    bad(R"({"type": "sun", "direction": [1, 0, 0]})", "/lights/0/direction: points along or above the horizon");
    bad(R"({"type": "sun", "direction": [0, 1, 0.2]})", "/lights/0/direction: points along or above the horizon");
    bad(R"({"type": "sun", "elevation": 10})", "/lights/0/azimuth: required");
    bad(R"({"type": "sun", "elevation": 0, "azimuth": 0})", "/lights/0/elevation: value 0 is outside");
    bad(R"({"type": "sun", "elevation": 95, "azimuth": 0})", "(0, 90]");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "colour": [0, 0, 0]})", "/lights/0/colour: must have a positive");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "colour": [1, -1, 1]})", "/lights/0/colour");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "irradiance": 0})", "/lights/0/irradiance");
    // Past what the renderer's float32 radiance carries (the sun's disc is ~2e5 x its irradiance).
    bad(R"({"type": "sun", "direction": [0, 0, -1], "irradiance": 1e31})", "/lights/0/irradiance: value 1e+31");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "irradiance": 1e308})", "/lights/0/irradiance");
    bad(R"({"type": "point", "position": [0, 0, 0], "intensity": 1e31})", "/lights/0/intensity");
    bad(R"({"type": "sun", "direction": [0, 0, -1]}, {"type": "sun", "direction": [0, 0, -1]})",
        "/lights/1/type: a scene has at most one sun");
    bad(R"({"type": "sun", "direction": [0, 0, -1], "size": 0.5})", "/lights/0/size: unknown key");
}

TEST_CASE("the sky: uniform or a zenith-horizon gradient, the lightning's colour, effects defaults") {
    const Scene u =
        parse_scene(minimal_with("\"cloud\"", R"("sky": {"radiance": 0.5, "colour": [1, 1, 1]}, "cloud")"), "u.json");
    REQUIRE(u.sky.has_value());
    CHECK(u.sky->zenith() == u.sky->horizon());
    CHECK(u.sky->zenith_radiance == 0.5);
    CHECK(u.effects.sky);
    CHECK_FALSE(u.effects.sun);
    const Scene g =
        parse_scene(minimal_with("\"cloud\"", R"("sky": {"zenith": {"radiance": 40, "colour": [0.3, 0.5, 1]},
        "horizon": {"radiance": 90, "colour": [1, 1, 1]}, "stars": 0}, "effects": {"sky": false},
        "lightning": {"colour": [1, 1, 2]}, "cloud")"),
                    "g.json");
    REQUIRE(g.sky.has_value());
    CHECK(g.sky->zenith_radiance == 40.0);
    CHECK(g.sky->horizon_radiance == 90.0);
    CHECK(luminance(g.sky->zenith_colour) == fulgur::test::rel(1.0, 1e-12));  // normalized on load
    CHECK(g.sky->star_radiance == 0.0);
    CHECK_FALSE(g.effects.sky);
    CHECK(luminance(g.lightning_colour) == fulgur::test::rel(1.0, 1e-12));
    CHECK(g.lightning_colour.z == fulgur::test::rel(2.0 * g.lightning_colour.x, 1e-12));
    // The default flash is bluish white.
    const Scene d = parse_scene(kMinimal, "d.json");
    CHECK(d.lightning_colour.z > d.lightning_colour.x);
    CHECK(luminance(d.lightning_colour) == fulgur::test::rel(1.0, 1e-4));  // 4 decimals in the constant
    CHECK_FALSE(d.sky.has_value());
    CHECK(SkyDome::zenith_weight(1.0) == 1.0);
    CHECK(SkyDome::zenith_weight(0.0) == 0.0);

    auto bad = [](const std::string& section, const char* needle) {
        CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"cloud\"", section + ", \"cloud\""), "b.json"),
                             doctest::Contains(needle), Error);
    };
    bad(R"("sky": {})", "b.json: /sky/radiance: give either");
    bad(R"("sky": {"radiance": 1, "zenith": {"radiance": 1}})", "/sky/radiance: give either");
    bad(R"("sky": {"radiance": -1, "colour": [1, 1, 1]})", "/sky/radiance: value -1");
    bad(R"("sky": {"zenith": {"radiance": 1}})", "/sky/horizon: required object is missing");
    bad(R"("sky": {"zenith": {"radiance": 1, "hue": 3}, "horizon": {"radiance": 1}})", "/sky/zenith/hue: unknown key");
    bad(R"("sky": {"zenith": {"radiance": 1}, "horizon": {"radiance": 1, "colour": [0, 0, 0]}})",
        "/sky/horizon/colour");
    bad(R"("effects": {"sky": true})", "b.json: /effects/sky: true needs");
    bad(R"("effects": {"sun": true})", "b.json: /effects/sun: true needs");
    bad(R"("lightning": {"colour": [1, 1]})", "/lightning/colour");
    bad(R"("transport": {"refine": 3}, "lighting": {"downsample": 4})", "/transport/refine: must divide");
}

TEST_CASE("the default storm scene loads") {
    const Scene s = load_scene(fulgur::test::source_dir() / "content/scenes/storm.json");
    CHECK(s.effects.lightning);
    CHECK(s.medium.extinction > 0.0);
    CHECK(s.virtual_lights.h_usr == 1500.0);  // docs/bake.md: chosen for bake time and file size
    CHECK(s.lighting_downsample == 6);
    CHECK(s.separate_components);
    CHECK(s.transport.ss_tolerance == 1e-2);
    // docs/presets.md: strikes lit by their own Monte Carlo solve (4% from the truth); the
    // bake, only the fallback there, keeps the lattice on the lighting grid (a bake of under
    // a minute: the finer lattice changes the basis frames' error by 2 points, the splat's
    // error dominates them).
    CHECK(s.transport.refine == 1);
    CHECK(s.quality.preset == fulgur::scene::Quality::Preset::PerStrikeMc);
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
    const Scene s =
        parse_scene(minimal_with("\"cloud\"", R"("virtual_lights": {"h_usr": 500, "epsilon": 2e-7, "margin": 100,
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
        minimal_with("\"cloud\"", R"("compression": {"threshold": "relative_l2", "xi": 0.001}, "cloud")"), "r.json");
    CHECK(r.compression.mode == fulgur::basis::ThresholdMode::RelativeL2);
    CHECK(r.compression.precision == fulgur::basis::Precision::Float16);
    CHECK(r.compression.decomposition == fulgur::basis::Decomposition::NonStandard);
    const Scene st =
        parse_scene(minimal_with("\"cloud\"", R"("compression": {"decomposition": "standard"}, "cloud")"), "d.json");
    CHECK(st.compression.decomposition == fulgur::basis::Decomposition::Standard);
    CHECK(r.compression.entropy == fulgur::basis::Entropy::Deflate);
    const Scene plain =
        parse_scene(minimal_with("\"cloud\"", R"("compression": {"entropy": "none"}, "cloud")"), "e.json");
    CHECK(plain.compression.entropy == fulgur::basis::Entropy::None);

    auto bad = [](const std::string& section, const char* needle) {
        CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"cloud\"", section + ", \"cloud\""), "b.json"),
                             doctest::Contains(needle), Error);
    };
    bad(R"("virtual_lights": {"h_usr": 0})", "b.json: /virtual_lights/h_usr");
    bad(R"("virtual_lights": {"h_usr": -5})", "(0, 1000000]");
    bad(R"("virtual_lights": {"epsilon": -1e-9})", "/virtual_lights/epsilon");
    bad(R"("virtual_lights": {"margin": "wide"})", "expected a number");
    bad(R"("virtual_lights": {"density_threshold": 1})", "/virtual_lights/density_threshold");
    bad(R"("virtual_lights": {"spacing": 3})", "/virtual_lights/spacing: unknown key");
    bad(R"("compression": {"threshold": "energy", "xi": 1.5})", "/compression/xi");
    bad(R"("compression": {"threshold": "absolute"})", "/compression/xi: required with threshold \"absolute\"");
    bad(R"("compression": {"threshold": "lossy", "xi": 1})", "/compression/threshold");
    bad(R"("compression": {"xi": 0.99, "precision": "float8"})", "/compression/precision");
    bad(R"("compression": {"threshold": "relative_l2", "xi": -0.1})", "/compression/xi");
    bad(R"("compression": {"decomposition": "wavelet"})", "/compression/decomposition");
    bad(R"("compression": {"entropy": "zstd"})", "/compression/entropy");
}

TEST_CASE("transport.lattice_boltzmann.thick_voxels: default, both values, unknown value names the field") {
    CHECK(parse_scene(kMinimal, "min.json").transport.lb_thick_voxels == "diffusion_matched");
    const Scene m = parse_scene(
        minimal_with("\"cloud\"",
                     R"("transport": {"lattice_boltzmann": {"thick_voxels": "diffusion_matched"}}, "cloud")"),
        "t.json");
    CHECK(m.transport.lb_thick_voxels == "diffusion_matched");
    const Scene s = parse_scene(
        minimal_with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"thick_voxels": "saturate"}}, "cloud")"),
        "t.json");
    CHECK(s.transport.lb_thick_voxels == "saturate");
    CHECK_THROWS_WITH_AS(
        parse_scene(
            minimal_with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"thick_voxels": "subgrid"}}, "cloud")"),
            "t.json"),
        doctest::Contains("/transport/lattice_boltzmann/thick_voxels"), Error);
}

TEST_CASE("quality: a preset's name or an object of knobs; bad values name the field") {
    auto scene = [](const std::string& quality) {
        return parse_scene(minimal_with("\"cloud\"", "\"quality\": " + quality + ", \"cloud\""), "q.json");
    };
    CHECK(parse_scene(kMinimal, "min.json").quality.preset == Quality::Preset::Paper);
    const Quality h = scene(R"("hybrid")").quality;
    CHECK(h.preset == Quality::Preset::Hybrid);
    CHECK(h.multiple == "none");
    const Quality p = scene(R"("per_strike")").quality;
    CHECK(p.multiple == "lattice");
    CHECK(p.refine == 2);  // docs/presets.md: 47% -> 12% from the truth on the default storm
    CHECK(p.exact_orders == 2);
    const Quality mc = scene(R"("per_strike_mc")").quality;
    CHECK(mc.preset == Quality::Preset::PerStrikeMc);
    CHECK(mc.multiple == "monte_carlo");
    CHECK(mc.multiple_paths >= 1000);
    CHECK(to_string(mc.preset) == "per_strike_mc");
    const Quality r = scene(R"("reference")").quality;
    CHECK(r.multiple == "monte_carlo");
    CHECK(r.multiple_paths >= 1000);
    const Quality k = scene(R"({"preset": "per_strike", "single_paths": 50000, "lookahead": 2.5, "refine": 2,
                                "exact_orders": 2})")
                          .quality;
    CHECK(k.preset == Quality::Preset::PerStrike);
    CHECK(k.single_paths == 50'000);
    CHECK(k.lookahead == 2.5);
    CHECK(k.refine == 2);
    CHECK(k.exact_orders == 2);
    CHECK(to_string(k.preset) == "per_strike");
    CHECK_THROWS_WITH_AS(scene(R"("best")"), doctest::Contains("quality"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "per_strike", "refine": 3})"), doctest::Contains("refine"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "per_strike", "exact_orders": 3})"), doctest::Contains("exact_orders"),
                         Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "paper", "multiple": "lattice"})"), doctest::Contains("multiple"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "hybrid", "multiple": "monte_carlo", "multiple_paths": 10})"),
                         doctest::Contains("multiple_paths"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "hybrid", "speed": 1})"), doctest::Contains("speed"), Error);
    const Quality i = scene(R"("instant")").quality;
    CHECK(i.preset == Quality::Preset::Instant);
    CHECK(i.multiple == "monte_carlo");
    CHECK(to_string(i.preset) == "instant");
    const Quality ik = scene(R"({"preset": "instant", "target_noise": 0.05, "max_change_per_frame": 0.5})").quality;
    CHECK(ik.target_noise == 0.05);
    CHECK(ik.max_change_per_frame == 0.5);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "multiple": "lattice"})"), doctest::Contains("multiple"),
                         Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "target_noise": 0})"), doctest::Contains("target_noise"),
                         Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "max_change_per_frame": -1})"),
                         doctest::Contains("max_change_per_frame"), Error);
    // The near-field correction: on for instant (32 rays), off elsewhere, 0 turns it off.
    CHECK(i.near_field_rays == 32);
    CHECK(scene(R"("paper")").quality.near_field_rays == 0);
    CHECK(scene(R"({"preset": "instant", "near_field_rays": 0})").quality.near_field_rays == 0);
    CHECK(scene(R"({"preset": "instant", "near_field_rays": 128})").quality.near_field_rays == 128);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "near_field_rays": 5000})"),
                         doctest::Contains("near_field_rays"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "near_field_rays": -1})"), doctest::Contains("near_field_rays"),
                         Error);
    // Its multiple part: the strike's diffusion solve for instant, the kernel elsewhere.
    CHECK(i.near_field_multiple == "diffusion");
    CHECK(scene(R"("paper")").quality.near_field_multiple == "kernel");
    CHECK(scene(R"({"preset": "instant", "near_field_multiple": "kernel"})").quality.near_field_multiple == "kernel");
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "near_field_multiple": "lattice"})"),
                         doctest::Contains("near_field_multiple"), Error);
    CHECK(i.near_field_fine_rays == 128);
    CHECK(scene(R"("paper")").quality.near_field_fine_rays == 0);
    CHECK(scene(R"({"preset": "instant", "near_field_fine_rays": 0})").quality.near_field_fine_rays == 0);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "near_field_fine_rays": 4097})"),
                         doctest::Contains("near_field_fine_rays"), Error);
    CHECK_THROWS_WITH_AS(scene(R"({"preset": "instant", "near_field_fine_rays": 1.5})"),
                         doctest::Contains("near_field_fine_rays"), Error);
}

TEST_CASE("transport.refine and lattice_boltzmann.exact_orders: values and ranges naming the field") {
    const Scene d = parse_scene(kMinimal, "min.json");
    CHECK(d.transport.refine == 1);
    CHECK(d.transport.lb_exact_orders == 1);
    const Scene s =
        parse_scene(minimal_with("\"cloud\"", R"("transport": {"refine": 2, "lattice_boltzmann": {"exact_orders": 2,
        "order2_paths": 20000}}, "cloud")"),
                    "t.json");
    CHECK(s.transport.refine == 2);
    CHECK(s.transport.lb_exact_orders == 2);
    CHECK(s.transport.lb_order2_paths == 20'000);
    // The transport grid refines the lighting grid (downsample 4): 3 does not divide it.
    CHECK_THROWS_WITH_AS(parse_scene(minimal_with("\"cloud\"", R"("transport": {"refine": 3}, "cloud")"), "t.json"),
                         doctest::Contains("transport/refine"), Error);
    CHECK_THROWS_WITH_AS(
        parse_scene(minimal_with("\"cloud\"", R"("transport": {"lattice_boltzmann": {"exact_orders": 3}}, "cloud")"),
                    "t.json"),
        doctest::Contains("exact_orders"), Error);
}

TEST_CASE("lightning section: defaults, every field, and ranges naming the field") {
    const Scene d = parse_scene(kMinimal, "min.json");
    CHECK(d.lightning.bolt.kind == fulgur::lightning::Kind::CloudToGround);
    CHECK(d.lightning.bolt.angle_mean_deg == 16.0);
    CHECK(d.lightning.schedule.strike_rate == 0.2);

    const std::string full = minimal_with("\"cloud\"", R"("lightning": {
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
        CHECK_THROWS_WITH_AS(
            parse_scene(minimal_with("\"cloud\"", "\"lightning\": " + section + ", \"cloud\""), "s.json"),
            doctest::Contains(field), Error);
    };
    bad(R"({"kind": "ball"})", "s.json: /lightning/kind");
    bad(R"({"angle_mean": -3})", "s.json: /lightning/angle_mean");
    bad(R"({"angle_mean": 400})", "/lightning/angle_mean");
    bad(R"({"segment_length_mean": 0})", "/lightning/segment_length_mean");
    bad(R"({"target_bias": 1.2})", "/lightning/target_bias");
    bad(R"({"zigzag": 5})", "/lightning/zigzag");
    bad(R"({"intensity": -1})", "/lightning/intensity");
    bad(R"({"start_density_threshold": 1})", "/lightning/start_density_threshold");
    bad(R"({"max_segments": 0})", "/lightning/max_segments");
    bad(R"({"branches": {"probability": 2}})", "/lightning/branches/probability");
    bad(R"({"branches": {"max_depth": 50}})", "/lightning/branches/max_depth");
    bad(R"({"branches": {"length_fraction": 0}})", "/lightning/branches/length_fraction");
    bad(R"({"timing": {"decay_time": 0}})", "/lightning/timing/decay_time");
    bad(R"({"timing": {"leader_speed": 1e12}})", "/lightning/timing/leader_speed");
    bad(R"({"timing": {"restrikes": 1e9}})", "/lightning/timing/restrikes");
    bad(R"({"timing": {"restrikes_max": 2.5}})", "/lightning/timing/restrikes_max");
    bad(R"({"strike_rate": -1})", "/lightning/strike_rate");
    bad(R"({"first_strike": "soon"})", "/lightning/first_strike");
    bad(R"({"thunder": true})", "/lightning/thunder: unknown key");
    bad(R"({"timing": {"boom": 1}})", "/lightning/timing/boom: unknown key");
}

TEST_CASE("camera: an orbit or a look-at camera; bad values name the field") {
    CHECK_FALSE(parse_scene(kMinimal, "s.json").camera.has_value());  // the default view
    const std::string fields = "\"medium\":";
    auto camera = [&](const std::string& c) {
        return parse_scene(minimal_with(fields, "\"camera\": " + c + ",\n  " + fields), "s.json").camera;
    };
    const auto orbit = camera(R"({"orbit": {"azimuth": -60, "elevation": 12}})");
    REQUIRE(orbit.has_value());
    CHECK(orbit->kind == CameraSpec::Kind::Orbit);
    CHECK(orbit->azimuth_deg == -60.0);
    CHECK(orbit->elevation_deg == 12.0);
    CHECK_FALSE(orbit->orbit_target.has_value());  // the cloud's centre, resolved by the view
    CHECK_FALSE(orbit->distance.has_value());
    CHECK(orbit->vertical_fov_deg == 50.0);
    const auto full = camera(R"({"orbit": {"target": [1, 2, 3], "distance": 9000, "azimuth": 5, "elevation": -4},
                                 "vertical_fov": 35})");
    CHECK(full->orbit_target.value() == glm::dvec3(1, 2, 3));
    CHECK(full->distance.value() == 9000.0);
    CHECK(full->vertical_fov_deg == 35.0);
    const auto look = camera(R"({"position": [0, -9000, 300], "target": [0, 0, 4000]})");
    CHECK(look->kind == CameraSpec::Kind::LookAt);
    CHECK(look->position == glm::dvec3(0, -9000, 300));
    CHECK(look->target == glm::dvec3(0, 0, 4000));
    CHECK(look->up == glm::dvec3(0, 0, 1));

    auto rejects = [&](const std::string& c, const char* reason) {
        CAPTURE(c);
        CHECK_THROWS_WITH_AS(camera(c), doctest::Contains(reason), Error);
    };
    rejects(R"({"orbit": {"azimuth": 0, "elevation": 90}})", "s.json: /camera/orbit/elevation");
    rejects(R"({"orbit": {"azimuth": 0}})", "/camera/orbit/elevation: required");
    rejects(R"({"orbit": {"azimuth": 0, "elevation": 0, "distance": 0}})", "/camera/orbit/distance");
    rejects(R"({"orbit": {"azimuth": 0, "elevation": 0}, "target": [0, 0, 0]})", "/camera/target: does not go");
    rejects(R"({"orbit": {"azimuth": 0, "elevation": 0}, "vertical_fov": 180})", "/camera/vertical_fov");
    rejects(R"({"orbit": {"azimuth": 0, "elevation": 0, "radius": 5}})", "/camera/orbit/radius: unknown key");
    rejects(R"({"position": [0, 0, 0]})", "/camera/target: required");
    rejects(R"({"position": [0, 0, 0], "target": [0, 0, 0]})", "/camera/target: is the camera's position");
    rejects(R"({"position": [0, 0, 0], "target": [0, 0, 10]})", "/camera/up: is parallel");
    rejects(R"({"position": [0, 0, 0], "target": [0, 10, 0], "up": [0, 0, 0]})", "/camera/up: is the zero vector");
    rejects(R"({"position": [0, 0, 1e300], "target": [0, 10, 0]})", "/camera/position");
    rejects(R"({"position": [0, 0, 0], "target": [0, 10, 0], "zoom": 2})", "/camera/zoom: unknown key");
}

TEST_CASE("camera: camera_json reads back exactly; a command line gives JSON text or a file") {
    fulgur::core::Rng rng(11);
    for (int i = 0; i < 200; ++i) {
        CameraSpec c;
        c.vertical_fov_deg = 1.0 + 169.0 * rng.uniform();
        if (i % 2) {
            c.kind = CameraSpec::Kind::LookAt;
            c.position = {rng.uniform() * 2e4 - 1e4, rng.uniform() * 2e4 - 1e4, rng.uniform() * 1e4};
            c.target = c.position + glm::dvec3(1.0 + rng.uniform(), rng.uniform(), rng.uniform());
            c.up = {rng.uniform() * 0.1, rng.uniform() * 0.1, 1.0};
        } else {
            c.azimuth_deg = rng.uniform() * 720.0 - 360.0;
            c.elevation_deg = rng.uniform() * 178.0 - 89.0;
            if (i % 4 == 0) c.orbit_target = glm::dvec3(rng.uniform(), -rng.uniform() * 1e3, 1e3 * rng.uniform());
            if (i % 8 == 0) c.distance = 1.0 + 1e5 * rng.uniform();
        }
        const std::string j = camera_json(c);
        CAPTURE(j);
        CHECK(parse_camera(j, "--camera") == c);
        CHECK(camera_argument("  " + j, "--camera") == c);
    }
    CameraSpec c;
    c.azimuth_deg = -87.30000000000001;
    CHECK(camera_json(c, 8).find("-87.3,") != std::string::npos);  // the demo's rounding

    const std::filesystem::path file = fulgur::test::scratch_dir("scene_camera") / "camera.json";
    fulgur::core::write_file(file, R"({"orbit": {"azimuth": 30, "elevation": 10}, "vertical_fov": 40})");
    CHECK(camera_argument(file.string(), "--camera").vertical_fov_deg == 40.0);
    fulgur::core::write_file(file, R"({"orbit": {"azimuth": 30}})");
    const std::string named = "--camera " + file.string() + ": /orbit/elevation";
    CHECK_THROWS_WITH_AS(camera_argument(file.string(), "--camera"), doctest::Contains(named.c_str()), Error);
    CHECK_THROWS_WITH_AS(camera_argument((file.parent_path() / "none.json").string(), "--camera"),
                         doctest::Contains("--camera"), Error);
    CHECK_THROWS_WITH_AS(camera_argument("", "--camera"), doctest::Contains("needs a camera"), Error);
    CHECK_THROWS_WITH_AS(parse_camera("[1, 2]", "--camera"), doctest::Contains("expected a JSON object"), Error);
}
