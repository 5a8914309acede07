// The view a scene states: view::scene_camera and view::explicit_orbit against the default view,
// the tools' --camera, and every golden scene stating its camera.
#include "common/demo_args.h"
#include "common/shot_args.h"
#include "core/core.h"
#include "scene/scene.h"
#include "support/test_support.h"
#include "view/view.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <filesystem>

using namespace fulgur;

namespace {

core::Grid3<float> box_density() {
    core::GridGeometry g;
    g.dims = {40, 30, 20};
    g.voxel_size = 250.0;
    g.origin = {-5000.0, -3750.0, 500.0};
    return core::Grid3<float>(g);
}

void check_same(const render::Camera& a, const render::Camera& b, double tol) {
    CHECK(glm::length(a.position - b.position) <= tol);
    CHECK(glm::length(a.target - b.target) <= tol);
    CHECK(glm::length(a.up - b.up) <= 1e-12);
    CHECK(a.vertical_fov_deg == b.vertical_fov_deg);
}

}  // namespace

TEST_CASE("scene_camera: no camera and an orbit's defaults are the default view, bit for bit") {
    const core::Grid3<float> d = box_density();
    check_same(view::scene_camera(std::nullopt, d), view::default_camera(d), 0.0);
    scene::CameraSpec orbit;  // azimuth -90, elevation 6: the default view's angles
    check_same(view::scene_camera(orbit, d), view::default_camera(d), 0.0);
    orbit.azimuth_deg = 30.0;
    orbit.elevation_deg = 20.0;
    check_same(view::scene_camera(orbit, d), view::default_camera(d, 30.0, 20.0), 0.0);
    // explicit_orbit states the defaults; the camera it gives is the same one.
    const scene::CameraSpec stated = view::explicit_orbit(orbit, d);
    REQUIRE(stated.orbit_target.has_value());
    REQUIRE(stated.distance.has_value());
    CHECK(*stated.distance == 1.1 * 10000.0);  // 1.1 x the largest extent (40 x 250 m)
    CHECK(*stated.orbit_target == glm::dvec3(0.0, 0.0, 500.0 + 0.33 * 5000.0));
    check_same(view::scene_camera(stated, d), view::scene_camera(orbit, d), 0.0);
}

TEST_CASE("scene_camera: a look-at camera as stated, and as the orbit through its position") {
    const core::Grid3<float> d = box_density();
    scene::CameraSpec look;
    look.kind = scene::CameraSpec::Kind::LookAt;
    look.position = {3000.0, -9000.0, 300.0};
    look.target = {0.0, 500.0, 4000.0};
    look.vertical_fov_deg = 70.0;
    const render::Camera c = view::scene_camera(look, d);
    CHECK(c.position == look.position);
    CHECK(c.target == look.target);
    CHECK(c.vertical_fov_deg == 70.0);
    // The demo turns it as an orbit around its target: the same camera (up +z).
    const scene::CameraSpec o = view::explicit_orbit(look, d);
    CHECK(o.kind == scene::CameraSpec::Kind::Orbit);
    CHECK(o.vertical_fov_deg == 70.0);
    check_same(view::scene_camera(o, d), c, 1e-8 * glm::length(look.position - look.target));
}

TEST_CASE("scene::camera_position stands where scene_camera places the camera, bit for bit") {
    // The static light solved toward the camera (sky::solve_settings) takes its point from
    // scene::camera_position; the renderer's camera is view::scene_camera's.
    const core::Grid3<float> d = box_density();
    CHECK(scene::camera_position(std::nullopt, d.geom) == view::scene_camera(std::nullopt, d).position);
    scene::CameraSpec orbit;
    orbit.azimuth_deg = 33.0;
    orbit.elevation_deg = -4.5;
    CHECK(scene::camera_position(orbit, d.geom) == view::scene_camera(orbit, d).position);
    orbit.orbit_target = glm::dvec3(100.0, -200.0, 1500.0);
    orbit.distance = 7300.0;
    CHECK(scene::camera_position(orbit, d.geom) == view::scene_camera(orbit, d).position);
    scene::CameraSpec look;
    look.kind = scene::CameraSpec::Kind::LookAt;
    look.position = {3000.0, -9000.0, 300.0};
    look.target = {0.0, 500.0, 4000.0};
    CHECK(scene::camera_position(look, d.geom) == look.position);
}

TEST_CASE("strike_toward and static_toward: the scene's camera when asked, none when baked or at g = 0") {
    const core::Grid3<float> d = box_density();
    scene::Scene s;
    s.medium.g = 0.6;
    scene::CameraSpec look;
    look.kind = scene::CameraSpec::Kind::LookAt;
    look.position = {3000.0, -9000.0, 300.0};
    s.camera = look;
    scene::Quality q = scene::quality_preset("per_strike_mc");
    CHECK_FALSE(scene::strike_toward(s, q, d.geom).has_value());  // baked directions
    q.toward_camera = true;
    REQUIRE(scene::strike_toward(s, q, d.geom).has_value());
    CHECK(*scene::strike_toward(s, q, d.geom) == look.position);

    CHECK_FALSE(scene::static_toward(s, d.geom).has_value());
    s.transport.static_toward_camera = true;  // only a Monte Carlo static light is tallied toward a point
    CHECK_FALSE(scene::static_toward(s, d.geom).has_value());
    s.transport.static_monte_carlo = true;
    REQUIRE(scene::static_toward(s, d.geom).has_value());
    CHECK(*scene::static_toward(s, d.geom) == look.position);

    s.camera.reset();  // no camera: the default orbit's position
    CHECK(*scene::strike_toward(s, q, d.geom) == scene::camera_position(std::nullopt, d.geom));

    s.medium.g = 0.0;  // isotropic: S is the same toward every point
    CHECK_FALSE(scene::strike_toward(s, q, d.geom).has_value());
    CHECK_FALSE(scene::static_toward(s, d.geom).has_value());
}

TEST_CASE("--camera on fulgur-shot and fulgur: JSON text or a file, validated") {
    const std::string scene_file = FULGUR_SOURCE_DIR "/tests/apps/scenes/test_iso_ss_ic.json";
    const std::vector<std::string> shot = {scene_file, "--seed", "1", "--time", "0", "--size", "64x32", "-o", "x.png"};
    auto with_camera = [&](const std::string& c) {
        std::vector<std::string> a = shot;
        a.insert(a.end(), {"--camera", c});
        return app::parse_shot_args(a);
    };
    CHECK_FALSE(app::parse_shot_args(shot).camera.has_value());
    const app::ShotArgs s = with_camera(R"({"orbit": {"azimuth": -45, "elevation": 8}, "vertical_fov": 40})");
    REQUIRE(s.camera.has_value());
    CHECK(s.camera->azimuth_deg == -45.0);
    CHECK(s.camera->vertical_fov_deg == 40.0);
    const std::filesystem::path file = test::scratch_dir("camera_args") / "view.json";
    core::write_file(file, R"({"position": [0, -9000, 300], "target": [0, 0, 4000]})");
    CHECK(with_camera(file.string()).camera->kind == scene::CameraSpec::Kind::LookAt);
    CHECK(app::parse_demo_args({"--camera", file.string()}).camera->target == glm::dvec3(0, 0, 4000));
    CHECK_THROWS_WITH_AS(with_camera(R"({"orbit": {"azimuth": -45}})"),
                         doctest::Contains("fulgur-shot: --camera: /orbit/elevation"), core::Error);
    CHECK_THROWS_WITH_AS(app::parse_demo_args({"--camera", "{\"position\": [0, 0, 0], \"target\": [0, 0, 1]}"}),
                         doctest::Contains("fulgur: --camera: /up: is parallel"), core::Error);
    CHECK_THROWS_WITH_AS(with_camera((file.parent_path() / "missing.json").string()), doctest::Contains("--camera"),
                         core::Error);
}

TEST_CASE("every golden and README scene states its camera") {
    // The golden tests render view::scene_camera(scene.camera): a scene without one would be
    // rendered from a view that moves whenever the default does.
    for (const char* f :
         {"content/scenes/storm.json", "content/scenes/dusk-storm.json", "content/scenes/day-cumulus.json",
          "content/scenes/vdb-cloud.json", "content/scenes/storm-full.json", "content/scenes/dusk-storm-full.json",
          "content/scenes/day-cumulus-full.json", "tests/apps/scenes/test_aniso_ms_cg.json",
          "tests/apps/scenes/test_aniso_ss_ic.json", "tests/apps/scenes/test_iso_ms_cg.json",
          "tests/apps/scenes/test_iso_ss_ic.json", "tests/apps/scenes/test_day_sun.json",
          "tests/apps/scenes/test_vdb_cloud.json"}) {
        CAPTURE(f);
        const scene::Scene s = scene::load_scene(test::source_dir() / f);
        CHECK(s.camera.has_value());
    }
}
