// The run time's pure logic on hand-made bakes (no solver): the accumulation layout, the
// sparse sum + inverse Haar against the double reference (basis::reconstruct), components,
// ambient, empty frames, thread independence, and rejected files. Fast; runs under ASan.
// Files: tests/basis/bake_fixture.h (8 lights, 5x4x3 lighting grid, 3 directions).
#include "basis/detail/internal.h"
#include "runtime/detail/internal.h"
#include "runtime/runtime.h"

#include "basis/bake_fixture.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

using namespace fulgur;

namespace {

std::filesystem::path write_bake(const std::string& name, const basis::FgbMetadata& m) {
    const std::filesystem::path p = test::scratch_dir("runtime_unit_" + name) / "b.fgb";
    basis::FgbWriter w(p, m);
    for (std::uint32_t l = 0; l < m.light_count(); ++l) w.add(test::small_light(m, l));
    w.finish();
    return p;
}

// Weights for every light of the fixture's 2x2x2 grid (light 5 has no coefficients).
lightning::LightWeights weights(std::size_t lights, std::initializer_list<std::pair<std::uint32_t, double>> e) {
    lightning::LightWeights w;
    w.e.assign(lights, 0.0);
    w.touched.assign(lights, 0);
    for (const auto& [l, v] : e) {
        w.e[l] = v;
        w.touched[l] = 1;
        w.active.push_back(l);
    }
    return w;
}

}  // namespace

TEST_CASE("bases: the accumulation layout holds every coefficient of the file") {
    for (const std::uint32_t comps : {1u, 2u}) {
        const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16, {5, 4, 3}, 3, comps);
        const auto path = write_bake("layout" + std::to_string(comps), m);
        const basis::BakedBasis file = basis::load_fgb(path);
        const runtime::BakedBases b = runtime::BakedBases::load(path);
        CHECK(b.coefficient_count() == file.coefficient_count());
        CHECK(b.metadata() == file.meta);
        CHECK(b.separate() == (comps == 2));
        CHECK(b.has_multiple());
        CHECK(b.memory_bytes() > 0);
        const runtime::BakedBases::Impl& im = runtime::bases_impl(b);
        CHECK(im.narrow);  // 60 cells: 16-bit indices
        CHECK(im.index32.empty());
        for (std::uint32_t l = 0; l < m.light_count(); ++l)
            for (std::size_t k = 0; k < m.bases(); ++k) {
                const basis::CompressedBasis& cb = file.lights[l].directions[k];
                const std::size_t r = im.run(l, k);
                REQUIRE(im.offset[r + 1] - im.offset[r] == cb.size());
                CHECK(im.gamma[r] == cb.gamma);
                // The file's coefficients (in the order stored: by index in a deflated file).
                basis::CompressedBasis run;
                CHECK(im.half);  // a float16 file keeps its values in float16
                for (std::size_t q = im.offset[r]; q < im.offset[r + 1]; ++q) {
                    run.index.push_back(im.index16[q]);
                    run.value.push_back(im.value_at(r, q - im.offset[r]));
                }
                CHECK(std::is_sorted(run.index.begin(), run.index.end()));
                basis::sort_canonical(run);
                CHECK(run.index == cb.index);
                CHECK(run.value == cb.value);
            }
        CHECK(im.offset[im.run(5, 0)] == im.offset[im.run(5, m.bases() - 1) + 1]);  // the dropped light is empty
    }
}

TEST_CASE("reconstruct: float sum + inverse Haar agrees with the double reference") {
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16);
    const auto path = write_bake("ref", m);
    const basis::BakedBasis file = basis::load_fgb(path);
    const runtime::BakedBases b = runtime::BakedBases::load(path);
    runtime::Reconstructor rec(b);
    const auto w = weights(8, {{0, 3.5e4}, {2, 1.0}, {3, 7.25e5}, {5, 2e3}, {7, 0.125}});
    runtime::RadianceField out;
    runtime::StageTimes t;
    REQUIRE(rec.reconstruct(w, {}, {}, out, t));
    CHECK(out.directions == std::vector<int>{0, 1, 2});  // empty request: all directions
    CHECK(out.direction_count == 3);
    CHECK(out.geometry == m.lighting);
    CHECK(out.components.single);
    CHECK(out.components.multiple);
    CHECK(t.accumulate >= 0.0);
    CHECK(t.inverse_haar >= 0.0);
    std::vector<basis::WeightedLight> wl;
    for (const std::uint32_t l : w.active) wl.push_back({l, w.e[l]});
    for (std::size_t d = 0; d < 3; ++d) {
        const core::Grid3<float> ref = basis::reconstruct(file, wl, d);
        // float32 weights, products, sums of 5 terms and a 3-level inverse: a few float
        // ulps (6e-8) per operation over ~15 operations; 2e-6 leaves a factor ~2 of margin.
        CHECK(test::relative_l2(out.values[d], ref.data) < 2e-6);
    }

    // A subset, in the caller's order, duplicates allowed.
    const std::vector<int> some = {2, 0, 2};
    REQUIRE(rec.reconstruct(w, some, {}, out, t));
    CHECK(out.directions == some);
    REQUIRE(out.values.size() == 3);
    CHECK(out.values[0] == out.values[2]);
    CHECK(test::relative_l2(out.values[1], basis::reconstruct(file, wl, 0).data) < 2e-6);  // as above

    const std::vector<int> bad = {3};
    CHECK_THROWS_WITH_AS(rec.reconstruct(w, bad, {}, out, t), doctest::Contains("direction 3 does not exist"),
                         core::Error);
}

TEST_CASE("reconstruct: no active light returns false, touches nothing and costs nothing") {
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float32);
    const runtime::BakedBases b = runtime::BakedBases::load(write_bake("empty", m));
    runtime::Reconstructor rec(b);
    runtime::RadianceField out;
    out.direction_count = 77;
    out.values = {{1.0f, 2.0f}};
    runtime::StageTimes t;
    t.accumulate = t.inverse_haar = 5.0;
    CHECK_FALSE(rec.reconstruct(weights(8, {}), {}, {}, out, t));
    CHECK(out.direction_count == 77);
    CHECK(out.values == std::vector<std::vector<float>>{{1.0f, 2.0f}});
    CHECK(t.accumulate == 0.0);
    CHECK(t.inverse_haar == 0.0);
    // Only the dropped light (no coefficients): valid, all zero.
    REQUIRE(rec.reconstruct(weights(8, {{5, 1e3}}), {}, {}, out, t));
    for (const auto& v : out.values)
        for (const float x : v) CHECK(x == 0.0f);
}

TEST_CASE("reconstruct: components - separate parts add up, combined and missing parts are flagged") {
    // Separate: single-only + multiple-only == both, exactly up to float rounding.
    const basis::FgbMetadata m2 = test::small_metadata(basis::Precision::Float16, {5, 4, 3}, 3, 2);
    const runtime::BakedBases b2 = runtime::BakedBases::load(write_bake("sep", m2));
    runtime::Reconstructor rec(b2);
    const auto w = weights(8, {{1, 2.0}, {4, 5e3}, {6, 1e-3}});
    runtime::RadianceField both, single, multiple, none;
    runtime::StageTimes t;
    runtime::ReconstructOptions o;
    REQUIRE(rec.reconstruct(w, {}, o, both, t));
    o.components = {true, false};
    REQUIRE(rec.reconstruct(w, {}, o, single, t));
    CHECK((single.components.single && !single.components.multiple));
    o.components = {false, true};
    REQUIRE(rec.reconstruct(w, {}, o, multiple, t));
    CHECK((!multiple.components.single && multiple.components.multiple));
    for (std::size_t d = 0; d < 3; ++d) {
        std::vector<float> sum(single.values[d].size());
        for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = single.values[d][i] + multiple.values[d][i];
        // Two float sums in another order and a linear float transform: ~1e-7 relative.
        CHECK(test::relative_l2(sum, both.values[d]) < 1e-6);
        bool differ = false;  // the parts are different fields
        for (std::size_t i = 0; i < sum.size(); ++i) differ |= single.values[d][i] != multiple.values[d][i];
        CHECK(differ);
    }
    o.components = {false, false};
    REQUIRE(rec.reconstruct(w, {}, o, none, t));
    CHECK((!none.components.single && !none.components.multiple));
    for (const auto& v : none.values)
        for (const float x : v) CHECK(x == 0.0f);

    // Combined (one basis per direction holding both): asking for one part gets both, flagged.
    const basis::FgbMetadata m1 = test::small_metadata(basis::Precision::Float16);
    const runtime::BakedBases b1 = runtime::BakedBases::load(write_bake("comb", m1));
    runtime::Reconstructor rec1(b1);
    runtime::RadianceField all1, one1;
    REQUIRE(rec1.reconstruct(w, {}, {}, all1, t));
    o.components = {false, true};
    REQUIRE(rec1.reconstruct(w, {}, o, one1, t));
    CHECK((one1.components.single && one1.components.multiple));
    CHECK(one1.values == all1.values);

    // Single scattering only was baked: asking for multiple alone gets zeros, flagged as nothing.
    basis::FgbMetadata ms = m1;
    ms.content = basis::FgbMetadata::kContentSingle;
    const runtime::BakedBases bs = runtime::BakedBases::load(write_bake("single", ms));
    CHECK_FALSE(bs.has_multiple());
    runtime::Reconstructor recs(bs);
    REQUIRE(recs.reconstruct(w, {}, o, one1, t));
    CHECK((!one1.components.single && !one1.components.multiple));
    for (const auto& v : one1.values)
        for (const float x : v) CHECK(x == 0.0f);
    o.components = {true, true};
    REQUIRE(recs.reconstruct(w, {}, o, one1, t));
    CHECK((one1.components.single && !one1.components.multiple));
}

TEST_CASE("reconstruct: ambient term - none by default, RMS of the dropped detail, or the paper's e_l gamma") {
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float32);
    const auto path = write_bake("ambient", m);
    const basis::BakedBasis file = basis::load_fgb(path);
    const runtime::BakedBases b = runtime::BakedBases::load(path);
    runtime::Reconstructor rec(b);
    const auto w = weights(8, {{0, 2.0}, {3, 10.0}});
    runtime::RadianceField none, rms, paper;
    runtime::StageTimes t;
    runtime::ReconstructOptions o;
    REQUIRE(rec.reconstruct(w, {}, o, none, t));
    o.ambient = runtime::Ambient::Rms;
    REQUIRE(rec.reconstruct(w, {}, o, rms, t));
    o.ambient = runtime::Ambient::Paper;
    REQUIRE(rec.reconstruct(w, {}, o, paper, t));
    const std::size_t cells = m.cells();
    for (std::size_t d = 0; d < 3; ++d) {
        double g = 0.0;
        for (const std::uint32_t l : w.active) g += w.e[l] * file.lights[l].directions[d].gamma;
        REQUIRE(g > 0.0);  // xi = 0.99 drops detail
        for (std::size_t i = 0; i < cells; ++i) {
            // The constant is added in float to a float value: one rounding of the sum.
            CHECK(double(rms.values[d][i] - none.values[d][i]) == test::rel(g / std::sqrt(double(cells)), 1e-5));
            CHECK(double(paper.values[d][i] - none.values[d][i]) == test::rel(g, 1e-5));
        }
    }
}

TEST_CASE("reconstruct: the result does not depend on the thread count") {
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16, {9, 7, 5}, 5, 2);
    const runtime::BakedBases b = runtime::BakedBases::load(write_bake("threads", m));
    const int saved = core::thread_count();
    const auto w = weights(8, {{0, 1.0}, {1, 2.0}, {2, 3.0}, {7, 4.0}});
    runtime::RadianceField one, two;
    runtime::StageTimes t;
    core::set_thread_count(1);
    runtime::Reconstructor rec1(b);
    REQUIRE(rec1.reconstruct(w, {}, {}, one, t));
    core::set_thread_count(2);
    runtime::Reconstructor rec2(b);
    runtime::ReconstructOptions always;
    always.parallel_min_work = 0;  // this tiny frame would otherwise run on one thread
    REQUIRE(rec2.reconstruct(w, {}, always, two, t));
    core::set_thread_count(saved);
    CHECK(one.values == two.values);  // bit-identical: each direction is computed the same way
}

TEST_CASE("load: stale, corrupt, truncated, partial and missing files are rejected with a message") {
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16);
    const auto path = write_bake("bad", m);
    CHECK_NOTHROW(runtime::BakedBases::load(path));
    CHECK_NOTHROW(runtime::BakedBases::load(path, m.key));

    // Stale by hash: both hashes named.
    basis::BakeKey rehashed = m.key;
    rehashed.hash ^= 1;
    char want[24], have[24];
    std::snprintf(want, sizeof want, "%016llx", static_cast<unsigned long long>(rehashed.hash));
    std::snprintf(have, sizeof have, "%016llx", static_cast<unsigned long long>(m.key.hash));
    try {
        (void)runtime::BakedBases::load(path, rehashed);
        FAIL("a stale file was accepted");
    } catch (const core::Error& e) {
        const std::string msg = e.what();
        CHECK(msg.find("stale bake") != std::string::npos);
        CHECK(msg.find(want) != std::string::npos);
        CHECK(msg.find(have) != std::string::npos);
        CHECK(msg.find(path.string()) != std::string::npos);
    }
    // Stale by key: the changed parameter named.
    const basis::BakeKey other = basis::BakeKey::from_description(
        "fulgur_bake=1\nmedium.extinction=0.005\nmedium.albedo=0.99\nmedium.g=0.6\nlighting.downsample=4\n"
        "virtual_lights.h_usr=1000\n");
    CHECK_THROWS_WITH_AS(runtime::BakedBases::load(path, other), doctest::Contains("medium.extinction"), core::Error);

    // Corrupt: one byte flipped in the last block; truncated; garbage; missing; partial.
    std::vector<char> bytes;
    {
        std::ifstream f(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(f), {});
    }
    const auto dir = path.parent_path();
    auto write = [&](const std::string& n, const std::vector<char>& v) {
        std::ofstream f(dir / n, std::ios::binary);
        f.write(v.data(), std::streamsize(v.size()));
        return dir / n;
    };
    std::vector<char> flipped = bytes;
    flipped[flipped.size() - 3] ^= 0x10;
    CHECK_THROWS_AS(runtime::BakedBases::load(write("flipped.fgb", flipped)), core::Error);
    const std::vector<char> cut(bytes.begin(), bytes.begin() + std::ptrdiff_t(bytes.size() / 2));
    CHECK_THROWS_WITH_AS(runtime::BakedBases::load(write("cut.fgb", cut)), doctest::Contains("cut.fgb"), core::Error);
    CHECK_THROWS_AS(runtime::BakedBases::load(write("garbage.fgb", std::vector<char>(100, 'x'))), core::Error);
    CHECK_THROWS_WITH_AS(runtime::BakedBases::load(dir / "missing.fgb"), doctest::Contains("missing.fgb"), core::Error);
    {
        basis::FgbWriter w(dir / "part.fgb", m, 0, 4);
        for (std::uint32_t l = 0; l < 4; ++l) w.add(test::small_light(m, l));
        w.finish();
    }
    CHECK_THROWS_WITH_AS(runtime::BakedBases::load(dir / "part.fgb"), doctest::Contains("partial"), core::Error);
}
