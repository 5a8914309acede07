// Trilinear splatting into virtual lights (Dobashi Eq. 6) and point sources along segments:
// exact energy conservation, linearity, determinism and the hard cases.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <limits>
#include <map>

using namespace fulgur;
using namespace fulgur::lightning;
using fulgur::core::Error;

namespace {

const basis::VirtualLightGrid& vgrid() {
    static const basis::VirtualLightGrid g = fixture::dobashi_grid();
    return g;
}

double sum_e(const LightWeights& w) {
    core::CompensatedSum s;
    for (const std::uint32_t l : w.active) s.add(w.e[l]);
    return s.value();
}

double sum_l(const std::vector<transport::PointSource>& q) {
    core::CompensatedSum s;
    for (const transport::PointSource& p : q) s.add(p.intensity);
    return s.value();
}

/// Independent oracle: the trilinear weights of one source by a linear scan per axis.
std::map<std::size_t, double> oracle(const basis::VirtualLightGrid& g, const transport::PointSource& q) {
    auto axis = [](const std::vector<double>& n, double v, std::size_t& i, double& f) {
        v = std::clamp(v, n.front(), n.back());
        if (n.size() == 1) return i = 0, f = 0.0, void();
        i = 0;
        while (i + 2 < n.size() && v >= n[i + 1]) ++i;
        f = (v - n[i]) / (n[i + 1] - n[i]);
    };
    std::size_t i, j, k;
    double fx, fy, fz;
    axis(g.x, q.position.x, i, fx);
    axis(g.y, q.position.y, j, fy);
    axis(g.z, q.position.z, k, fz);
    std::map<std::size_t, double> w;
    for (int c = 0; c < 8; ++c) {
        const int a = c & 1, b = (c >> 1) & 1, d = (c >> 2) & 1;
        const double wt = (a ? fx : 1 - fx) * (b ? fy : 1 - fy) * (d ? fz : 1 - fz);
        if (wt == 0.0) continue;
        const std::size_t ii = std::min(i + a, g.x.size() - 1), jj = std::min(j + b, g.y.size() - 1),
                          kk = std::min(k + d, g.z.size() - 1);
        w[g.index(ii, jj, kk)] += wt * q.intensity;
    }
    return w;
}

std::vector<transport::PointSource> random_sources(std::size_t n, std::uint64_t seed, const Box& box) {
    core::Rng r(seed, 3);
    std::vector<transport::PointSource> q(n);
    for (transport::PointSource& p : q) {
        p.position = box.lo + glm::dvec3(r.uniform(), r.uniform(), r.uniform()) * (box.hi - box.lo);
        p.intensity = 1e5 * (0.1 + r.uniform());
    }
    return q;
}

const Box kInside{glm::dvec3(-6400.0, -6400.0, 0.0), glm::dvec3(6400.0, 6400.0, 9500.0)};

}  // namespace

TEST_CASE("splat: the grid lookup agrees with the binary search and an independent oracle") {
    const Splatter sp(vgrid());
    CHECK(sp.light_count() == 33u * 33u * 24u);
    CHECK(sp.min_spacing() == 400.0);
    CHECK(sp.source_spacing() == 200.0);
    // Inside, outside and on nodes: 2000 random sources over a box larger than the grid.
    const Box wide{glm::dvec3(-9000.0, -9000.0, -2000.0), glm::dvec3(9000.0, 9000.0, 12000.0)};
    std::vector<transport::PointSource> q = random_sources(2000, 1, wide);
    q.push_back({glm::dvec3(-6400.0, 400.0, 700.0), 3.0});   // on a node
    q.push_back({glm::dvec3(6400.0, 6400.0, 9500.0), 5.0});  // the last corner
    LightWeights a, b;
    sp.splat(q, a);
    sp.reset(b);
    sp.accumulate_binary_search(q, b);
    REQUIRE(a.active == b.active);
    for (const std::uint32_t l : a.active) CHECK(fixture::same_bits(a.e[l], b.e[l]));  // same arithmetic, same bits
    std::map<std::size_t, double> ref;
    for (const transport::PointSource& p : q)
        for (const auto& [l, w] : oracle(vgrid(), p)) ref[l] += w;
    for (const auto& [l, w] : ref) CHECK(a.e[l] == test::rel(w, 1e-12));  // summation order differs
    std::size_t nonzero = 0;
    for (const auto& [l, w] : ref) nonzero += w != 0.0;
    CHECK(a.active.size() == nonzero);
}

TEST_CASE("splat: sum of e_l equals sum of L_q (exact energy conservation), in and out of the grid") {
    const Splatter sp(vgrid());
    const Box wide{glm::dvec3(-20000.0, -20000.0, -5000.0), glm::dvec3(20000.0, 20000.0, 20000.0)};
    for (const bool inside : {true, false}) {
        const std::vector<transport::PointSource> q = random_sources(10000, 7, inside ? kInside : wide);
        LightWeights w;
        sp.splat(q, w);
        const double in = sum_l(q);
        CHECK(w.total == test::rel(in, 1e-15));
        // Each source's eight weights sum to 1 up to ~3 roundings; the double accumulation of
        // 10^4 sources adds ~1e-16 relative each: 1e-12 relative is a generous bound that a
        // lost or duplicated weight (>= 1e-4 relative here) can never pass.
        CHECK(std::fabs(sum_e(w) - in) <= 1e-12 * in);
        CHECK(w.sources == q.size());
        if (inside)
            CHECK(w.clamped == 0);
        else
            CHECK(w.clamped > 5000);  // most of the wide box lies outside the grid
        for (const std::uint32_t l : w.active) CHECK(std::isfinite(w.e[l]));
        CHECK(std::is_sorted(w.active.begin(), w.active.end()));
    }
}

TEST_CASE("splat: linear - two bolts splatted together equal the sum of each splatted alone") {
    const Splatter sp(vgrid());
    const auto cloud = fixture::synthetic_storm(200.0);
    const BoltGenerator gen(BoltParams{}, cloud);
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;
    std::vector<LitSegment> la, lb;
    lit_segments(gen.generate(11), peak, la);
    lit_segments(gen.generate(12), peak, lb);
    std::vector<transport::PointSource> qa, qb, qab;
    append_point_sources(la, sp.source_spacing(), qa);
    append_point_sources(lb, sp.source_spacing(), qb);
    qab = qa;
    qab.insert(qab.end(), qb.begin(), qb.end());
    LightWeights wa, wb, wab, wacc;
    sp.splat(qa, wa);
    sp.splat(qb, wb);
    sp.splat(qab, wab);
    // accumulate() after splat() is the same computation as one splat of the union.
    sp.splat(qa, wacc);
    sp.accumulate(qb, wacc);
    double max_e = 0.0;
    for (const std::uint32_t l : wab.active) max_e = std::max(max_e, std::fabs(wab.e[l]));
    for (std::size_t l = 0; l < sp.light_count(); ++l) {
        CHECK(fixture::same_bits(wab.e[l], wacc.e[l]));
        // e(A+B) - e(A) - e(B): a few roundings of the largest weight (1e-13 relative to max).
        CHECK(std::fabs(wab.e[l] - wa.e[l] - wb.e[l]) <= 1e-13 * max_e);
    }
    CHECK(wab.active == wacc.active);
    // Scaling: intensities x 3 give e x 3 exactly (multiplication by 3 is exact in the
    // weights' last step only up to one rounding: 1e-15 relative).
    std::vector<transport::PointSource> q3 = qa;
    for (transport::PointSource& p : q3) p.intensity *= 3.0;
    LightWeights w3;
    sp.splat(q3, w3);
    for (const std::uint32_t l : wa.active) CHECK(w3.e[l] == test::rel(3.0 * wa.e[l], 1e-15));
}

TEST_CASE("splat: sources exactly on nodes and on the boundaries get exact weights") {
    const Splatter sp(vgrid());
    const auto& g = vgrid();
    LightWeights w;
    // On every kind of node: interior, faces, edges, corners.
    for (std::size_t i : {std::size_t(0), std::size_t(5), g.x.size() - 1})
        for (std::size_t j : {std::size_t(0), std::size_t(17), g.y.size() - 1})
            for (std::size_t k : {std::size_t(0), std::size_t(1), std::size_t(2), g.z.size() - 1}) {
                const transport::PointSource q{glm::dvec3(g.x[i], g.y[j], g.z[k]), 7.25};
                sp.splat(std::span(&q, 1), w);
                REQUIRE(w.active.size() == 1);  // all the weight on that node, none on neighbours
                CHECK(w.active[0] == g.index(i, j, k));
                CHECK(w.e[g.index(i, j, k)] == 7.25);  // exact
                CHECK(w.clamped == 0);
            }
    // Midway on an edge of the last cell: two lights, exactly half each.
    const transport::PointSource mid{glm::dvec3(g.x.back(), 0.5 * (g.y[3] + g.y[4]), g.z.back()), 2.0};
    sp.splat(std::span(&mid, 1), w);
    REQUIRE(w.active.size() == 2);
    CHECK(w.e[w.active[0]] == 1.0);
    CHECK(w.e[w.active[1]] == 1.0);
    // Just inside / outside the last node: nearest boundary lights, energy kept, counted.
    const transport::PointSource out{glm::dvec3(g.x.back() + 1e-9, g.y.back() + 500.0, g.z.front() - 1e6), 4.0};
    sp.splat(std::span(&out, 1), w);
    CHECK(w.clamped == 1);
    REQUIRE(w.active.size() == 1);
    CHECK(w.active[0] == g.index(g.x.size() - 1, g.y.size() - 1, 0));
    CHECK(w.e[w.active[0]] == 4.0);
}

TEST_CASE("splat: non-finite sources are rejected, zero intensity lights nothing, no NaN ever") {
    const Splatter sp(vgrid());
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const std::vector<transport::PointSource> q = {
        {glm::dvec3(nan, 0.0, 1000.0), 1.0}, {glm::dvec3(0.0, inf, 1000.0), 1.0},
        {glm::dvec3(0.0, 0.0, 1000.0), nan}, {glm::dvec3(0.0, 0.0, 1000.0), -inf},
        {glm::dvec3(0.0, 0.0, 1000.0), 0.0}, {glm::dvec3(1e300, -1e300, 1e300), 2.0}};
    LightWeights w;
    sp.splat(q, w);
    CHECK(w.rejected == 4);
    CHECK(w.sources == 2);
    CHECK(w.clamped == 1);
    CHECK(w.total == 2.0);
    REQUIRE(w.active.size() == 1);  // only the far source, on a corner light
    CHECK(w.e[w.active[0]] == 2.0);
    for (const double e : w.e) CHECK(std::isfinite(e));
    // A zero-intensity bolt: no lit stretch, no source, no light.
    const auto cloud = fixture::synthetic_storm(200.0);
    BoltParams dark;
    dark.intensity = 0.0;
    const Bolt b = BoltGenerator(dark, cloud).generate(1);
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;
    std::vector<LitSegment> lit;
    lit_segments(b, peak, lit);
    std::vector<transport::PointSource> none;
    CHECK(append_point_sources(lit, 200.0, none) == 0.0);
    CHECK(none.empty());
    sp.splat(none, w);
    CHECK(w.empty());
}

TEST_CASE("splat: reuse across frames resets sparsely and leaves no stale weight") {
    const Splatter sp(vgrid());
    LightWeights w;
    sp.splat(random_sources(500, 1, kInside), w);
    const std::size_t first = w.active.size();
    CHECK(first > 100);
    const transport::PointSource one{glm::dvec3(0.0, 0.0, 1500.0), 1.0};
    sp.splat(std::span(&one, 1), w);
    CHECK(w.active.size() == 1);
    std::size_t nonzero = 0;
    for (const double e : w.e) nonzero += e != 0.0;
    CHECK(nonzero == 1);
    // Opposite sources cancel exactly: the light drops out of the active list.
    const std::vector<transport::PointSource> pair = {{glm::dvec3(0.0, 0.0, 1500.0), 1.0},
                                                      {glm::dvec3(0.0, 0.0, 1500.0), -1.0}};
    sp.splat(pair, w);
    CHECK(w.empty());
}

TEST_CASE("splat: bolts at the grid's top and bottom layers and a bolt leaving the grid") {
    const Splatter sp(vgrid());
    const auto& g = vgrid();
    for (const double z : {g.z.front(), g.z.back()}) {
        Bolt b;
        b.segments.push_back({glm::dvec3(-3000.0, 100.0, z), glm::dvec3(2500.0, -700.0, z), 1e5, 0.0, -1, 0});
        b.main_count = 1;
        b.main_length = b.segments[0].length();
        FlashState s;
        s.main_glow = 1.0;
        std::vector<LitSegment> lit;
        lit_segments(b, s, lit);
        std::vector<transport::PointSource> q;
        const double total = append_point_sources(lit, sp.source_spacing(), q);
        LightWeights w;
        sp.splat(q, w);
        CHECK(std::fabs(sum_e(w) - total) <= 1e-12 * total);  // see the conservation test
        CHECK(w.clamped == 0);
        const std::size_t layer = z == g.z.front() ? 0 : g.z.size() - 1;
        for (const std::uint32_t l : w.active) CHECK(l / (g.x.size() * g.y.size()) == layer);  // only that layer
    }
    // A bolt that leaves the grid sideways and below: every source is kept (clamped, counted).
    Bolt b;
    b.segments.push_back({glm::dvec3(0.0, 0.0, 5000.0), glm::dvec3(9000.0, 0.0, -1000.0), 1e5, 0.0, -1, 0});
    b.main_count = 1;
    FlashState s;
    s.main_glow = 1.0;
    std::vector<LitSegment> lit;
    lit_segments(b, s, lit);
    std::vector<transport::PointSource> q;
    const double total = append_point_sources(lit, sp.source_spacing(), q);
    LightWeights w;
    sp.splat(q, w);
    CHECK(w.clamped > 0);
    CHECK(w.clamped < q.size());
    CHECK(std::fabs(sum_e(w) - total) <= 1e-12 * total);
}

TEST_CASE("splat: degenerate grids - single-layer axes work, invalid axes are rejected") {
    basis::VirtualLightGrid flat;
    flat.x = {0.0, 100.0, 300.0};
    flat.y = {0.0, 50.0};
    flat.z = {1000.0};  // one layer
    const Splatter sp(flat);
    CHECK(sp.min_spacing() == 50.0);
    const transport::PointSource q{glm::dvec3(150.0, 25.0, 5000.0), 8.0};
    LightWeights w;
    sp.splat(std::span(&q, 1), w);
    CHECK(w.clamped == 1);  // above the only layer
    CHECK(sum_e(w) == 8.0);
    // Cell x [100, 300]: fx = 0.25; fy = 0.5. Weights 0.75*0.5 and 0.25*0.5, exact in binary.
    CHECK(w.e[flat.index(1, 0, 0)] == 3.0);
    CHECK(w.e[flat.index(2, 0, 0)] == 1.0);
    CHECK(w.e[flat.index(1, 1, 0)] == 3.0);
    CHECK(w.e[flat.index(2, 1, 0)] == 1.0);
    CHECK(w.active.size() == 4);

    basis::VirtualLightGrid bad = flat;
    bad.x = {0.0, 0.0, 1.0};
    CHECK_THROWS_WITH_AS(Splatter{bad}, doctest::Contains("axis x"), Error);
    bad = flat;
    bad.y = {};
    CHECK_THROWS_WITH_AS(Splatter{bad}, doctest::Contains("axis y"), Error);
    bad = flat;
    bad.z = {std::numeric_limits<double>::quiet_NaN()};
    CHECK_THROWS_WITH_AS(Splatter{bad}, doctest::Contains("not finite"), Error);
    basis::VirtualLightGrid single;
    single.x = single.y = single.z = {0.0};
    CHECK_THROWS_AS(Splatter{single}, Error);
}

TEST_CASE("point sources: a stroke's energy does not depend on the spacing, and e_l converges") {
    const Splatter sp(vgrid());
    const auto cloud = fixture::synthetic_storm(200.0);
    const Bolt b = BoltGenerator(BoltParams{}, cloud).generate(4);
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;
    std::vector<LitSegment> lit;
    lit_segments(b, peak, lit);
    // The exact energy: sum over segments of intensity * length.
    core::CompensatedSum exact;
    for (const Segment& s : b.segments) exact.add(s.intensity * s.length());

    LightWeights fine;
    std::vector<transport::PointSource> qf;
    append_point_sources(lit, 2.0, qf);  // 2 m: a near-continuous line
    sp.splat(qf, fine);
    double fine_norm = 0.0;
    for (const double e : fine.e) fine_norm += std::fabs(e);

    double previous_err = 1e300;
    for (const double spacing : {400.0, 200.0, 50.0, 10.0}) {
        std::vector<transport::PointSource> q;
        const double total = append_point_sources(lit, spacing, q);
        // Every source spacing carries the same energy up to rounding (1e-12 relative).
        CHECK(std::fabs(total - exact.value()) <= 1e-12 * exact.value());
        CHECK(std::fabs(sum_l(q) - exact.value()) <= 1e-12 * exact.value());
        // Along each lit stretch: sources at most `spacing` apart, the ends within half of it.
        for (const LitSegment& l : lit) {
            std::vector<transport::PointSource> one;
            append_point_sources(std::span(&l, 1), spacing, one);
            REQUIRE(!one.empty());
            const double slack = 1e-9 * spacing;  // rounding of the positions
            CHECK(glm::length(one.front().position - l.a) <= 0.5 * spacing + slack);
            CHECK(glm::length(one.back().position - l.b) <= 0.5 * spacing + slack);
            for (std::size_t i = 1; i < one.size(); ++i)
                CHECK(glm::length(one[i].position - one[i - 1].position) <= spacing + slack);
        }
        LightWeights w;
        sp.splat(q, w);
        double err = 0.0;
        for (std::size_t l = 0; l < w.e.size(); ++l) err += std::fabs(w.e[l] - fine.e[l]);
        err /= fine_norm;
        INFO("spacing " << spacing << ": relative L1 difference of e_l to the 2 m reference " << err);
        CHECK(err < previous_err);  // converges as the spacing shrinks
        // Half the light spacing (the default, 200 m) is within 5% of the continuous line:
        // measured ~1%; trilinear weights are linear inside a cell, so the residual comes from
        // pieces straddling cell faces.
        if (spacing == 200.0) CHECK(err < 0.05);
        previous_err = err;
    }
}

TEST_CASE("point sources and splat: same bolt and time give bit-identical e_l") {
    const auto cloud = fixture::synthetic_storm(200.0);
    LightningParams p;
    p.schedule.strike_rate = 0.0;
    const Splatter sp(vgrid());
    std::vector<double> first;
    for (int run = 0; run < 2; ++run) {
        Storm storm(p, cloud);
        storm.strike_at(1.0, 99);
        const double t = 1.0 + storm.strike(0).profile.leader_duration + 0.002;
        std::vector<transport::PointSource> q;
        REQUIRE(storm.point_sources(t, sp.source_spacing(), q));
        LightWeights w;
        sp.splat(q, w);
        if (run == 0)
            first = w.e;
        else
            for (std::size_t l = 0; l < w.e.size(); ++l) CHECK(fixture::same_bits(first[l], w.e[l]));
    }
}

TEST_CASE("splat: 10,000 point sources") {
    const Splatter sp(vgrid());
    const std::vector<transport::PointSource> q = random_sources(10000, 5, kInside);
    LightWeights w;
    sp.splat(q, w);
    CHECK(w.sources == 10000);
    CHECK(std::fabs(sum_e(w) - sum_l(q)) <= 1e-12 * sum_l(q));  // see the conservation test
    CHECK(w.active.size() > 5000);                              // spread over the grid: thousands of lights lit
}
