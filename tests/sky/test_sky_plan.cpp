// The plan decides from the scene (and says why): no lightning -> no bake, no sun -> no sun
// solve, isotropic -> one direction, nothing that lights the cloud -> an error; the solves
// are cached and done again only when their key changes; the composed colour.
#include "sky/sky.h"

#include "support/test_support.h"

#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include <glm/geometric.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <numbers>
#include <thread>

using namespace fulgur;

namespace {

// The tiny anisotropic test scene with `patch` merged into it (RFC 7396), written to `dir`.
scene::Scene variant(const std::filesystem::path& dir, const std::string& name, const std::string& patch) {
    std::ifstream in(test::source_dir() / "tests/apps/scenes/test_aniso_ms_cg.json");
    nlohmann::json j = nlohmann::json::parse(in);
    j.merge_patch(nlohmann::json::parse(patch));
    const auto path = dir / (name + ".json");
    test::write_text(path, j.dump(1));
    return scene::load_scene(path);
}

bake::PlanOptions quick() {
    bake::PlanOptions o;
    o.estimate = false;
    return o;
}

bool mentions(const sky::ScenePlan& p, const std::string& needle) {
    for (const std::string& r : p.reasons)
        if (r.find(needle) != std::string::npos) return true;
    return false;
}

const char* kSunSky = R"({"lights": [{"type": "sun", "name": "moon", "elevation": 40, "azimuth": 30,
    "irradiance": 0.01, "colour": [0.8, 0.9, 1]}], "sky": {"zenith": {"radiance": 1e-3, "colour": [0.4, 0.5, 1]},
    "horizon": {"radiance": 3e-3, "colour": [1, 1, 1]}}, "effects": {"sun": true, "sky": true}})";

}  // namespace

TEST_CASE("plan: the solves each kind of scene triggers, counted, and the reasons naming them") {
    const auto dir = test::scratch_dir("sky_plan");
    const scene::Scene night = variant(dir, "night", kSunSky);
    const core::Grid3<float> d = scene::make_density(night);
    const sky::ScenePlan all = sky::plan_scene(night, d, quick());
    REQUIRE(all.lightning.has_value());
    CHECK(all.virtual_lights == all.lightning->lights.count());
    CHECK(all.sun_solves == 1);
    CHECK(all.sky_single_solves == 0);   // the dome by its own Monte Carlo (sky_paths), no directions
    CHECK(all.sky_lattice_solves == 2);  // a gradient: one per end
    CHECK(mentions(all, "order 1 and 2 by Monte Carlo from the whole dome (2000000 paths per gradient end"));
    CHECK(all.directions == 26);
    CHECK(mentions(all, "moon (elevation 40 deg, azimuth 30 deg): one solve per direction"));
    CHECK(mentions(all, "zenith-horizon gradient"));
    CHECK(all.to_text().find("bake plan") != std::string::npos);

    const scene::Scene day_sun = variant(
        dir, "day_sun", R"({"effects": {"lightning": false, "sun": true}, "medium": {"g": 0}, "lights": [{"type": "sun",
        "elevation": 50, "azimuth": -60, "irradiance": 800}], "sky": {"radiance": 2, "colour": [0.5, 0.6, 1]}})");
    const sky::ScenePlan p = sky::plan_scene(day_sun, d, quick());
    CHECK_FALSE(p.lightning.has_value());
    CHECK(p.virtual_lights == 0);
    CHECK(p.sun_solves == 1);
    CHECK(p.sky_lattice_solves == 1);  // uniform: the sum only
    CHECK(p.directions == 1);          // isotropic
    CHECK(mentions(p, "no lightning (effects.lightning = false): no virtual-light bake, no .fgb"));
    CHECK(mentions(p, "g = 0 (isotropic scattering): S does not depend on direction, 1 output direction"));
    CHECK(p.to_text().find("bake plan") == std::string::npos);

    const sky::ScenePlan storm = sky::plan_scene(variant(dir, "storm", "{}"), d, quick());
    CHECK(storm.lightning.has_value());
    CHECK(storm.sun_solves == 0);
    CHECK(storm.sky_single_solves == 0);
    CHECK(storm.sky_lattice_solves == 0);
    CHECK(mentions(storm, "no sun in the scene: no sun solve"));
    CHECK(mentions(storm, "no sky in the scene: no sky solve"));

    const sky::ScenePlan off = sky::plan_scene(
        variant(dir, "off",
                std::string(kSunSky).replace(std::string(kSunSky).find("\"sun\": true"), 11, "\"sun\": false")),
        d, quick());
    CHECK(off.sun_solves == 0);
    CHECK(mentions(off, "a sun is declared but effects.sun = false: no sun solve"));

    const sky::ScenePlan single = sky::plan_scene(
        variant(dir, "single",
                R"({"effects": {"multiple_scattering": false, "lightning": false}, "sky": {"radiance": 1}})"),
        d, quick());
    CHECK(single.sky_lattice_solves == 0);
    CHECK(single.sky_single_solves == 0);
    CHECK(mentions(single, "order 1 by Monte Carlo from the whole dome"));

    // The dome as directions: sky_paths 0, sky_samples of them.
    const sky::ScenePlan directions =
        sky::plan_scene(variant(dir, "directions",
                                R"({"effects": {"lightning": false}, "sky": {"radiance": 1},
                    "transport": {"static_light": {"sky_paths": 0, "sky_samples": 16}}})"),
                        d, quick());
    CHECK(directions.sky_single_solves == 16);
    CHECK(mentions(directions, "16 directions' exact single scattering"));

    // Nothing that lights the cloud: a clear error naming the file and the field.
    CHECK_THROWS_WITH_AS(sky::plan_scene(variant(dir, "dark", R"({"effects": {"lightning": false}})"), d, quick()),
                         doctest::Contains("dark.json: /effects: the scene asks for nothing that lights the cloud"),
                         core::Error);
    CHECK_THROWS_WITH_AS(
        sky::plan_scene(
            variant(dir, "none", R"({"effects": {"single_scattering": false, "multiple_scattering": false}})"), d,
            quick()),
        doctest::Contains("/effects: single_scattering and multiple_scattering are both false"), core::Error);
}

TEST_CASE("solved once: the cache is read while fresh, solved again when the sun moves; colour rides on the fields") {
    const auto dir = test::scratch_dir("sky_load");
    const scene::Scene s = variant(dir, "night", kSunSky);
    const core::Grid3<float> d = scene::make_density(s);
    const solve::Media media = sky::static_media(s, d);
    const sky::ScenePlan plan = sky::plan_scene(s, d, quick());
    std::vector<std::string> said;
    auto say = [&](const std::string& m) { said.push_back(m); };
    const sky::CacheOptions cache{true, dir / "cache"};
    const sky::StaticLight a = sky::load_or_solve(s, d, media, plan, cache, say);
    REQUIRE(said.size() == 2);
    CHECK(said[0].find("sun: solved") == 0);
    CHECK(said[1].find("sky: solved") == 0);
    CHECK(std::filesystem::exists(dir / "cache/night.sun.fgl"));
    CHECK(std::filesystem::exists(dir / "cache/night.sky.fgl"));
    said.clear();
    const sky::StaticLight b = sky::load_or_solve(s, d, media, plan, cache, say);
    REQUIRE(said.size() == 2);
    CHECK(said[0].find("sun: read from") == 0);
    CHECK(said[1].find("sky: read from") == 0);
    CHECK(b.sun->multiple.data == a.sun->multiple.data);
    CHECK(b.sky->zenith.single.data == a.sky->zenith.single.data);

    // A brighter, redder moon: no new solve (the solves are per unit light).
    const scene::Scene brighter =
        variant(dir, "night", std::string(kSunSky).replace(std::string(kSunSky).find("0.01"), 4, "0.05"));
    said.clear();
    (void)sky::load_or_solve(brighter, d, media, sky::plan_scene(brighter, d, quick()), cache, say);
    CHECK(said[0].find("sun: read from") == 0);
    // The moon moved: solved again, and the message says which parameter changed.
    const scene::Scene moved =
        variant(dir, "night",
                std::string(kSunSky).replace(std::string(kSunSky).find("\"elevation\": 40"), 15, "\"elevation\": 20"));
    said.clear();
    (void)sky::load_or_solve(moved, d, media, sky::plan_scene(moved, d, quick()), cache, say);
    CHECK(said[0].find("sun: solved") == 0);
    CHECK(said[0].find("sky.sun.direction") != std::string::npos);
    CHECK(said[1].find("sky: read from") == 0);  // the sky did not change

    // Colour: the composed field is irradiance x colour x the unit field (plus the sky's).
    sky::ComposeOptions only_sun;
    only_sun.sky = false;
    const sky::ColourField c = sky::compose(a, s.sun, s.sky, only_sun);
    REQUIRE(c.directions.size() == 26);
    const std::size_t cells = c.geom.cell_count();
    for (std::size_t i = 0; i < cells; i += 7) {
        const double unit = double(a.sun->single.data[i]) + double(a.sun->multiple.data[i]);
        for (int ch = 0; ch < 3; ++ch)
            CHECK(c.rgb[0][3 * i + std::size_t(ch)] ==
                  test::rel(s.sun->irradiance * s.sun->colour[ch] * unit, 1e-5));  // float products
    }
    sky::ComposeOptions full_res = only_sun;
    full_res.sun_single = false;  // the renderer draws the sun's order 1 itself
    const sky::ColourField m = sky::compose(a, s.sun, s.sky, full_res);
    CHECK(m.rgb[0][3] == test::rel(s.sun->irradiance * s.sun->colour[0] * a.sun->multiple.data[1], 1e-5));
    sky::ComposeOptions none;
    none.sun = none.sky = false;
    CHECK(sky::compose(a, s.sun, s.sky, none).empty());
}

TEST_CASE("the static light kept on its transport grid: media, plan, cache key, colour and truth on that grid") {
    const auto dir = test::scratch_dir("sky_keep");
    nlohmann::json patch = nlohmann::json::parse(kSunSky);
    // Few Monte Carlo paths for order 2 and the dome: this checks grids, not values.
    patch["transport"] = {{"static_light", {{"refine", 2}, {"order2_paths", 1000}, {"sky_paths", 1000}}}};
    const scene::Scene averaged = variant(dir, "night", patch.dump());
    patch["transport"]["static_light"]["grid"] = "transport";
    const scene::Scene kept = variant(dir, "night", patch.dump());
    const core::Grid3<float> d = scene::make_density(kept);
    const solve::Media ma = sky::static_media(averaged, d), mk = sky::static_media(kept, d);
    // The same transport grid (2 km lighting voxels refined by 2); kept, it is the lighting grid.
    CHECK(mk.transport.density.geom == ma.transport.density.geom);
    CHECK(mk.lighting.density.geom == mk.transport.density.geom);
    CHECK(mk.refine == 1);
    CHECK(ma.lighting.density.geom.voxel_size == 2.0 * ma.transport.density.geom.voxel_size);
    const sky::ScenePlan pk = sky::plan_scene(kept, d, quick());
    CHECK(pk.settings.refine == 2);
    CHECK(pk.settings.keep_transport_grid);
    CHECK(mentions(pk, "S kept on that grid"));
    CHECK(mentions(sky::plan_scene(averaged, d, quick()), "S averaged onto the lighting grid"));

    // One cache file name for both: the kept grid is in the key, so neither reads the other's.
    std::vector<std::string> said;
    auto say = [&](const std::string& m) { said.push_back(m); };
    const sky::CacheOptions cache{true, dir / "cache"};
    const sky::StaticLight la = sky::load_or_solve(averaged, d, ma, sky::plan_scene(averaged, d, quick()), cache, say);
    said.clear();
    const sky::StaticLight lk = sky::load_or_solve(kept, d, mk, pk, cache, say);
    REQUIRE(said.size() == 2);
    CHECK(said[0].find("sun: solved") == 0);
    CHECK(said[0].find("sky.grid") != std::string::npos);
    CHECK(lk.sun->multiple.geom == mk.lighting.density.geom);
    CHECK(la.sun->multiple.geom == ma.lighting.density.geom);
    said.clear();
    (void)sky::load_or_solve(kept, d, mk, pk, cache, say);  // and it is read back on its grid
    CHECK(said[0].find("sun: read from") == 0);

    const sky::ColourField c = sky::compose(lk, kept.sun, kept.sky, {});
    CHECK(c.geom == mk.lighting.density.geom);
    // The truth tallies where the solves' S is kept (a few paths: only the grid is checked).
    sky::TruthOptions few;
    few.paths = 2000;
    const sky::StaticLight t = sky::truth_of(kept, d, pk, mk, lk, transport::output_directions(26), few);
    CHECK(t.sun->multiple.geom == mk.lighting.density.geom);
    CHECK_THROWS_WITH_AS(variant(dir, "bad", R"({"transport": {"static_light": {"grid": "fine"}}})"),
                         doctest::Contains("/transport/static_light/grid"), core::Error);
    // Bounded before anything is solved: the kept fields over the scene's memory limit (the
    // 16 x 16 x 8 grid's six fields of 26 directions and the renderer's copy: ~2.2 MB; no
    // lightning, whose bake's own estimate would be refused first).
    CHECK(mentions(pk, "S kept on the 16 x 16 x 8 transport grid"));
    patch["limits"] = {{"memory_gib", 0.001}};
    patch["effects"]["lightning"] = false;
    const scene::Scene tight = variant(dir, "tight", patch.dump());
    CHECK_THROWS_WITH_AS(sky::plan_scene(tight, d, quick()),
                         doctest::Contains("/transport/static_light/grid: \"transport\" keeps"), core::Error);
}

TEST_CASE("the static light by Monte Carlo (solver \"monte_carlo\"): the truth of the same paths, cached apart") {
    const auto dir = test::scratch_dir("sky_mc");
    nlohmann::json patch = nlohmann::json::parse(kSunSky);
    patch["transport"] = {{"static_light", {{"order2_paths", 1000}, {"sky_paths", 1000}}}};
    const scene::Scene lattice = variant(dir, "night", patch.dump());
    patch["transport"]["static_light"]["solver"] = "monte_carlo";
    patch["transport"]["static_light"]["paths"] = 3000;
    const scene::Scene mc = variant(dir, "night", patch.dump());
    const core::Grid3<float> d = scene::make_density(mc);
    const solve::Media media = sky::static_media(mc, d);
    REQUIRE_FALSE(media.full.density.data.empty());  // the truth's estimator needs it
    const sky::ScenePlan plan = sky::plan_scene(mc, d, quick());
    CHECK(plan.settings.method == sky::Method::MonteCarlo);
    CHECK(plan.settings.truth_paths == 3000);
    CHECK(mentions(plan, "every order by 3000 Monte Carlo paths from the box's boundary"));
    CHECK(plan.sky_lattice_solves == 0);

    // One cache file name for both: the solver is in the key, so neither reads the other's.
    std::vector<std::string> said;
    auto say = [&](const std::string& m) { said.push_back(m); };
    const sky::CacheOptions cache{true, dir / "cache"};
    (void)sky::load_or_solve(lattice, d, sky::static_media(lattice, d), sky::plan_scene(lattice, d, quick()), cache,
                             say);
    said.clear();
    const sky::StaticLight solved = sky::load_or_solve(mc, d, media, plan, cache, say);
    REQUIRE(said.size() == 2);
    CHECK(said[0].find("sun: solved") == 0);
    CHECK(said[0].find("sky.method") != std::string::npos);
    said.clear();
    const sky::StaticLight read = sky::load_or_solve(mc, d, media, plan, cache, say);
    CHECK(said[0].find("sun: read from") == 0);

    // The static truth with the same paths and seed (transport.mc_seed), bit for bit: the
    // figures measured for the truth with that seed (docs/sky.md, docs/blender.md) are this
    // solve's.
    sky::TruthOptions same;
    same.paths = 3000;
    same.seed = plan.settings.seed;
    const sky::StaticLight truth =
        sky::truth_of(mc, d, plan, media, solved, transport::output_directions(plan.directions), same);
    REQUIRE(solved.sun.has_value());
    REQUIRE(solved.sky.has_value());
    const auto lit = [](const transport::SourceField& f) {
        return std::any_of(f.data.begin(), f.data.end(), [](float v) { return v > 0.0f; });
    };
    CHECK(lit(solved.sun->single));
    CHECK(lit(solved.sun->multiple));
    CHECK(lit(solved.sky->zenith.multiple));
    CHECK(solved.sun->single.data == truth.sun->single.data);
    CHECK(solved.sun->multiple.data == truth.sun->multiple.data);
    CHECK(solved.sky->zenith.multiple.data == truth.sky->zenith.multiple.data);
    CHECK(solved.sky->horizon.single.data == truth.sky->horizon.single.data);
    CHECK(read.sun->multiple.data == solved.sun->multiple.data);
    CHECK_THROWS_WITH_AS(variant(dir, "bad", R"({"transport": {"static_light": {"solver": "exact"}}})"),
                         doctest::Contains("/transport/static_light/solver"), core::Error);
    CHECK_THROWS_WITH_AS(variant(dir, "bad", R"({"transport": {"static_light": {"paths": 100000000}}})"),
                         doctest::Contains("/transport/static_light/paths"), core::Error);
}

TEST_CASE("the static light toward the camera (directions \"camera\"): one field, each voxel's own direction") {
    const auto dir = test::scratch_dir("sky_toward");
    nlohmann::json patch = nlohmann::json::parse(kSunSky);
    patch["transport"] = {{"static_light", {{"solver", "monte_carlo"}, {"paths", 3000}, {"directions", "camera"}}}};
    const scene::Scene s = variant(dir, "still", patch.dump());
    const core::Grid3<float> d = scene::make_density(s);
    const solve::Media media = sky::static_media(s, d);
    const sky::ScenePlan plan = sky::plan_scene(s, d, quick());
    // The scene's orbit (test_aniso_ms_cg.json: target (0, 0, 2640), 17.6 km, azimuth -90,
    // elevation 6), where view::scene_camera stands.
    const glm::dvec3 camera = scene::camera_position(s.camera, d.geom);
    CHECK(camera.y == test::rel(-17600.0 * std::cos(6.0 * std::numbers::pi / 180.0), 1e-12));
    REQUIRE(plan.settings.toward.has_value());
    CHECK(*plan.settings.toward == camera);
    CHECK(plan.directions == 1);
    CHECK(mentions(plan, "directions \"camera\": the sun's, moon's and sky's S toward the camera at"));
    CHECK(mentions(plan, "lightning keeps its 26 output directions"));

    std::vector<std::string> said;
    auto say = [&](const std::string& m) { said.push_back(m); };
    const sky::CacheOptions cache{true, dir / "cache"};
    const sky::StaticLight solved = sky::load_or_solve(s, d, media, plan, cache, say);
    REQUIRE(solved.sun.has_value());
    REQUIRE(solved.sky.has_value());
    CHECK(solved.sun->multiple.directions.size() == 1);
    CHECK(solved.sky->zenith.multiple.directions.size() == 1);
    CHECK(said.at(0).find("sun: solved") == 0);
    // The truth of the same paths and seed is the same field: --against static compares like
    // with like.
    sky::TruthOptions same;
    same.paths = 3000;
    same.seed = plan.settings.seed;
    const sky::StaticLight truth =
        sky::truth_of(s, d, plan, media, solved, transport::output_directions(plan.directions), same);
    CHECK(truth.sun->multiple.data == solved.sun->multiple.data);
    CHECK(truth.sky->horizon.multiple.data == solved.sky->horizon.multiple.data);
    // A lit cell holds the truth along its own direction to the camera (the same paths; float32
    // rounding, as test_monte_carlo's "S toward a point").
    const core::GridGeometry& g = media.lighting.density.geom;
    std::size_t best = 0;
    for (std::size_t c = 0; c < g.cell_count(); ++c)
        if (solved.sun->multiple.data[c] > solved.sun->multiple.data[best]) best = c;
    const core::Int3 b = g.unindex(best);
    const glm::dvec3 own = camera - g.centre(b.x, b.y, b.z);
    const sky::TruthField along = sky::sun_truth(media, solved.sun_direction, std::span(&own, 1), same);
    CHECK(solved.sun->multiple.data[best] == test::rel(along.field.multiple.data[best], 2e-7));
    CHECK(solved.sun->single.data[best] == test::rel(along.field.single.data[best], 2e-7));

    // Read back while the camera stands still; another camera position is another solve.
    said.clear();
    (void)sky::load_or_solve(s, d, media, plan, cache, say);
    CHECK(said.at(0).find("sun: read from") == 0);
    patch["camera"] = {{"orbit", {{"azimuth", -60}}}};
    const scene::Scene moved = variant(dir, "still", patch.dump());
    said.clear();
    const sky::StaticLight again =
        sky::load_or_solve(moved, d, sky::static_media(moved, d), sky::plan_scene(moved, d, quick()), cache, say);
    CHECK(said.at(0).find("sun: solved") == 0);
    CHECK(said.at(0).find("sky.toward") != std::string::npos);
    CHECK(again.sun->multiple.data != solved.sun->multiple.data);

    // At g = 0 every camera sees the same S: the isotropic field, no camera in the key.
    nlohmann::json iso = patch;
    iso["medium"] = {{"g", 0}};
    const scene::Scene flat = variant(dir, "flat", iso.dump());
    const sky::ScenePlan fp = sky::plan_scene(flat, d, quick());
    CHECK_FALSE(fp.settings.toward.has_value());
    CHECK(fp.directions == 1);
    // Refused, named: the lattice solves fixed directions; an unknown value.
    CHECK_THROWS_WITH_AS(
        variant(dir, "bad", R"({"transport": {"static_light": {"solver": "lattice", "directions": "camera"}}})"),
        doctest::Contains("/transport/static_light/directions"), core::Error);
    CHECK_THROWS_WITH_AS(variant(dir, "bad", R"({"transport": {"static_light": {"directions": "eye"}}})"),
                         doctest::Contains("/transport/static_light/directions"), core::Error);
}

TEST_CASE("the sun solved again on a worker thread: the newest request wins, the old field until then") {
    const auto dir = test::scratch_dir("sky_resolver");
    const scene::Scene s = variant(dir, "night", kSunSky);
    const core::Grid3<float> d = scene::make_density(s);
    const solve::Media media = sky::static_media(s, d);
    sky::SunResolver r(s, d, media, sky::solve_settings(s, d), 1);
    CHECK_FALSE(r.take().has_value());
    const glm::dvec3 first = scene::sun_direction(30.0, 0.0), last = scene::sun_direction(10.0, 90.0);
    r.request(first);
    r.request(last);  // replaces the first unless it has started
    // With exact orders 2 (the default) it answers twice: a preview (order 2 by the lattice),
    // then the refined solve of the same direction.
    REQUIRE(sky::solve_settings(s, d).exact_orders == 2);
    std::optional<sky::SunSolve> got;
    bool preview = false;
    for (int i = 0; i < 6000 && !(got && got->direction == last && !got->preview); ++i) {
        if (auto t = r.take()) {
            got = std::move(t);
            preview |= got->preview && got->direction == last;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    REQUIRE(got.has_value());
    CHECK(got->direction == last);
    CHECK_FALSE(got->preview);
    CHECK(preview);  // taken every 5 ms: the preview lands seconds before the refined solve
    CHECK(got->seconds > 0.0);
    CHECK(got->transmittance.geom == d.geom);
    const sky::SunSolve direct = sky::solve_sun(s, d, media, sky::solve_settings(s, d), last);
    CHECK(got->field.multiple.data == direct.field.multiple.data);  // the same solve, deterministic
    CHECK_FALSE(r.busy());
}

TEST_CASE("the sun solved again by Monte Carlo toward the camera: one answer, no preview, one field") {
    const auto dir = test::scratch_dir("sky_resolver_mc");
    nlohmann::json patch = nlohmann::json::parse(kSunSky);
    patch["transport"] = {{"static_light", {{"solver", "monte_carlo"}, {"paths", 3000}, {"directions", "camera"}}}};
    const scene::Scene s = variant(dir, "still", patch.dump());
    const core::Grid3<float> d = scene::make_density(s);
    const solve::Media media = sky::static_media(s, d);
    const sky::SolveSettings st = sky::solve_settings(s, d);
    REQUIRE(st.exact_orders == 2);  // a lattice solve of these settings would preview first
    sky::SunResolver r(s, d, media, st, 1);
    const glm::dvec3 sun = scene::sun_direction(20.0, 45.0);
    r.request(sun);
    std::vector<sky::SunSolve> answers;
    for (int i = 0; i < 6000 && (answers.empty() || r.busy()); ++i) {
        if (auto t = r.take()) answers.push_back(std::move(*t));
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (auto t = r.take()) answers.push_back(std::move(*t));
    REQUIRE(answers.size() == 1);
    CHECK_FALSE(answers[0].preview);
    CHECK(answers[0].field.multiple.directions.size() == 1);
    const sky::SunSolve direct = sky::solve_sun(s, d, media, st, sun);
    CHECK(answers[0].field.multiple.data == direct.field.multiple.data);
}

TEST_CASE("plan: the three content scenes trigger exactly the solves they call for") {
    struct Expect {
        const char* scene;
        bool bake;
        int sun, sky_single, sky_lattice, directions;
        const char* reason;
    };
    // The sky by the dome's Monte Carlo (the default sky_paths): no directions' single scatterings.
    for (const Expect e : {Expect{"storm", true, 1, 0, 2, 26, "moon (elevation 40 deg, azimuth -130 deg)"},
                           Expect{"dusk-storm", true, 1, 0, 2, 26, "sun (elevation 5 deg, azimuth -30 deg)"},
                           Expect{"day-cumulus", false, 1, 0, 2, 26, "no lightning (effects.lightning = false)"}}) {
        INFO(e.scene);
        const scene::Scene s =
            scene::load_scene(test::source_dir() / "content/scenes" / (std::string(e.scene) + ".json"));
        const core::Grid3<float> d = scene::make_density(s);
        const sky::ScenePlan p = sky::plan_scene(s, d, quick());
        CHECK(p.lightning.has_value() == e.bake);
        if (e.bake) CHECK(p.virtual_lights == 968);  // the default storm's grid (docs/bake.md)
        if (!e.bake) CHECK(p.virtual_lights == 0);
        CHECK(p.sun_solves == e.sun);
        CHECK(p.sky_single_solves == e.sky_single);
        CHECK(p.sky_lattice_solves == e.sky_lattice);
        CHECK(p.directions == e.directions);
        CHECK(mentions(p, e.reason));
    }
}

TEST_CASE("time of day: the sun's course passes through the scene's sun, redder and dimmer when low") {
    for (const auto& [el, az] :
         {std::pair{5.0, -30.0}, std::pair{40.0, -130.0}, std::pair{32.0, 25.0}, std::pair{85.0, 170.0}}) {
        INFO("elevation " << el << ", azimuth " << az);
        scene::Sun sun;
        sun.direction = scene::sun_direction(el, az);
        sun.irradiance = 60.0;
        sun.colour = glm::dvec3(1.0, 0.5, 0.22) / scene::luminance({1.0, 0.5, 0.22});
        const sky::SunCourse c = sky::sun_course(sun);
        // At its own hour the course is the scene's sun (1e-9: rounding through acos/atan2).
        const scene::Sun s0 = c.at(c.scene_hour);
        CHECK(glm::length(s0.direction - sun.direction) < 1e-9);
        CHECK(s0.irradiance == test::rel(sun.irradiance, 1e-9));
        CHECK(glm::length(s0.colour - sun.colour) < 1e-9);
        CHECK(c.scene_hour > 12.0);  // the afternoon
        // Noon is the highest, the ends of the course 1 degree above the horizon.
        double e = 0.0, a = 0.0;
        c.angles(12.0, e, a);
        CHECK(e >= std::max(50.0, el) - 1e-9);
        c.angles(c.first_hour, e, a);
        CHECK(e == test::rel(1.0, 1e-9));
        c.angles(c.last_hour, e, a);
        CHECK(e == test::rel(1.0, 1e-9));
        // Lower: dimmer and redder (blue over red falls), colour of luminance 1.
        const scene::Sun noon = c.at(12.0), late = c.at(c.last_hour);
        CHECK(late.irradiance < s0.irradiance);
        CHECK(noon.irradiance > s0.irradiance);
        CHECK(late.colour.z / late.colour.x < s0.colour.z / s0.colour.x);
        CHECK(scene::luminance(late.colour) == test::rel(1.0, 1e-12));
        CHECK(c.at(30.0).direction == late.direction);  // clamped to the course
    }
}
