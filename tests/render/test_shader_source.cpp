// GLSL preprocessing (#include, #line mapping) and driver-log mapping, without GL.
#include "render/detail/gl_program.h"

#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <string>

using namespace fulgur;
using render::detail::kLineBase;

TEST_CASE("preprocess expands includes once and emits #line blocks per file") {
    const auto dir = test::scratch_dir("shader_source");
    test::write_text(dir / "main.frag",
                     "#version 450 core\n#include \"a.glsl\"\n#include \"a.glsl\"\nvoid main() {}\n");
    test::write_text(dir / "a.glsl", "#include \"b.glsl\"\nfloat a() { return b(); }\n");
    test::write_text(dir / "b.glsl", "float b() { return 1.0; }\n");
    const auto pp = render::detail::preprocess(dir, "main.frag", "#define X 1\n");
    REQUIRE(pp.files.size() == 3);
    CHECK(pp.files[0] == "main.frag");
    CHECK(pp.files[1] == "a.glsl");
    CHECK(pp.files[2] == "b.glsl");
    CHECK(pp.text.rfind("#version 450 core\n#define X 1\n#line 2\n", 0) == 0);
    CHECK(pp.text.find("#line " + std::to_string(1 * kLineBase + 1) + "\n") != std::string::npos);
    CHECK(pp.text.find("#line " + std::to_string(2 * kLineBase + 1) + "\n") != std::string::npos);
    // b.glsl appears once although a.glsl is included twice.
    CHECK(pp.text.find("float b()") == pp.text.rfind("float b()"));
    CHECK(pp.text.find("float a()") == pp.text.rfind("float a()"));
}

TEST_CASE("preprocess errors name the file and line") {
    const auto dir = test::scratch_dir("shader_source_errors");
    test::write_text(dir / "no_version.frag", "void main() {}\n");
    test::write_text(dir / "missing.frag", "#version 450 core\n\n#include \"nope.glsl\"\n");
    test::write_text(dir / "inner_version.frag", "#version 450 core\n#include \"v.glsl\"\n");
    test::write_text(dir / "v.glsl", "// comment\n#version 450 core\n");
    try {
        render::detail::preprocess(dir, "no_version.frag");
        FAIL("expected an error");
    } catch (const core::Error& e) {
        CHECK(e.where() == "no_version.frag:1");
    }
    try {
        render::detail::preprocess(dir, "missing.frag");
        FAIL("expected an error");
    } catch (const core::Error& e) {
        CHECK(e.where() == "missing.frag:3");
        CHECK(std::string(e.what()).find("nope.glsl") != std::string::npos);
    }
    try {
        render::detail::preprocess(dir, "inner_version.frag");
        FAIL("expected an error");
    } catch (const core::Error& e) {
        CHECK(e.where() == "v.glsl:2");
    }
}

TEST_CASE("driver logs are mapped back to files") {
    const std::vector<std::string> files = {"main.frag", "common.glsl", "volume.glsl"};
    const std::string l1 = std::to_string(2 * kLineBase + 17), l0 = "12";
    const auto mesa =
        render::detail::map_log("0:" + l1 + "(5): error: `foo' undeclared\n0:" + l0 + "(2): error: x\n", files);
    CHECK(mesa.first_location == "volume.glsl:17");
    CHECK(mesa.text.find("volume.glsl:17(5): error: `foo' undeclared") != std::string::npos);
    CHECK(mesa.text.find("main.frag:12(2): error: x") != std::string::npos);
    const auto nvidia =
        render::detail::map_log("0(" + std::to_string(kLineBase + 3) + ") : error C1008: undefined\n", files);
    CHECK(nvidia.first_location == "common.glsl:3");
    const auto amd =
        render::detail::map_log("ERROR: 0:" + std::to_string(kLineBase + 9) + ": 'x' : undeclared\n", files);
    CHECK(amd.first_location == "common.glsl:9");
    const auto none = render::detail::map_log("error: unresolved reference to function `f'\n", files);
    CHECK(none.first_location.empty());
    // A line number beyond the known files is left alone.
    const auto stray = render::detail::map_log("0:" + std::to_string(9 * kLineBase) + "(1): error\n", files);
    CHECK(stray.first_location.empty());
}
