// The run time on real bakes of the tiny test scenes (tests/apps/scenes: 32x32x16 density,
// 8x8x4 lighting grid, virtual lights 4 km apart; each bakes in about a second):
// determinism, linearity, components, a source on a virtual light, the run time's hard cases
// (a bolt leaving the grid, sources on nodes and boundaries, zero intensity, 10,000 sources,
// bolts on the top and bottom light layers), dark frames, and the accuracy of the basis
// method against the direct solve.
// Exact splat energy conservation (sum e_l == sum L_q) is tested where the splat lives:
// tests/lightning/test_splat.cpp, "splat: sum of e_l equals sum of L_q ...".
#include "runtime/runtime.h"

#include "bake/bake.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <memory>

using namespace fulgur;

namespace {

struct Baked {
    scene::Scene scene;
    core::Grid3<float> density;
    solve::Media media;
    const transport::LightingMedium& medium() const { return media.lighting; }
    std::filesystem::path fgb;
    basis::BakedBasis file;
    std::unique_ptr<runtime::BakedBases> bases;
};

// Each scene baked once per test run into the build tree.
const Baked& baked(const std::string& name) {
    static std::map<std::string, std::unique_ptr<Baked>> cache;
    auto& slot = cache[name];
    if (!slot) {
        auto b = std::make_unique<Baked>();
        b->scene = scene::load_scene(test::source_dir() / "tests/apps/scenes" / (name + ".json"));
        b->density = scene::make_density(b->scene);
        b->media = solve::make_media(b->scene, b->density);
        b->fgb = test::scratch_dir("runtime_" + name) / (name + ".fgb");
        bake::bake(b->scene, b->density, b->fgb);
        b->file = basis::load_fgb(b->fgb);
        b->bases = std::make_unique<runtime::BakedBases>(
            runtime::BakedBases::load(b->fgb, bake::scene_key(b->scene, b->density)));
        slot = std::move(b);
    }
    return *slot;
}

bool all_finite(const runtime::RadianceField& r) {
    for (const auto& v : r.values)
        for (const float x : v)
            if (!std::isfinite(x)) return false;
    return true;
}

// Largest relative L2 error over the reconstructed directions against the double reference
// (basis::reconstruct: double sums, double inverse transform, all stored components).
double vs_reference(const Baked& b, const lightning::LightWeights& w, const runtime::RadianceField& r) {
    std::vector<basis::WeightedLight> wl;
    for (const std::uint32_t l : w.active) wl.push_back({l, w.e[l]});
    double worst = 0.0;
    for (std::size_t i = 0; i < r.directions.size(); ++i) {
        const core::Grid3<float> ref = basis::reconstruct(b.file, wl, std::size_t(r.directions[i]));
        worst = std::max(worst, test::relative_l2(r.values[i], ref.data));
    }
    return worst;
}

// Float32 accumulation + float32 inverse Haar against the double reference: each H
// coefficient is a float sum of (active lights) x (components) terms, each a float product;
// the inverse adds ~2 roundings per level (8x8x4: 3 levels). Measured: ~1e-7 to 5e-7.
// 5e-6 is ~10x that, and 100x below the bake's 1% compression error, so it cannot hide a
// missing or wrong basis.
constexpr double kFloatTol = 5e-6;

std::vector<transport::PointSource> line(const glm::dvec3& a, const glm::dvec3& b, int n, double intensity) {
    std::vector<transport::PointSource> q;
    for (int i = 0; i < n; ++i) q.push_back({a + (b - a) * (double(i) / double(std::max(1, n - 1))), intensity});
    return q;
}

// The frame at the first return stroke + 2 ms of a strike at t = 0 with `seed`.
double peak_time(runtime::FramePipeline& p, std::uint64_t seed) {
    const std::size_t i = p.strike_at(0.0, seed);
    const lightning::Strike& s = p.storm().strike(i);
    return s.profile.stroke_onset.at(0) + 0.002;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

}  // namespace

TEST_CASE("frame: same seed and time give bit-identical segments, sources, weights and field") {
    const Baked& b = baked("test_aniso_ms_cg");
    runtime::FramePipeline p1(b.scene, b.density, *b.bases), p2(b.scene, b.density, *b.bases);
    const double t = peak_time(p1, 11);
    REQUIRE(peak_time(p2, 11) == t);
    const runtime::Frame& f1 = p1.build(t, {});
    const runtime::Frame& f2 = p2.build(t, {});
    REQUIRE(f1.lit);
    REQUIRE(f2.lit);
    REQUIRE(f1.sources.size() == f2.sources.size());
    REQUIRE(!f1.sources.empty());
    CHECK(std::memcmp(f1.sources.data(), f2.sources.data(), f1.sources.size() * sizeof(transport::PointSource)) == 0);
    CHECK(same_bits(f1.weights.e, f2.weights.e));
    CHECK(f1.weights.active == f2.weights.active);
    CHECK(f1.radiance.values == f2.radiance.values);
    CHECK(f1.radiance.directions.size() == 26);  // empty request: all directions

    // The pipeline's sources are the storm's point_sources at the splatter's spacing, bit for bit.
    lightning::Storm storm(b.scene.lightning, b.density);
    storm.strike_at(0.0, 11);
    std::vector<transport::PointSource> q;
    REQUIRE(storm.point_sources(t, lightning::Splatter(b.bases->lights()).source_spacing(), q));
    REQUIRE(q.size() == f1.sources.size());
    CHECK(std::memcmp(q.data(), f1.sources.data(), q.size() * sizeof(transport::PointSource)) == 0);

    // A subset of directions gives exactly those directions of the full field.
    const std::vector<int> some = {25, 3, 0};
    const std::vector<std::vector<float>> all = f1.radiance.values;
    const runtime::Frame& f3 = p1.build(t, some);
    REQUIRE(f3.radiance.values.size() == 3);
    for (std::size_t i = 0; i < some.size(); ++i) CHECK(f3.radiance.values[i] == all[std::size_t(some[i])]);
    CHECK(vs_reference(b, f3.weights, f3.radiance) < kFloatTol);
}

TEST_CASE("reconstruct: linear - two bolts together equal the sum of each alone") {
    const Baked& b = baked("test_aniso_ms_cg");
    runtime::FramePipeline p(b.scene, b.density, *b.bases);
    // Two bolts at their peaks, taken as two source sets.
    const double ta = peak_time(p, 21);
    const std::vector<transport::PointSource> a = p.build(ta, std::vector<int>{0}).sources;
    runtime::FramePipeline p2(b.scene, b.density, *b.bases);
    const double tb = peak_time(p2, 22);
    const std::vector<transport::PointSource> c = p2.build(tb, std::vector<int>{0}).sources;
    REQUIRE(!a.empty());
    REQUIRE(!c.empty());
    std::vector<transport::PointSource> ac = a;
    ac.insert(ac.end(), c.begin(), c.end());

    const lightning::Splatter sp(b.bases->lights());
    runtime::Reconstructor rec(*b.bases);
    lightning::LightWeights wa, wc, wac;
    sp.splat(a, wa);
    sp.splat(c, wc);
    sp.splat(ac, wac);
    runtime::RadianceField ra, rc, rac;
    runtime::StageTimes t;
    REQUIRE(rec.reconstruct(wa, {}, {}, ra, t));
    REQUIRE(rec.reconstruct(wc, {}, {}, rc, t));
    REQUIRE(rec.reconstruct(wac, {}, {}, rac, t));
    double worst = 0.0;
    for (std::size_t d = 0; d < 26; ++d) {
        std::vector<float> sum(ra.values[d].size());
        for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = ra.values[d][i] + rc.values[d][i];
        worst = std::max(worst, test::relative_l2(sum, rac.values[d]));
    }
    MESSAGE("linearity: worst relative L2 difference over 26 directions " << worst);
    // Three float reconstructions, each within kFloatTol of its exact value.
    CHECK(worst < 3 * kFloatTol);
}

TEST_CASE("reconstruct: components of a real bake - single only + multiple only = both") {
    const Baked& b = baked("test_aniso_ms_cg");
    REQUIRE(b.bases->separate());
    runtime::FramePipeline p(b.scene, b.density, *b.bases);
    const double t = peak_time(p, 5);
    runtime::ReconstructOptions o;
    const std::vector<std::vector<float>> both = p.build(t, {}, o).radiance.values;
    o.components = {true, false};
    const std::vector<std::vector<float>> single = p.build(t, {}, o).radiance.values;
    o.components = {false, true};
    const std::vector<std::vector<float>> multiple = p.build(t, {}, o).radiance.values;
    double share = 0.0, total = 0.0;
    for (std::size_t d = 0; d < 26; ++d) {
        std::vector<float> sum(both[d].size());
        for (std::size_t i = 0; i < sum.size(); ++i) {
            sum[i] = single[d][i] + multiple[d][i];
            share += double(multiple[d][i]);
            total += double(both[d][i]);
        }
        // Same float operations in another grouping: a few float roundings.
        CHECK(test::relative_l2(sum, both[d]) < kFloatTol);
    }
    MESSAGE("multiple scattering carries " << share / total << " of S");
    CHECK(share > 0.0);  // the multiple part is really there (and not the single one twice)
    CHECK(share < total);
}

TEST_CASE("reconstruct: a point source exactly on a virtual light reproduces that light's basis") {
    const Baked& b = baked("test_aniso_ms_cg");
    const basis::VirtualLightGrid& g = b.bases->lights();
    const lightning::Splatter sp(g);
    runtime::Reconstructor rec(*b.bases);
    // An interior light inside the cloud layers, one on the grid's corner, one on the ground layer.
    const std::size_t mid_k = std::min(g.base_layer + 1, g.z.size() - 1);
    for (const std::size_t l : {g.index(g.x.size() / 2, g.y.size() / 2, mid_k), std::size_t(0), g.index(1, 0, 0)}) {
        CAPTURE(l);
        const double intensity = 3.0e6;
        const std::vector<transport::PointSource> q = {{g.position(l), intensity}};
        lightning::LightWeights w;
        sp.splat(q, w);
        REQUIRE(w.active == std::vector<std::uint32_t>{std::uint32_t(l)});
        CHECK(w.e[l] == intensity);  // all eight weights but one are exactly 0 on a node
        runtime::RadianceField r;
        runtime::StageTimes t;
        REQUIRE(rec.reconstruct(w, {}, {}, r, t));
        const std::vector<basis::WeightedLight> wl = {{std::uint32_t(l), intensity}};
        for (std::size_t d = 0; d < 26; ++d) {
            const core::Grid3<float> ref = basis::reconstruct(b.file, wl, d);
            CHECK(test::relative_l2(r.values[d], ref.data) < kFloatTol);
        }
    }
}

TEST_CASE("hard cases: a bolt leaving the grid, sources on nodes and boundaries, top and bottom layers") {
    const Baked& b = baked("test_aniso_ms_cg");
    const basis::VirtualLightGrid& g = b.bases->lights();
    const lightning::Splatter sp(g);
    runtime::Reconstructor rec(*b.bases);
    runtime::RadianceField r;
    runtime::StageTimes t;
    const glm::dvec3 lo(g.x.front(), g.y.front(), g.z.front()), hi(g.x.back(), g.y.back(), g.z.back());
    const glm::dvec3 mid = 0.5 * (lo + hi);

    SUBCASE("a bolt leaving the grid: clamped onto the boundary lights, counted, still exact") {
        const auto q = line(mid, mid + glm::dvec3(3.0 * (hi.x - lo.x), 0.5 * (hi.y - lo.y), 0.0), 200, 1e5);
        lightning::LightWeights w;
        sp.splat(q, w);
        CHECK(w.clamped > 100);  // 5/6 of the line lies beyond x = hi.x
        CHECK(w.clamped < 200);
        REQUIRE(rec.reconstruct(w, {}, {}, r, t));
        CHECK(all_finite(r));
        CHECK(vs_reference(b, w, r) < kFloatTol);
    }
    SUBCASE("sources exactly on lighting-grid voxel corners and centres, and on the virtual-light grid's faces") {
        const core::GridGeometry& lg = b.bases->lighting();
        std::vector<transport::PointSource> q;
        for (int k = 0; k <= lg.dims.z; ++k)
            for (int i = 0; i <= lg.dims.x; i += 2) {
                q.push_back({lg.origin + glm::dvec3(i, lg.dims.y / 2, k) * lg.voxel_size, 1e4});  // corners
                if (i < lg.dims.x && k < lg.dims.z) q.push_back({lg.centre(i, 1, k), 1e4});       // centres
            }
        for (const double x : {lo.x, hi.x})
            for (const double z : {lo.z, mid.z, hi.z}) q.push_back({{x, mid.y, z}, 2e4});  // faces, edges
        q.push_back({lo, 5e4});  // corners of the virtual-light box
        q.push_back({hi, 5e4});
        lightning::LightWeights w;
        sp.splat(q, w);
        REQUIRE(rec.reconstruct(w, {}, {}, r, t));
        CHECK(all_finite(r));
        CHECK(vs_reference(b, w, r) < kFloatTol);
    }
    SUBCASE("bolts along the bottom (ground) and top layers of virtual lights light only that layer") {
        for (const std::size_t k : {std::size_t(0), g.z.size() - 1}) {
            CAPTURE(k);
            const auto q = line({lo.x, lo.y, g.z[k]}, {hi.x, hi.y, g.z[k]}, 300, 1e5);
            lightning::LightWeights w;
            sp.splat(q, w);
            CHECK(w.clamped == 0);  // on the boundary is inside
            for (const std::uint32_t l : w.active) CHECK(l / (g.x.size() * g.y.size()) == k);
            REQUIRE(rec.reconstruct(w, {}, {}, r, t));
            CHECK(all_finite(r));
            CHECK(vs_reference(b, w, r) < kFloatTol);
        }
    }
    SUBCASE("10,000 point sources, a tenth of them outside the grid") {
        core::Rng rng(99, 3);
        std::vector<transport::PointSource> q;
        const glm::dvec3 ext = hi - lo;
        for (int i = 0; i < 10000; ++i) {
            const double s = i % 10 == 0 ? 1.6 : 1.0;  // every tenth in a box 60% larger
            const glm::dvec3 u(rng.uniform(), rng.uniform(), rng.uniform());
            q.push_back({mid + (u - 0.5) * ext * s, 10.0 + 1e3 * rng.uniform()});
        }
        lightning::LightWeights w;
        sp.splat(q, w);
        CHECK(w.sources == 10000);
        CHECK(w.clamped > 0);
        CHECK(w.active.size() == g.count());  // dense enough to light every virtual light
        REQUIRE(rec.reconstruct(w, {}, {}, r, t));
        CHECK(all_finite(r));
        const double err = vs_reference(b, w, r);
        MESSAGE("10,000 sources: float vs double reconstruction, worst relative L2 " << err);
        CHECK(err < kFloatTol);  // all lights active: the longest float sums of any frame
    }
}

TEST_CASE("frame: zero intensity and dark frames compute nothing and keep the last field's buffers") {
    const Baked& b = baked("test_aniso_ms_cg");
    runtime::FramePipeline p(b.scene, b.density, *b.bases);
    const double t = peak_time(p, 8);
    // Dark: before the strike (the test scenes schedule no strikes: strike_rate 0).
    const runtime::Frame& dark0 = p.build(-1.0, {});
    CHECK_FALSE(dark0.lit);
    CHECK(dark0.segments.empty());
    CHECK(dark0.sources.empty());
    CHECK(dark0.weights.active.empty());
    CHECK(dark0.times.sources == 0.0);
    CHECK(dark0.times.splat == 0.0);
    CHECK(dark0.times.accumulate == 0.0);
    CHECK(dark0.times.inverse_haar == 0.0);
    CHECK(dark0.radiance.values.empty());  // never reconstructed

    const runtime::Frame& lit = p.build(t, {});
    REQUIRE(lit.lit);
    const float* buffer = lit.radiance.values.front().data();
    const std::vector<std::vector<float>> before = lit.radiance.values;
    // Dark after the flash: the weights are cleared, the radiance buffers are left alone.
    const runtime::Frame& dark1 = p.build(100.0, {});
    CHECK_FALSE(dark1.lit);
    CHECK(dark1.weights.active.empty());
    for (const double e : dark1.weights.e) CHECK(e == 0.0);
    CHECK(dark1.times.accumulate == 0.0);
    CHECK(dark1.times.inverse_haar == 0.0);
    CHECK(dark1.radiance.values.front().data() == buffer);
    CHECK(dark1.radiance.values == before);

    // Zero intensity: the bolt exists and is "lit", but carries no light: nothing to reconstruct.
    scene::Scene s0 = b.scene;
    s0.lightning.bolt.intensity = 0.0;
    runtime::FramePipeline p0(s0, b.density, *b.bases);
    const double t0 = peak_time(p0, 8);
    const runtime::Frame& z = p0.build(t0, {});
    CHECK_FALSE(z.lit);
    CHECK(z.weights.active.empty());
    CHECK(z.times.accumulate == 0.0);
    CHECK(z.times.inverse_haar == 0.0);
    CHECK(z.radiance.values.empty());
}

TEST_CASE("frame: a single-scattering, isotropic bake (1 direction) reconstructs and matches the reference") {
    const Baked& b = baked("test_iso_ss_ic");
    CHECK_FALSE(b.bases->has_multiple());
    CHECK(b.bases->directions().size() == 1);
    runtime::FramePipeline p(b.scene, b.density, *b.bases);
    const double t = peak_time(p, 3);
    const runtime::Frame& f = p.build(t, {});
    REQUIRE(f.lit);
    REQUIRE(f.radiance.values.size() == 1);
    CHECK(vs_reference(b, f.weights, f.radiance) < kFloatTol);
    // Multiple scattering alone was not baked: zeros, flagged as holding nothing.
    runtime::ReconstructOptions o;
    o.components = {false, true};
    const runtime::Frame& m = p.build(t, {}, o);
    REQUIRE(m.lit);
    CHECK_FALSE(m.radiance.components.single);
    CHECK_FALSE(m.radiance.components.multiple);
    for (const float x : m.radiance.values[0]) CHECK(x == 0.0f);
}

TEST_CASE("accuracy: basis method against the direct solve on a tiny scene") {
    // R: the frame's reconstruction (splat onto virtual lights + compressed bases, xi = 0.9999,
    // float16). D: the direct solve of the frame's point sources (solve::solve, no virtual
    // lights). V: the direct solve of the active virtual lights with their weights e_l, i.e.
    // what R would be with uncompressed bases and a perfectly linear solver. R - V is the
    // basis machinery's own error; V - D the error of replacing each source by the 8 virtual
    // lights around it (paper Eq. 6), a property of the virtual-light spacing.
    const Baked& b = baked("test_aniso_ms_cg");
    auto cloud_l2 = [&](auto value) {
        double s = 0.0;
        for (std::size_t m = 0; m < 26; ++m)
            for (std::size_t i = 0; i < b.medium().density.size(); ++i)
                if (b.medium().density.data[i] > 0.0f) s += value(m, i) * value(m, i);  // cloud voxels only
        return std::sqrt(s);
    };
    for (const std::uint64_t seed : {31u, 32u}) {
        CAPTURE(seed);
        runtime::FramePipeline p(b.scene, b.density, *b.bases);
        const double t = peak_time(p, seed);
        const runtime::Frame& f = p.build(t, {});
        REQUIRE(f.lit);
        const transport::SourceField D = runtime::direct_solve(b.scene, b.media, f.sources);
        REQUIRE(D.directions.size() == 26);
        std::vector<transport::PointSource> lights;
        for (const std::uint32_t l : f.weights.active)
            lights.push_back({b.bases->lights().position(l), f.weights.e[l]});
        const transport::SourceField V = runtime::direct_solve(b.scene, b.media, lights);
        const double nD = cloud_l2([&](std::size_t m, std::size_t i) { return double(D.direction(m)[i]); });
        const double nV = cloud_l2([&](std::size_t m, std::size_t i) { return double(V.direction(m)[i]); });
        const double eRD = cloud_l2([&](std::size_t m, std::size_t i) {
                               return double(f.radiance.values[m][i]) - double(D.direction(m)[i]);
                           }) /
                           nD;
        const double eRV = cloud_l2([&](std::size_t m, std::size_t i) {
                               return double(f.radiance.values[m][i]) - double(V.direction(m)[i]);
                           }) /
                           nV;
        const double eVD = cloud_l2([&](std::size_t m, std::size_t i) {
                               return double(V.direction(m)[i]) - double(D.direction(m)[i]);
                           }) /
                           nD;
        MESSAGE("seed " << seed << ": " << f.sources.size() << " sources, " << f.weights.active.size()
                        << " active lights; relative L2 over cloud voxels: basis vs direct " << eRD
                        << ", basis vs virtual lights solved directly " << eRV << ", virtual lights vs sources "
                        << eVD);
        // The basis machinery: measured 0.3%. The bake keeps 99.99% of each basis' energy (<= 1%
        // relative L2 per basis, float16 values) and the lattice-Boltzmann solve of a sum of
        // sources differs from the sum of solves by ~0.1% (fluence renormalization): 1.5% bounds
        // both with margin, and a wrong basis, direction or component breaks it by far.
        CHECK(eRV < 0.015);
        // The whole method on this deliberately coarse scene (virtual lights 4 km apart, 2 km
        // lighting voxels, bolts ~1 km from the nearest light): measured 0.94, all of it from
        // the splat (eVD); S there is dominated by the single scattering in the voxels next to
        // the channel, which no 4 km light grid can place. The splat's error itself is bounded
        // against the truth, per part, in test_truth and test_truth_storm (the paper preset);
        // here: it is the whole difference (same bound as eRV).
        CHECK(std::fabs(eRD - eVD) < 0.015);
    }
}
