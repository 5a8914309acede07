// ProgressiveMonteCarlo's contract (also under the sanitizers): one result for any thread
// count, order 1 left out without changing the other paths, no light, restart, bad input named.
#include "support/test_support.h"
#include "transport/transport.h"
#include "transport_test_util.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <vector>

using namespace fulgur;
using namespace fulgur::transport;

namespace {

const Medium kOptics{0.01, 0.95, 0.6};  // 1/m; a 100 m voxel holds 1 mean free path at rho 1

}  // namespace

TEST_CASE("progressive Monte Carlo: one result for any thread count; order 1 left out; no light; bad input") {
    const LightingMedium m = test::uniform_medium({9, 9, 9}, 100.0, glm::dvec3(0.0), 0.5f, kOptics);
    const LineSource line{{150.0, 450.0, 100.0}, {450.0, 450.0, 800.0}, 0.02, 0};
    const std::vector<glm::dvec3> dirs = output_directions(6);
    const MonteCarloMedium tracing(m, m.density.geom);
    const auto run = [&](int threads, const MonteCarloOptions& o) {
        const core::ScopedThreadCount share(threads);
        ProgressiveMonteCarlo p(tracing, {}, std::span(&line, 1), dirs, o);
        p.advance(3'000);
        p.advance(5'000);
        return p.result();
    };
    const MonteCarloOptions o;
    const MonteCarloResult one = run(1, o), two = run(2, o);
    CHECK(one.single.data == two.single.data);
    CHECK(one.multiple.data == two.multiple.data);
    CHECK(one.noise.total == two.noise.total);
    // Without order 1 the paths draw the same random numbers (its expected-value deposit uses
    // none): the same multiple scattering, bit for bit, and no single field at all (in groups
    // too); likewise no multiple field without orders >= 2.
    MonteCarloOptions no_single = o;
    no_single.tally_single = false;
    const MonteCarloResult ms = run(2, no_single);
    CHECK(ms.multiple.data == one.multiple.data);
    CHECK(ms.single.data.empty());
    CHECK(ms.noise.total == ms.noise.multiple);
    {
        MonteCarloOptions grouped = no_single, no_multiple = o;
        grouped.groups = 2;
        const MonteCarloResult g = run(2, grouped);
        REQUIRE(g.groups.size() == 2);
        CHECK(g.single.data.empty());
        for (const auto& part : g.groups) CHECK(part.single.data.empty());
        REQUIRE(g.multiple.data.size() == g.groups[0].multiple.data.size());
        for (std::size_t i = 0; i < g.multiple.data.size(); ++i)
            REQUIRE(g.multiple.data[i] == g.groups[0].multiple.data[i] + g.groups[1].multiple.data[i]);
        no_multiple.tally_multiple = false;
        no_multiple.groups = 2;
        const MonteCarloResult n = run(2, no_multiple);
        CHECK(n.multiple.data.empty());
        for (const auto& part : n.groups) CHECK(part.multiple.data.empty());
        CHECK_FALSE(n.single.data.empty());
    }
    no_single.tally_multiple = false;
    CHECK_THROWS_WITH_AS(ProgressiveMonteCarlo(tracing, {}, std::span(&line, 1), dirs, no_single),
                         doctest::Contains("tally_single"), core::Error);
    // restart(): the same sources and seed give the same result as a fresh run, whatever came
    // before (the memory is reused, nothing of the previous run stays).
    {
        const core::ScopedThreadCount share(2);
        ProgressiveMonteCarlo p(tracing, {}, std::span(&line, 1), dirs, o);
        const LineSource other{{100.0, 100.0, 100.0}, {800.0, 800.0, 800.0}, 0.05, 0};
        p.restart({}, std::span(&other, 1), 99);
        p.advance(4'000);
        p.restart({}, std::span(&line, 1), o.seed);
        CHECK(p.paths() == 0);
        p.advance(3'000);
        p.advance(5'000);
        const MonteCarloResult again = p.result();
        CHECK(again.single.data == two.single.data);
        CHECK(again.multiple.data == two.multiple.data);
        LineSource bad = line;
        bad.intensity = -1.0;
        CHECK_THROWS_WITH_AS(p.restart({}, std::span(&bad, 1), 1), doctest::Contains("lines[0].intensity"),
                             core::Error);
    }
    // noise_cells: the noise measured over the cells it marks, the tallies unchanged. Over
    // every cell it is the default's exactly (the uniform medium's cells all hold density);
    // over the bottom half alone, another figure; a mask of the wrong size is named.
    {
        MonteCarloOptions all = o, half = o;
        const std::vector<std::uint8_t> every(tracing.cloud().size(), 1);
        std::vector<std::uint8_t> bottom(tracing.cloud().size(), 0);
        for (std::size_t c = 0; c < bottom.size() / 2; ++c) bottom[c] = 1;
        all.noise_cells = &every;
        half.noise_cells = &bottom;
        const MonteCarloResult ra = run(2, all), rh = run(2, half);
        CHECK(ra.single.data == two.single.data);
        CHECK(rh.multiple.data == two.multiple.data);
        CHECK(ra.noise.total == two.noise.total);
        CHECK(rh.noise.total != two.noise.total);
        CHECK(rh.noise.total > 0.0);
        std::vector<std::uint8_t> wrong(bottom.size() + 1, 1);
        half.noise_cells = &wrong;
        CHECK_THROWS_WITH_AS(ProgressiveMonteCarlo(tracing, {}, std::span(&line, 1), dirs, half),
                             doctest::Contains("noise_cells"), core::Error);
    }
    // No light: zero after tracing, no noise.
    const LineSource dark{line.a, line.b, 0.0, 0};
    ProgressiveMonteCarlo d(tracing, {}, std::span(&dark, 1), dirs, o);
    d.advance(100);
    for (const float v : d.result().single.data) REQUIRE(v == 0.0f);
    CHECK(d.result().noise.total == 0.0);
    // Bad input names its field.
    core::GridGeometry shifted = m.density.geom;
    shifted.origin.x += 1.0;
    CHECK_THROWS_WITH_AS(MonteCarloMedium(m, shifted), doctest::Contains("tally_grid"), core::Error);
    CHECK_THROWS_WITH_AS(MonteCarloMedium(m, m.density.geom, -1), doctest::Contains("macro_cell"), core::Error);
    LineSource bad_group = line;
    bad_group.group = 3;
    CHECK_THROWS_WITH_AS(ProgressiveMonteCarlo(tracing, {}, std::span(&bad_group, 1), dirs, o),
                         doctest::Contains("lines[0].group"), core::Error);
    LineSource nan_line = line;
    nan_line.a.z = std::nan("");
    CHECK_THROWS_WITH_AS(ProgressiveMonteCarlo(tracing, {}, std::span(&nan_line, 1), dirs, o),
                         doctest::Contains("lines[0]"), core::Error);
}
