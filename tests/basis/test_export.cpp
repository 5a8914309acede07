#include "bake_fixture.h"
#include "basis/basis.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <map>

using namespace fulgur;

TEST_CASE("export: a basis and a weighted sum, raw and reconstructed, as NRRD float32") {
    const auto dir = test::scratch_dir("basis_export");
    basis::FgbMetadata meta = test::small_metadata(basis::Precision::Float32);
    meta.compression = {basis::ThresholdMode::Absolute, 0.0, basis::Precision::Float32};  // lossless
    // Raw fields of every light, and the bake made from them.
    std::map<std::uint32_t, transport::SourceField> raw;
    basis::BakedBasis baked;
    baked.meta = meta;
    basis::HaarTransform<double> plan(meta.lighting.dims);
    for (std::uint32_t l = 0; l < meta.light_count(); ++l) {
        transport::SourceField f(meta.lighting, meta.directions);
        for (std::size_t d = 0; d < meta.directions.size(); ++d) {
            const auto v = test::light_field(meta.lighting.dims, 77 * l + d);
            for (std::size_t i = 0; i < v.size(); ++i) f.direction(d)[i] = float(v[i]);
        }
        baked.lights.push_back(basis::compress_light(l, f, meta.compression, plan));
        raw.emplace(l, std::move(f));
    }
    auto field_of = [&](std::uint32_t l) -> const transport::SourceField& { return raw.at(l); };

    const std::vector<basis::WeightedLight> one = {{3, 1.0}};
    const std::vector<basis::WeightedLight> sum = {{0, 0.25}, {3, 2.0}, {6, -0.5}};
    for (const auto* lights : {&one, &sum}) {
        basis::export_raw_nrrd(dir / "raw.nrrd", *lights, 2, field_of);
        basis::export_compressed_nrrd(dir / "rec.nrrd", baked, *lights, 2);
        const core::Grid3<float> r = core::read_nrrd(dir / "raw.nrrd");
        const core::Grid3<float> c = core::read_nrrd(dir / "rec.nrrd");
        CHECK(r.geom == meta.lighting);
        CHECK(c.geom == meta.lighting);
        // The raw export is the weighted sum of the fields, computed here independently.
        core::RelativeL2 e;
        double worst = 0;
        for (std::size_t i = 0; i < r.size(); ++i) {
            double expect = 0;
            for (const auto& wl : *lights) expect += wl.weight * double(raw.at(wl.light).direction(2)[i]);
            worst = std::max(worst, std::fabs(double(r.data[i]) - expect) / (std::fabs(expect) + 1e-30));
            e.add(double(c.data[i]), expect);
        }
        CHECK(worst < 1e-6);      // one float32 rounding of a double sum
        CHECK(e.value() < 3e-7);  // lossless compression: float32 storage rounding only
    }
    // Linearity of the reconstruction: sum of reconstructions == reconstruction of the sum.
    const core::Grid3<float> all = basis::reconstruct(baked, sum, 1);
    for (std::size_t i = 0; i < all.size(); ++i) {
        double parts = 0;
        for (const auto& wl : sum)
            parts += wl.weight *
                     double(basis::reconstruct(baked, std::vector<basis::WeightedLight>{{wl.light, 1.0}}, 1).data[i]);
        CHECK(double(all.data[i]) == test::rel(parts, 1e-6));
        if (i > 6) break;  // a few cells are enough (each reconstruct is a full inverse)
    }
    const std::vector<basis::WeightedLight> bad = {{99, 1.0}};
    CHECK_THROWS_WITH_AS(basis::reconstruct(baked, bad, 0), doctest::Contains("light 99"), core::Error);
    CHECK_THROWS_WITH_AS(basis::reconstruct(baked, one, 7), doctest::Contains("direction 7"), core::Error);
}
