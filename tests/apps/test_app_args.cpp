// fulgur-shot's and fulgur's argument validation and the tiny test scenes used by the golden tests.
#include "common/demo_args.h"
#include "common/shot_args.h"
#include "core/core.h"
#include "scene/scene.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <fstream>

using namespace fulgur;

namespace {
app::ShotArgs parse(std::vector<std::string> a) { return app::parse_shot_args(a); }
// The scene must exist (the parser checks): a test scene stands for any scene file.
const std::string s_json = FULGUR_SOURCE_DIR "/tests/apps/scenes/test_iso_ss_ic.json";
const std::vector<std::string> good = {s_json, "--seed", "7", "--time", "0.05", "--size", "64x32", "-o", "x.png"};
}  // namespace

TEST_CASE("fulgur-shot: a complete command line parses") {
    const app::ShotArgs a = parse(good);
    CHECK(a.scene == s_json);
    CHECK(a.seed == 7);
    CHECK(a.time == doctest::Approx(0.05));
    CHECK_FALSE(a.time_after_return_stroke);
    std::vector<std::string> plus = good;
    plus[4] = "+0.002";
    CHECK(parse(plus).time_after_return_stroke);
    CHECK(parse(plus).time == doctest::Approx(0.002));
    std::vector<std::string> more = good;
    more.insert(more.end(), {"--repeat", "12", "--exposure", "-2.5"});
    CHECK(parse(more).repeat == 12);
    CHECK(parse(more).exposure_ev == -2.5);
    CHECK_FALSE(parse(more).manual_exposure.has_value());  // automatic unless asked
    std::vector<std::string> manual = good;
    manual.insert(manual.end(), {"--manual-exposure", "0.125"});
    CHECK(parse(manual).manual_exposure.value() == 0.125);
    manual.back() = "1e38";  // the largest a float32 uniform carries as a power of ten
    CHECK(parse(manual).manual_exposure.value() == 1e38);
    for (const char* bad : {"0", "-1", "2e38", "inf", "nan"}) {
        manual.back() = bad;
        CHECK_THROWS_WITH_AS(parse(manual), doctest::Contains("--manual-exposure must be in (0, 1e38]"), core::Error);
    }
    CHECK_FALSE(parse(good).since_known_ms.has_value());  // the strike's own solve is waited for
    std::vector<std::string> known = good;
    known.insert(known.end(), {"--since-known", "100"});
    CHECK(parse(known).since_known_ms.value() == 100.0);
    for (const char* bad : {"-1", "nan", "inf", "1e9", "Leader", "leaders"}) {
        known.back() = bad;
        CHECK_THROWS_WITH_AS(parse(known), doctest::Contains("--since-known must be"), core::Error);
    }
    CHECK(parse(good).strike_grid == 0);  // the quality's own grid
    std::vector<std::string> grid = good;
    grid.insert(grid.end(), {"--strike-grid", "3"});
    CHECK(parse(grid).strike_grid == 3);
    for (const char* bad : {"1", "0", "65", "2.5", "x"}) {  // 1 is the lighting grid itself
        grid.back() = bad;
        CHECK_THROWS_WITH_AS(parse(grid), doctest::Contains("--strike-grid"), core::Error);
    }
    known.back() = "leader";  // triggered at its leader's start: the time comes from the strike
    CHECK(parse(known).since_leader);
    CHECK(parse(known).since_known_ms.has_value());
    CHECK_FALSE(parse(known).without_instant);  // an unscheduled strike: the instant way meanwhile
    known.push_back("--without-instant");
    CHECK(parse(known).without_instant);
    std::vector<std::string> alone = good;  // nothing to say without a strike that became known
    alone.push_back("--without-instant");
    CHECK_THROWS_WITH_AS(parse(alone), doctest::Contains("--without-instant goes with --since-known"), core::Error);
    more[more.size() - 3] = "0";  // --repeat 0
    CHECK_THROWS_AS(parse(more), core::Error);
    CHECK(a.width == 64);
    CHECK(a.height == 32);
    CHECK(a.output == "x.png");
    CHECK_FALSE(a.fgb.has_value());
    const std::string b_fgb = (test::scratch_dir("app_args") / "b.fgb").string();  // --fgb must exist
    std::ofstream(b_fgb) << "";
    std::vector<std::string> f = good;
    f.insert(f.end(), {"--fgb", b_fgb});
    CHECK(parse(f).fgb.value() == b_fgb);
    f.back() = b_fgb + ".missing";
    CHECK_THROWS_AS(parse(f), core::Error);
    CHECK(parse({"--help"}).help);
    CHECK(app::shot_usage().find("--size") != std::string::npos);
    CHECK(a.off.empty());
    std::vector<std::string> off = good;
    off.insert(off.end(), {"--off", "sun,silver-lining,multiple"});
    CHECK(parse(off).off == std::vector<std::string>{"sun", "silver-lining", "multiple"});
    off.back() = "dither,display-upsample";
    CHECK(parse(off).off == std::vector<std::string>{"dither", "display-upsample"});
    off.back() = "sun,moon";
    CHECK_THROWS_WITH_AS(parse(off), doctest::Contains("--off: \"moon\" is not one of sun, sky"), core::Error);
    off.back() = "";
    CHECK_THROWS_WITH_AS(parse(off), doctest::Contains("--off: \"\" is not one of"), core::Error);
}

TEST_CASE("fulgur-shot: invalid command lines are rejected with a reason") {
    auto without = [](const std::string& opt, int n) {
        std::vector<std::string> v = good;
        auto it = std::find(v.begin(), v.end(), opt);
        v.erase(it, it + n);
        return v;
    };
    CHECK_THROWS_AS(parse(without("--seed", 2)), core::Error);
    CHECK_THROWS_AS(parse(without("--time", 2)), core::Error);
    CHECK_THROWS_AS(parse(without("--size", 2)), core::Error);
    CHECK_THROWS_AS(parse(without("-o", 2)), core::Error);
    CHECK_THROWS_AS(parse(without(s_json, 1)), core::Error);
    auto with = [](std::size_t i, const std::string& v) {
        std::vector<std::string> a = good;
        a[i] = v;
        return a;
    };
    CHECK_THROWS_AS(parse(with(2, "-1")), core::Error);    // negative seed
    CHECK_THROWS_AS(parse(with(2, "7x")), core::Error);    // trailing garbage
    CHECK_THROWS_AS(parse(with(4, "-0.1")), core::Error);  // negative time
    CHECK_THROWS_AS(parse(with(4, "nan")), core::Error);
    CHECK_THROWS_AS(parse(with(6, "64")), core::Error);  // no 'x'
    CHECK_THROWS_AS(parse(with(6, "0x32")), core::Error);
    CHECK_THROWS_AS(parse(with(6, "64x99999")), core::Error);
    std::vector<std::string> extra = good;
    extra.push_back("--bogus");
    CHECK_THROWS_AS(parse(extra), core::Error);
    extra.back() = "second.json";
    CHECK_THROWS_AS(parse(extra), core::Error);
    std::vector<std::string> missing = good;
    missing.push_back("--fgb");  // option without its value
    CHECK_THROWS_AS(parse(missing), core::Error);
}

TEST_CASE("golden-test scenes are tiny and cover the required cases") {
    const std::filesystem::path dir = std::filesystem::path(FULGUR_SOURCE_DIR) / "tests/apps/scenes";
    bool iso = false, aniso = false, ss_only = false, ms = false, cg = false, ic = false;
    for (std::string name : {"test_iso_ms_cg", "test_aniso_ms_cg", "test_aniso_ss_ic", "test_iso_ss_ic"}) {
        CAPTURE(name);
        const scene::Scene s = scene::load_scene(dir / (name + ".json"));
        const core::Grid3<float> d = scene::make_density(s);
        // Tiny: at most 32 x 32 x 16 density voxels so the test bakes in seconds.
        CHECK(d.geom.cell_count() <= 32u * 32u * 16u);
        float dmax = 0;
        for (float v : d.data) dmax = std::max(dmax, v);
        CHECK(dmax > 0.3f);  // a cloud dense enough for bolts to start in (start_density_threshold)
        (s.medium.g == 0.0 ? iso : aniso) = true;
        (s.effects.multiple_scattering ? ms : ss_only) = true;
        (s.lightning.bolt.kind == lightning::Kind::CloudToGround ? cg : ic) = true;
    }
    CHECK((iso && aniso && ss_only && ms && cg && ic));
}

TEST_CASE("fulgur-shot: --reference names a PNG other than -o") {
    std::vector<std::string> r = good;
    CHECK_FALSE(parse(r).reference.has_value());
    r.insert(r.end(), {"--reference", "ref.png"});
    CHECK(parse(r).reference.value() == "ref.png");
    r.back() = "ref.jpg";
    CHECK_THROWS_AS(parse(r), core::Error);
    r.back() = "x.png";  // the basis frame's own output
    CHECK_THROWS_AS(parse(r), core::Error);
    r.pop_back();  // missing value
    CHECK_THROWS_AS(parse(r), core::Error);
}

TEST_CASE("fulgur-shot: --vdb names a .vdb file") {
    std::vector<std::string> r = good;
    CHECK_FALSE(parse(r).vdb.has_value());
    r.insert(r.end(), {"--vdb", "lit.vdb"});
    CHECK(parse(r).vdb.value() == "lit.vdb");
    r.back() = "lit.nrrd";
    CHECK_THROWS_WITH_AS(parse(r), doctest::Contains("--vdb must name a .vdb file, got 'lit.nrrd'"), core::Error);
}

TEST_CASE("fulgur: the demo's command line parses strictly") {
    auto demo = [](std::vector<std::string> a) { return app::parse_demo_args(a); };
    const app::DemoArgs d = demo({});
    CHECK(d.scene == "content/scenes/storm.json");
    CHECK(d.frames == 8);
    CHECK(d.width == 1280);
    CHECK(d.height == 720);
    CHECK(d.time_scale == 0.25);
    CHECK_FALSE(d.seed.has_value());
    CHECK(d.dither);
    CHECK(d.panels);
    CHECK_FALSE(demo({"--hide-panels"}).panels);
    CHECK(d.orbit_deg_per_s == 0.0);
    CHECK(demo({"--orbit", "-30"}).orbit_deg_per_s == -30.0);
    const app::DemoArgs e = demo({s_json, "--frames", "3", "--size", "320x180", "--seed", "5", "--time-scale", "0.5",
                                  "--no-dither", "--headless", "--solve-direct"});
    CHECK(e.scene == s_json);
    CHECK(e.frames == 3);
    CHECK(e.width == 320);
    CHECK(e.height == 180);
    CHECK(e.seed.value() == 5);
    CHECK(e.time_scale == 0.5);
    CHECK_FALSE(e.dither);
    CHECK(e.headless);
    CHECK(e.solve_direct);
    CHECK(demo({"--screenshot-at-peak"}).screenshot_after == 4);  // a few frames for the panel
    CHECK(demo({"--screenshot-at-peak", "--screenshot-after", "7"}).screenshot_after == 7);
    CHECK(demo({"--help"}).help);
    CHECK(app::demo_usage().find("--time-scale") != std::string::npos);
    CHECK_FALSE(d.time_of_day.has_value());
    CHECK(demo({"--time-of-day", "17.5"}).time_of_day.value() == 17.5);

    auto rejects = [&](std::vector<std::string> a, const char* reason) {
        CAPTURE(reason);
        CHECK_THROWS_WITH_AS(demo(a), doctest::Contains(reason), core::Error);
    };
    rejects({"--frames", "3x"}, "not a number");  // atoi took the 3
    rejects({"--frames", "0"}, "1..10000");
    rejects({"--time-scale", "nan"}, "0.001..10");
    rejects({"--time-scale", "inf"}, "0.001..10");
    rejects({"--time-scale", "0.5s"}, "not a number");  // atof took the 0.5
    rejects({"--time-of-day", "25"}, "solar time in [0, 24] hours");
    rejects({"--time-of-day", "nan"}, "solar time in [0, 24] hours");
    rejects({"--time-of-day", "5pm"}, "not a number");
    rejects({"--orbit", "400"}, "-360..360");
    rejects({"--orbit", "nan"}, "-360..360");
    rejects({"--size", "320x"}, "not a number");
    rejects({"--size", "8x8"}, "16..8192");
    rejects({"--screenshot-after", "0"}, ">= 1");
    rejects({"--seed", "-1"}, "not a number");
    rejects({"--seed"}, "needs a value");
    rejects({"--bogus"}, "unknown option");
    rejects({"missing.json"}, "missing.json");
    rejects({s_json, s_json}, "more than one scene");
}

TEST_CASE("fulgur-shot: --exr names an .exr other than the other outputs; --exr-passes needs it") {
    std::vector<std::string> r = good;
    CHECK_FALSE(parse(r).exr.has_value());
    r.push_back("--exr-passes");
    CHECK_THROWS_WITH_AS(parse(r), doctest::Contains("--exr-passes goes with --exr"), core::Error);
    r.insert(r.end(), {"--exr", "f.exr"});
    const app::ShotArgs a = parse(r);
    CHECK(a.exr.value() == "f.exr");
    CHECK(a.exr_passes);
    r.back() = "f.png";
    CHECK_THROWS_WITH_AS(parse(r), doctest::Contains("--exr must name a .exr file"), core::Error);
    r = good;
    r.insert(r.end(), {"--exr", "a.exr", "--reference", "a.png"});
    CHECK_NOTHROW(parse(r));
    CHECK(app::reference_exr_path("out/a.exr") == std::filesystem::path("out/a_reference.exr"));
}

TEST_CASE("fulgur-shot: --internal-scale is a fraction of the output resolution") {
    std::vector<std::string> r = good;
    CHECK(parse(r).internal_scale == 0.5);
    r.insert(r.end(), {"--internal-scale", "1"});
    CHECK(parse(r).internal_scale == 1.0);
    for (const char* bad : {"0", "1.5", "-0.5", "nan"}) {
        r.back() = bad;
        CHECK_THROWS_AS(parse(r), core::Error);
    }
}

TEST_CASE("fulgur-shot: --blender takes a directory") {
    std::vector<std::string> r = good;
    r.insert(r.end(), {"--blender", "out/blender"});
    CHECK(parse(r).blender.value() == "out/blender");
    r.back() = "";
    CHECK_THROWS_WITH_AS(parse(r), doctest::Contains("--blender needs a directory"), core::Error);
}
