#include "basis/basis.h"
#include "basis/detail/internal.h"
#include "fields.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <limits>
#include <vector>

#if defined(__F16C__)
#include <immintrin.h>
#endif

using namespace fulgur;
using basis::CompressedBasis;
using basis::CompressionParams;
using basis::Precision;
using basis::ThresholdMode;
using core::Int3;

namespace {

std::vector<double> coefficients(Int3 n, std::uint64_t seed) {
    std::vector<double> c = test::light_field(n, seed);
    basis::HaarTransform<double>(n).forward(c);
    return c;
}

double sumsq_dropped(const std::vector<double>& c, const CompressedBasis& b) {
    std::vector<char> kept(c.size(), 0);
    for (std::uint32_t i : b.index) kept[i] = 1;
    core::CompensatedSum s;
    for (std::size_t i = 0; i < c.size(); ++i)
        if (!kept[i]) s.add(c[i] * c[i]);
    return s.value();
}

void check_order(const CompressedBasis& b) {
    for (std::size_t k = 1; k < b.size(); ++k) {
        const float a = std::fabs(b.value[k - 1]), v = std::fabs(b.value[k]);
        CHECK(a >= v);
        if (a == v) CHECK(b.index[k - 1] < b.index[k]);
    }
}

// Nearest half by exhaustive search over the positive halves, ties to even: an oracle
// independent of the bit manipulation in float_to_half.
std::uint16_t reference_half(float f) {
    if (std::isnan(f)) return 0x7e00;
    const double a = std::fabs(double(f));
    const std::uint16_t sign = std::signbit(f) ? 0x8000 : 0;
    // Halves 0..0x7bff are increasing in value; 0x7c00 is infinity (treat as 65536 for rounding).
    auto value = [](std::uint32_t h) { return h == 0x7c00 ? 65536.0 : double(basis::half_to_float(std::uint16_t(h))); };
    std::uint32_t lo = 0, hi = 0x7c00;
    if (a >= 65536.0) return std::uint16_t(sign | 0x7c00);
    while (hi - lo > 1) {  // value(lo) <= a < value(hi)
        const std::uint32_t mid = (lo + hi) / 2;
        if (value(mid) <= a)
            lo = mid;
        else
            hi = mid;
    }
    const double dl = a - value(lo), dh = value(hi) - a;
    std::uint32_t h = dl < dh ? lo : dh < dl ? hi : ((lo & 1) ? hi : lo);
    return std::uint16_t(sign | h);
}

}  // namespace

TEST_CASE("threshold forms hit their targets") {
    const Int3 n{32, 32, 4};
    const std::vector<double> c = coefficients(n, 3);
    const double norm = test::l2(c);

    SUBCASE("absolute: keeps exactly |B| > xi") {
        for (double xi : {1e-6, 1e-4, 1e-3, 1e-2}) {
            const CompressedBasis b =
                basis::compress_coefficients(c, {ThresholdMode::Absolute, xi, Precision::Float32});
            std::size_t expect = 0;
            for (double v : c) expect += std::fabs(v) > xi;
            CHECK(b.size() == expect);
            for (std::uint32_t i : b.index) CHECK(std::fabs(c[i]) > xi);
            CHECK(b.gamma == test::rel(std::sqrt(sumsq_dropped(c, b)), 1e-12));
            CHECK(b.norm == test::rel(norm, 1e-12));
            check_order(b);
        }
    }
    SUBCASE("relative_l2: keeps exactly |B| > xi * ||B||") {
        for (double xi : {1e-5, 1e-3, 0.05}) {
            const CompressedBasis b =
                basis::compress_coefficients(c, {ThresholdMode::RelativeL2, xi, Precision::Float32});
            std::size_t expect = 0;
            for (double v : c) expect += std::fabs(v) > xi * norm;
            CHECK(b.size() == expect);
            check_order(b);
        }
        // Scale-free: scaling the basis does not change what is kept.
        std::vector<double> c2 = c;
        for (double& v : c2) v *= 1e-9;
        const auto a = basis::compress_coefficients(c, {ThresholdMode::RelativeL2, 1e-3, Precision::Float32});
        const auto b = basis::compress_coefficients(c2, {ThresholdMode::RelativeL2, 1e-3, Precision::Float32});
        CHECK(a.index == b.index);
    }
    SUBCASE("energy: the fewest largest coefficients holding >= xi of the energy") {
        for (double xi : {0.5, 0.9, 0.99, 0.9999, 0.999999}) {
            const CompressedBasis b = basis::compress_coefficients(c, {ThresholdMode::Energy, xi, Precision::Float32});
            const double total = norm * norm, dropped = sumsq_dropped(c, b);
            INFO("xi = " << xi);
            // Kept energy >= xi (1e-12: compensated double sums over 4096 terms).
            CHECK(total - dropped >= xi * total * (1 - 1e-12));
            // Minimal: dropping the smallest kept one as well would break the target.
            REQUIRE(b.size() > 0);
            const double smallest = c[b.index.back()];
            CHECK(dropped + smallest * smallest > (1 - xi) * total * (1 - 1e-12));
            // Relative L2 error of the basis is sqrt(dropped / total) <= sqrt(1 - xi).
            CHECK(b.gamma / b.norm <= std::sqrt(1 - xi) * (1 + 1e-12));
            check_order(b);
        }
    }
}

TEST_CASE("xi = 0 keeps every non-zero coefficient; xi huge drops everything and gamma is the norm") {
    std::vector<double> c = coefficients({5, 3, 7}, 9);
    c[4] = 0.0;  // an exact zero is never stored
    const double norm = test::l2(c);
    for (ThresholdMode m : {ThresholdMode::Absolute, ThresholdMode::RelativeL2}) {
        const auto b = basis::compress_coefficients(c, {m, 0.0, Precision::Float32});
        CHECK(b.size() == c.size() - 1);
        CHECK(b.gamma == 0.0);
    }
    CHECK(basis::compress_coefficients(c, {ThresholdMode::Energy, 1.0, Precision::Float32}).size() == c.size() - 1);
    for (const CompressionParams p : {CompressionParams{ThresholdMode::Absolute, 1e30, Precision::Float32},
                                      CompressionParams{ThresholdMode::RelativeL2, 1.0, Precision::Float16},
                                      CompressionParams{ThresholdMode::Energy, 0.0, Precision::Float16}}) {
        const auto b = basis::compress_coefficients(c, p);
        CHECK(b.size() == 0);
        CHECK(b.gamma == test::rel(norm, 1e-14));
        CHECK(b.scale_exp == 0);
    }
}

TEST_CASE("bad coefficients and parameters are rejected") {
    std::vector<double> c = coefficients({4, 4, 4}, 1);
    c[7] = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(basis::compress_coefficients(c, {}, "light 3 direction 2"),
                         doctest::Contains("light 3 direction 2: Haar coefficient 7 is not finite"), core::Error);
    c[7] = 1e300;  // beyond float32 and, even scaled by 2^112, beyond float16
    CHECK_THROWS_WITH_AS(basis::compress_coefficients(c, {ThresholdMode::Absolute, 0.0, Precision::Float32}),
                         doctest::Contains("float32 range"), core::Error);
    CHECK_THROWS_WITH_AS(basis::compress_coefficients(c, {ThresholdMode::Absolute, 0.0, Precision::Float16}),
                         doctest::Contains("overflows float16"), core::Error);
    CHECK_THROWS_WITH_AS(
        basis::validate(CompressionParams{ThresholdMode::Energy, 1.5, Precision::Float16}, "s.compression"),
        doctest::Contains("s.compression.xi"), core::Error);
    CHECK_THROWS_AS(basis::validate(CompressionParams{ThresholdMode::Absolute, -1.0, Precision::Float16}, "c"),
                    core::Error);
    CHECK_THROWS_AS(basis::validate(CompressionParams{ThresholdMode::Absolute, std::nan(""), Precision::Float16}, "c"),
                    core::Error);
}

TEST_CASE("float16 storage: per-basis scale, error within half an ulp of binary16") {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        const Int3 n{32, 32, 4};
        std::vector<double> c = coefficients(n, seed);
        for (double& v : c) v *= 1e-9;  // typical basis magnitudes: far below half's normal range unscaled
        const auto b = basis::compress_coefficients(c, {ThresholdMode::Absolute, 0.0, Precision::Float16});
        const auto b32 = basis::compress_coefficients(c, {ThresholdMode::Absolute, 0.0, Precision::Float32});
        REQUIRE(b.size() == b32.size());
        // The same coefficients are kept; the order may differ where float16 rounding makes
        // two magnitudes equal (ties go by index: the canonical order of stored values).
        auto sorted = [](std::vector<std::uint32_t> v) {
            std::sort(v.begin(), v.end());
            return v;
        };
        CHECK(sorted(b.index) == sorted(b32.index));
        for (std::size_t k = 1; k < b.size(); ++k) {
            const float a = std::fabs(b.value[k - 1]), z = std::fabs(b.value[k]);
            CHECK((a > z || (a == z && b.index[k - 1] < b.index[k])));
        }
        // The largest magnitude sits in [2^14, 2^15) after scaling.
        const double top = std::ldexp(std::fabs(double(b.value[0])), -b.scale_exp);
        CHECK(top >= 16384.0);
        CHECK(top <= 32768.0);
        core::CompensatedSum err2;
        for (std::size_t k = 0; k < b.size(); ++k) {
            const double exact = c[b.index[k]], stored = b.value[k];
            const double scaled = std::ldexp(std::fabs(exact), -b.scale_exp);
            // Half an ulp: 2^-11 relative in the normal range, 2^-25 absolute (scaled) below 2^-14.
            const double bound =
                scaled >= 0x1p-14 ? std::ldexp(std::fabs(exact), -11) : std::ldexp(0x1p-25, b.scale_exp);
            CHECK(std::fabs(stored - exact) <= bound);
            err2.add((stored - exact) * (stored - exact));
        }
        // Whole basis: relative L2 error <= 2^-11 (every coefficient within 2^-11 relative).
        CHECK(std::sqrt(err2.value()) <= 0x1p-11 * test::l2(c));
    }
}

TEST_CASE("float16 conversion: exact decode, round-to-nearest-even encode, subnormals, overflow, NaN") {
    // Every half decodes to a float that encodes back to the same half.
    for (std::uint32_t h = 0; h < 0x10000; ++h) {
        const float f = basis::half_to_float(std::uint16_t(h));
        const bool nan = (h & 0x7c00) == 0x7c00 && (h & 0x3ff);
        if (nan) {
            CHECK(std::isnan(f));
            CHECK(std::isnan(basis::half_to_float(basis::float_to_half(f))));
        } else if (basis::float_to_half(f) != h) {
            FAIL_CHECK("half " << h << " does not round trip");
        }
    }
    // Known values.
    CHECK(basis::float_to_half(1.0f) == 0x3c00);
    CHECK(basis::float_to_half(-2.0f) == 0xc000);
    CHECK(basis::float_to_half(65504.0f) == 0x7bff);   // largest finite half
    CHECK(basis::float_to_half(65519.99f) == 0x7bff);  // below the midpoint to 2^16
    CHECK(basis::float_to_half(65520.0f) == 0x7c00);   // the midpoint rounds to even = infinity
    CHECK(basis::float_to_half(1e10f) == 0x7c00);
    CHECK(basis::float_to_half(-1e10f) == 0xfc00);
    CHECK(basis::float_to_half(0x1p-14f) == 0x0400);    // smallest normal
    CHECK(basis::float_to_half(0x1p-24f) == 0x0001);    // smallest subnormal
    CHECK(basis::float_to_half(0x1p-25f) == 0x0000);    // tie between 0 and 2^-24 -> even (0)
    CHECK(basis::float_to_half(0x1.8p-25f) == 0x0001);  // above the tie
    CHECK(basis::float_to_half(0x1.8p-24f) == 0x0002);  // 1.5 * 2^-24: tie -> even (2)
    CHECK(basis::float_to_half(1e-9f) == 0x0000);
    CHECK(basis::float_to_half(-0.0f) == 0x8000);
    CHECK(basis::float_to_half(1.0f + 0x1p-11f) == 0x3c00);    // tie -> even mantissa
    CHECK(basis::float_to_half(1.0f + 0x1.8p-10f) == 0x3c02);  // 1.5 ulp -> tie -> even (2)
    CHECK(basis::float_to_half(0x1.ffcp-15f) == 0x0400);       // rounds up from the subnormal range into normal
    CHECK(std::isnan(basis::half_to_float(basis::float_to_half(std::numeric_limits<float>::quiet_NaN()))));
    CHECK(basis::float_to_half(std::numeric_limits<float>::infinity()) == 0x7c00);
    CHECK(basis::half_to_float(0x0001) == 0x1p-24f);
    CHECK(basis::half_to_float(0x7bff) == 65504.0f);

    // Random floats over the whole range and dense around the half range: the exhaustive
    // nearest-half oracle and, where the machine has it, the F16C instruction agree.
    core::Rng rng(2024, 1);
    for (int i = 0; i < 100000; ++i) {
        float f;
        if (i % 2) {
            f = std::bit_cast<float>(rng.next_u32());
        } else {  // exponents from 2^-27 to 2^17
            f = std::ldexp(1.0f + rng.uniform_float(), int(rng.uniform_below(45)) - 27);
            if (rng.next_u32() & 1) f = -f;
        }
        if (std::isnan(f)) continue;
        const std::uint16_t h = basis::float_to_half(f);
        if (h != reference_half(f))
            FAIL_CHECK("float " << f << " -> " << h << ", nearest half is " << reference_half(f));
#if defined(__F16C__)
        const std::uint16_t hw = std::uint16_t(_cvtss_sh(f, _MM_FROUND_TO_NEAREST_INT));
        if (h != hw) FAIL_CHECK("float " << f << " -> " << h << ", F16C gives " << hw);
#endif
    }
    // double_to_half rounds once, from the double (no double rounding through float).
    const double just_above_tie = 1.0 + 0x1p-11 + 0x1p-40;  // rounds to 1.0 through float, up from double
    CHECK(basis::double_to_half(just_above_tie) == 0x3c01);
}

TEST_CASE("retruncate: a prefix of the stored order is the basis at a stricter threshold") {
    const Int3 n{33, 4, 7};
    const std::vector<double> c = coefficients(n, 4);
    const auto lossless = basis::compress_coefficients(c, {ThresholdMode::Absolute, 0.0, Precision::Float32});
    // An absolute threshold halfway between two stored magnitudes (no float rounding ambiguity).
    const std::size_t cut = lossless.size() / 5;
    const double t = 0.5 * (std::fabs(double(lossless.value[cut - 1])) + std::fabs(double(lossless.value[cut])));
    CompressedBasis r = lossless;
    basis::retruncate(r, ThresholdMode::Absolute, t);
    const auto direct = basis::compress_coefficients(c, {ThresholdMode::Absolute, t, Precision::Float32});
    CHECK(r.index == direct.index);
    CHECK(r.value == direct.value);
    // gamma from float32 values vs from the double originals: 1e-6 relative (float rounding).
    CHECK(r.gamma == test::rel(direct.gamma, 1e-6));
    // Energy retruncation meets its target.
    CompressedBasis e = lossless;
    basis::retruncate(e, ThresholdMode::Energy, 0.999);
    CHECK(e.gamma <= std::sqrt(0.001) * e.norm * (1 + 1e-9));
    CHECK(e.size() < lossless.size());
    // A looser threshold changes nothing.
    CompressedBasis same = direct;
    basis::retruncate(same, ThresholdMode::Absolute, t * 0.5);
    CHECK(same == direct);
    // Everything.
    basis::retruncate(same, ThresholdMode::Absolute, 1e30);
    CHECK(same.size() == 0);
    CHECK(same.gamma == test::rel(direct.norm, 1e-6));
}

TEST_CASE("compress_light: every direction of a field, and linearity of the reconstruction") {
    core::GridGeometry g;
    g.dims = {9, 6, 5};
    g.voxel_size = 50.0;
    transport::SourceField field(g, transport::output_directions(6));
    for (std::size_t m = 0; m < 6; ++m) {
        const std::vector<double> f = test::light_field(g.dims, 100 + m);
        for (std::size_t i = 0; i < f.size(); ++i) field.direction(m)[i] = float(f[i]);
    }
    basis::HaarTransform<double> plan(g.dims);
    const auto light = basis::compress_light(7, field, {ThresholdMode::Absolute, 0.0, Precision::Float32}, plan);
    CHECK(light.light == 7);
    REQUIRE(light.directions.size() == 6);
    for (std::size_t m = 0; m < 6; ++m) {
        std::vector<float> h(g.cell_count(), 0.0f);
        basis::accumulate(light.directions[m], 1.0f, h);
        basis::HaarTransform<float>(g.dims).inverse(h);
        CHECK(test::relative_l2(h, field.direction(m)) < 3e-7);  // lossless float32 round trip bound
    }
    field.direction(2)[5] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH_AS(basis::compress_light(7, field, {}, plan), doctest::Contains("light 7 direction 2"),
                         core::Error);
}
