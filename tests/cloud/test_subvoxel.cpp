// Sub-voxel detail: the billow tile (periodic, deterministic, full range), the erosion
// (only removes density, identity at strength 0) and the voxel means the solvers integrate.
#include "cloud/subvoxel.h"
#include "core/parallel.h"

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>

using namespace fulgur;
using cloud::DetailNoise;
using cloud::SubvoxelDetail;

namespace {

SubvoxelDetail params(std::uint64_t seed = 3, int octaves = 3, double strength = 0.6) {
    SubvoxelDetail d;
    d.seed = seed;
    d.scale = 300.0;
    d.octaves = octaves;
    d.strength = strength;
    return d;
}

// A 12^3 puff of 100 m voxels: a dense core (rho = 1) with a soft edge, the shape the
// erosion acts on (thin edges eroded, the core kept).
core::Grid3<float> puff() {
    core::GridGeometry g{{12, 12, 12}, 100.0, glm::dvec3(-600.0, -600.0, 1000.0)};
    core::Grid3<float> d(g, 0.0f);
    const glm::dvec3 c = g.origin + 0.5 * g.extent();
    for (int k = 0; k < 12; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 12; ++i) {
                const double r = glm::length(g.centre(i, j, k) - c) / 550.0;
                d.at(i, j, k) = float(std::clamp(2.5 * (1.0 - r), 0.0, 1.0));
            }
    return d;
}

}  // namespace

TEST_CASE("the billow tile is deterministic per seed, spans [0, 1] and is periodic") {
    const DetailNoise a(params(3)), b(params(3)), c(params(4));
    CHECK(a.texels() == b.texels());
    CHECK(a.texels() != c.texels());
    REQUIRE(a.texels().size() == std::size_t(cloud::kDetailTile) * cloud::kDetailTile * cloud::kDetailTile);
    const auto [lo, hi] = std::minmax_element(a.texels().begin(), a.texels().end());
    CHECK(*lo == 0);
    CHECK(*hi == 255);
    CHECK(a.period() == doctest::Approx(600.0));
    // One period away in any direction, and at negative coordinates, the same value: the
    // march samples the same tile with repeat wrapping everywhere in the cloud.
    for (const glm::dvec3 p : {glm::dvec3(13.7, 251.2, -80.4), glm::dvec3(-1234.5, 77.7, 4321.0)}) {
        const float v = a.sample(p);
        CHECK(v >= 0.0f);
        CHECK(v <= 1.0f);
        // 1e-4: float interpolation weights of positions a few periods apart differ in the
        // last bits (the texels are bytes: 1/255 apart).
        CHECK(std::abs(a.sample(p + glm::dvec3(600.0, 0.0, 0.0)) - v) < 1e-4f);
        CHECK(std::abs(a.sample(p + glm::dvec3(0.0, -1200.0, 600.0)) - v) < 1e-4f);
    }
    // At a texel centre the sample is the texel.
    const double texel = a.period() / cloud::kDetailTile;
    const glm::dvec3 centre = (glm::dvec3(5, 9, 17) + 0.5) * texel;
    const std::size_t idx = 5 + std::size_t(cloud::kDetailTile) * (9 + std::size_t(cloud::kDetailTile) * 17);
    CHECK(std::abs(a.sample(centre) - float(a.texels()[idx]) / 255.0f) < 1e-6f);
}

TEST_CASE("more octaves add finer billows: more of the tile's variance is at the finest scales") {
    // Share of the variance that a periodic 5-texel box average (along x) removes: the
    // structure finer than the finest octave's 4-texel cells of the 4-octave tile.
    auto fine_share = [](const DetailNoise& noise) {
        constexpr int n = cloud::kDetailTile;
        const auto& t = noise.texels();
        double mean = 0.0;
        for (std::uint8_t v : t) mean += v;
        mean /= double(t.size());
        double var = 0.0, fine = 0.0;
        for (std::size_t row = 0; row < t.size(); row += n)
            for (int i = 0; i < n; ++i) {
                double box = 0.0;
                for (int o = -2; o <= 2; ++o) box += t[row + std::size_t((i + o + n) % n)];
                const double v = t[row + std::size_t(i)];
                var += (v - mean) * (v - mean);
                fine += (v - box / 5.0) * (v - box / 5.0);
            }
        return fine / var;
    };
    const double one = fine_share(DetailNoise(params(3, 1))), four = fine_share(DetailNoise(params(3, 4)));
    MESSAGE("fine-scale variance share: 1 octave ", one, ", 4 octaves ", four);
    // Measured 0.0011 and 0.0094 (8.4x); 4x leaves room for other seeds.
    CHECK(four > 4.0 * one);
}

TEST_CASE("erosion only removes density; strength 0 and the billows' centres keep it") {
    for (float rho : {0.0f, 0.05f, 0.3f, 0.7f, 1.0f})
        for (float b : {0.0f, 0.25f, 0.5f, 1.0f})
            for (float s : {0.0f, 0.5f, 1.0f}) {
                CAPTURE(rho);
                CAPTURE(b);
                CAPTURE(s);
                const float e = cloud::erode(rho, b, s);
                CHECK(std::isfinite(e));
                CHECK(e >= 0.0f);
                CHECK(e <= rho + 1e-7f);
                if (s == 0.0f || b == 1.0f) CHECK(e == rho);
                if (rho == 1.0f && s * (1.0f - b) < 1.0f) CHECK(e == doctest::Approx(1.0f));
                // Monotone in rho: a denser point never ends up thinner.
                CHECK(cloud::erode(std::min(rho + 0.1f, 1.0f), b, s) >= e);
            }
    // Strength 1 empties the gaps between billows entirely, whatever the density.
    CHECK(cloud::erode(1.0f, 0.0f, 1.0f) == 0.0f);
}

TEST_CASE("the solvers' density: voxel means of the eroded field, exactly the input at strength 0") {
    const core::Grid3<float> d = puff();
    const core::Grid3<float> same = cloud::detailed_density(d, DetailNoise(params(3, 3, 0.0)));
    CHECK(same.data == d.data);  // bit for bit: a detail of strength 0 changes nothing

    const DetailNoise noise(params(3, 3, 0.6));
    const core::Grid3<float> e = cloud::detailed_density(d, noise);
    double mass = 0.0, mass_e = 0.0;
    for (std::size_t i = 0; i < d.data.size(); ++i) {
        CHECK(e.data[i] <= d.data[i]);
        CHECK(e.data[i] >= 0.0f);
        if (d.data[i] == 0.0f) CHECK(e.data[i] == 0.0f);
        mass += d.data[i];
        mass_e += e.data[i];
    }
    // The core (rho = 1 in the whole voxel and its neighbours) is kept.
    CHECK(e.at(6, 6, 6) == doctest::Approx(1.0f).epsilon(1e-6));
    // The erosion removed a visible share of the puff's mass, not all of it.
    CHECK(mass_e < 0.95 * mass);
    CHECK(mass_e > 0.3 * mass);

    // Each voxel against a 16^3 supersampling of the same ratio: the 4^3 estimate's error.
    // Measured: at most 0.0043 in rho (an edge voxel a billow boundary crosses), 0.00083 on
    // average over non-empty voxels; bounds at 1.5x those.
    const core::GridGeometry& g = d.geom;
    double worst = 0.0, sum = 0.0;
    int count = 0;
    for (int k = 0; k < 12; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 12; ++i) {
                if (d.at(i, j, k) == 0.0f) continue;
                double kept = 0.0, total = 0.0;
                constexpr int m = 16;
                for (int c = 0; c < m; ++c)
                    for (int b = 0; b < m; ++b)
                        for (int a = 0; a < m; ++a) {
                            const glm::dvec3 x =
                                g.origin +
                                (glm::dvec3(i, j, k) + (glm::dvec3(a, b, c) + 0.5) / double(m)) * g.voxel_size;
                            const float rho = d.sample(x);
                            total += rho;
                            kept += cloud::erode(rho, noise.sample(x), 0.6f);
                        }
                const double fine = double(d.at(i, j, k)) * kept / total;
                worst = std::max(worst, std::abs(fine - double(e.at(i, j, k))));
                sum += std::abs(fine - double(e.at(i, j, k)));
                ++count;
            }
    MESSAGE("4^3 vs 16^3 supersampling: worst ", worst, ", mean ", sum / count);
    CHECK(worst < 0.0065);
    CHECK(sum / count < 0.00125);
}

TEST_CASE("the detail on a finer grid: the eroded field at its centres, the solvers' voxel means in its blocks") {
    const core::Grid3<float> d = puff();
    const DetailNoise noise(params(3, 3, 0.6));
    constexpr int k = cloud::kDetailSupersamples;  // its centres are the voxel means' sample points
    const core::Grid3<float> fine = cloud::detailed_on_finer_grid(d, noise, k);
    const core::GridGeometry& g = d.geom;
    REQUIRE(fine.geom.dims == core::Int3{12 * k, 12 * k, 12 * k});
    CHECK(fine.geom.origin == g.origin);
    CHECK(fine.geom.voxel_size == doctest::Approx(g.voxel_size / k).epsilon(1e-15));
    // Each block of k^3 finer voxels holds the mass the solvers' voxel mean keeps: detailed_density
    // scales the voxel by kept / total over the same points, so kept = rho_d total / rho, up to
    // the float rounding of the stored values: measured 3.9e-8 of the block's mass at most; 64
    // float terms can differ by ~64 roundings (4e-6): bound 1e-5.
    const core::Grid3<float> means_grid = cloud::detailed_density(d, noise);
    double worst = 0.0;
    for (int z = 0; z < 12; ++z)
        for (int y = 0; y < 12; ++y)
            for (int x = 0; x < 12; ++x) {
                double kept = 0.0, total = 0.0;
                for (int c = 0; c < k; ++c)
                    for (int b = 0; b < k; ++b)
                        for (int a = 0; a < k; ++a) {
                            const int i = x * k + a, j = y * k + b, l = z * k + c;
                            kept += fine.at(i, j, l);
                            total += d.sample(fine.geom.centre(i, j, l));
                            // At each centre the field the march evaluates, exactly.
                            CHECK(fine.at(i, j, l) == cloud::detailed_at(d, noise, fine.geom.centre(i, j, l)));
                        }
                const float raw = d.at(x, y, z);
                if (raw == 0.0f) continue;
                const double means = double(means_grid.at(x, y, z)) * total / double(raw);
                worst = std::max(worst, std::abs(kept - means) / std::max(total, 1e-30));
            }
    MESSAGE("block mass against the voxel means': worst ", worst, " of the block's undetailed mass");
    CHECK(worst < 1e-5);
    // Refinement 1: the eroded field at the grid's own centres.
    const core::Grid3<float> same = cloud::detailed_on_finer_grid(d, noise, 1);
    CHECK(same.geom == g);
    CHECK(same.at(6, 6, 6) == doctest::Approx(1.0f).epsilon(1e-6));  // the core is kept
    CHECK(same.at(0, 0, 0) == 0.0f);                                 // nothing where there was nothing
}

TEST_CASE("the finer grid's refinement: half the finest billow, within the voxel budget") {
    // The default storm's grid with storm-full's detail: 300 m billows, 4 octaves (the finest
    // 37.5 m): 125 m voxels need 7x (17.9 m), 48 M voxels allow 3x (44.8 M), 16 M allow 2x.
    const core::GridGeometry g{{144, 144, 80}, 125.0, glm::dvec3(0.0)};
    SubvoxelDetail d = params(7, 4, 0.6);
    CHECK(cloud::detail_refinement(g, d, std::uint64_t(1) << 40) == 7);
    CHECK(cloud::detail_refinement(g, d, 48'000'000) == 3);
    CHECK(cloud::detail_refinement(g, d, 16'000'000) == 2);
    CHECK(cloud::detail_refinement(g, d, 1) == 1);  // never below 1
    d.octaves = 1;  // the finest billow 300 m: half of it, 150 m, is wider than the voxels
    CHECK(cloud::detail_refinement(g, d, std::uint64_t(1) << 40) == 1);
    d.scale = 100.0;  // 50 m needed: 3x
    CHECK(cloud::detail_refinement(g, d, std::uint64_t(1) << 40) == 3);
    // A grid far coarser than its billows is capped at 64x before the budget is applied.
    const core::GridGeometry coarse{{2, 2, 2}, 1e6, glm::dvec3(0.0)};
    CHECK(cloud::detail_refinement(coarse, d, std::uint64_t(1) << 62) == 64);
}

TEST_CASE("the detailed density does not depend on the thread count") {
    const core::Grid3<float> d = puff();
    const DetailNoise noise(params(5, 4, 0.8));
    const int threads = core::thread_count();
    core::set_thread_count(1);
    const core::Grid3<float> one = cloud::detailed_density(d, noise);
    const core::Grid3<float> fine_one = cloud::detailed_on_finer_grid(d, noise, 3);
    const DetailNoise noise1(params(5, 4, 0.8));
    core::set_thread_count(2);
    const core::Grid3<float> two = cloud::detailed_density(d, noise);
    const core::Grid3<float> fine_two = cloud::detailed_on_finer_grid(d, noise, 3);
    const DetailNoise noise2(params(5, 4, 0.8));
    core::set_thread_count(threads);
    CHECK(one.data == two.data);
    CHECK(fine_one.data == fine_two.data);
    CHECK(noise1.texels() == noise2.texels());
}

TEST_CASE("bad detail parameters are refused, naming the scene field") {
    auto expect = [](SubvoxelDetail d, const std::string& field) {
        CAPTURE(field);
        try {
            cloud::validate_subvoxel_detail(d);
            FAIL("accepted");
        } catch (const core::Error& e) {
            CHECK(e.where() == "cloud.detail." + field);
        }
        CHECK_THROWS_AS(DetailNoise{d}, core::Error);
    };
    SubvoxelDetail d = params();
    d.scale = 0.0;
    expect(d, "scale");
    d.scale = std::nan("");
    expect(d, "scale");
    d.scale = 1e9;
    expect(d, "scale");
    d = params();
    d.octaves = 0;
    expect(d, "octaves");
    d.octaves = cloud::kMaxDetailOctaves + 1;
    expect(d, "octaves");
    d = params();
    d.strength = -0.1;
    expect(d, "strength");
    d.strength = std::nan("");
    expect(d, "strength");
    d.strength = 1.5;
    expect(d, "strength");
}
