// fulgur-shot's argument validation and the tiny test scenes used by the golden tests.
#include "common/shot_args.h"
#include "core/core.h"
#include "scene/scene.h"

#include <doctest/doctest.h>

#include <algorithm>

using namespace fulgur;

namespace {
app::ShotArgs parse(std::vector<std::string> a) { return app::parse_shot_args(a); }
const std::vector<std::string> good = {"s.json", "--seed", "7", "--time", "0.05", "--size", "64x32", "-o", "x.png"};
}  // namespace

TEST_CASE("fulgur-shot: a complete command line parses") {
    const app::ShotArgs a = parse(good);
    CHECK(a.scene == "s.json");
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
    more[more.size() - 3] = "0";  // --repeat 0
    CHECK_THROWS_AS(parse(more), core::Error);
    CHECK(a.width == 64);
    CHECK(a.height == 32);
    CHECK(a.output == "x.png");
    CHECK_FALSE(a.fgb.has_value());
    std::vector<std::string> f = good;
    f.insert(f.end(), {"--fgb", "b.fgb"});
    CHECK(parse(f).fgb.value() == "b.fgb");
    CHECK(parse({"--help"}).help);
    CHECK(app::shot_usage().find("--size") != std::string::npos);
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
    CHECK_THROWS_AS(parse(without("s.json", 1)), core::Error);
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
