// fulgur-bake's argument validation: every bad command line is an error with a reason.
#include "common/bake_args.h"
#include "core/core.h"

#include <doctest/doctest.h>

using namespace fulgur;

namespace {
app::BakeArgs parse(std::vector<std::string> a) { return app::parse_bake_args(a); }
// The scene must exist (the parser checks): a test scene stands for any scene file.
const std::string s_json = FULGUR_SOURCE_DIR "/tests/apps/scenes/test_iso_ss_ic.json";
}  // namespace

TEST_CASE("fulgur-bake: valid command lines") {
    app::BakeArgs a = parse({s_json});
    CHECK(a.scene == s_json);
    CHECK_FALSE(a.output.has_value());
    CHECK_FALSE(a.dry_run);
    a = parse({s_json, "-o", "x.fgb", "--dry-run", "--threads", "2", "--report", "r.json", "--force"});
    CHECK(a.output.value() == "x.fgb");
    CHECK(a.dry_run);
    CHECK(a.force);
    CHECK(a.threads == 2);
    CHECK(a.report.value() == "r.json");
    a = parse({s_json, "--export", "3,7:0.5,9:-2", "--direction", "4", "--nrrd", "out/x"});
    REQUIRE(a.export_lights.size() == 3);
    CHECK(a.export_lights[0].light == 3);
    CHECK(a.export_lights[0].weight == 1.0);
    CHECK(a.export_lights[1].weight == 0.5);
    CHECK(a.export_lights[2].weight == -2.0);
    CHECK(a.export_direction == 4);
    CHECK(a.export_prefix == "out/x");
    a = parse({s_json, "--export", "3", "--export", "7:0.5", "--nrrd", "out/x"});  // repeated lists add up
    REQUIRE(a.export_lights.size() == 2);
    CHECK(a.export_lights[1].light == 7);
    a = parse({s_json, "--export", "3", "--vdb", "out/lit"});  // --vdb alone: every direction, no NRRD
    CHECK(a.vdb_prefix == "out/lit");
    CHECK(a.export_prefix.empty());
    CHECK(parse({"--help"}).help);
}

TEST_CASE("fulgur-bake: invalid command lines are rejected with a reason") {
    auto rejects = [](std::vector<std::string> a, const char* reason) {
        CAPTURE(reason);
        CHECK_THROWS_WITH_AS(parse(a), doctest::Contains(reason), core::Error);
    };
    rejects({}, "no SCENE.json");
    rejects({s_json, s_json}, "more than one scene");
    rejects({"missing.json"}, "missing.json");
    rejects({s_json, "--bogus"}, "unknown option");
    rejects({s_json, "-o"}, "needs a value");
    rejects({s_json, "--threads", "0"}, "1..1024");
    rejects({s_json, "--threads", "two"}, "not a number");
    rejects({s_json, "--threads", "0x10"}, "not a number");  // base 10 only
    rejects({s_json, "--threads", "2.5"}, "not a number");
    rejects({s_json, "--export", "1,x"}, "not a number");
    rejects({s_json, "--export", "1,"}, "not a number");
    rejects({s_json, "--export", "1:nan", "--nrrd", "p"}, "finite");
    rejects({s_json, "--export", "-1", "--nrrd", "p"}, "not a number");
    rejects({s_json, "--export", "1"}, "--export needs --nrrd PREFIX or --vdb PREFIX");
    rejects({s_json, "--nrrd", "p"}, "only go with --export");
    rejects({s_json, "--vdb", "p"}, "only go with --export");
    rejects({s_json, "--export", "1", "--vdb", "p", "--direction", "2"}, "--direction only goes with --nrrd");
    rejects({s_json, "--export", "1", "--nrrd", "p", "--dry-run"}, "--dry-run");
    rejects({s_json, "--export", "1", "--nrrd", "p", "--direction", "-3"}, "--direction");
}
