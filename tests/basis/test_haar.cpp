#include "basis/basis.h"
#include "basis/detail/haar_reference.h"
#include "fields.h"
#include "support/grids.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

using namespace fulgur;
using basis::Decomposition;
using basis::HaarTransform;
using core::Int3;

namespace {

std::string str(Int3 n) { return std::to_string(n.x) + "x" + std::to_string(n.y) + "x" + std::to_string(n.z); }

constexpr Decomposition kBoth[] = {Decomposition::NonStandard, Decomposition::Standard};

// Odd and even sizes (1, 2, 3, 5, 33 as cubes), larger grids, and mixed odd/even axes.
const std::vector<Int3> kSizes = {{1, 1, 1},  {2, 2, 2},  {3, 3, 3},   {5, 5, 5},    {33, 33, 33}, {33, 1, 1},
                                  {1, 33, 1}, {1, 1, 33}, {32, 32, 4}, {64, 48, 20}, {5, 2, 3},    {33, 4, 7},
                                  {6, 9, 1},  {1, 7, 2},  {2, 1, 5},   {32, 32, 24}};

// Matrix of the 1D transform along `axis` on length n: column j = forward(e_j).
std::vector<double> matrix_1d(int n, int axis) {
    Int3 d{1, 1, 1};
    (axis == 0 ? d.x : axis == 1 ? d.y : d.z) = n;
    HaarTransform<double> t(d);
    std::vector<double> m(std::size_t(n) * n);
    std::vector<double> e(static_cast<std::size_t>(n));
    for (int j = 0; j < n; ++j) {
        std::fill(e.begin(), e.end(), 0.0);
        e[std::size_t(j)] = 1.0;
        t.forward(e);
        for (int i = 0; i < n; ++i) m[std::size_t(i) * n + j] = e[std::size_t(i)];
    }
    return m;
}

}  // namespace

TEST_CASE("1D Haar is orthonormal on every length 1..40, identical on all three axes") {
    for (int n = 1; n <= 40; ++n) {
        const std::vector<double> w = matrix_1d(n, 0);
        double worst = 0.0;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) {
                double dot = 0.0;
                for (int k = 0; k < n; ++k) dot += w[std::size_t(a) * n + k] * w[std::size_t(b) * n + k];
                worst = std::max(worst, std::fabs(dot - (a == b ? 1.0 : 0.0)));
            }
        INFO("n = " << n);
        // A few dozen double roundings per entry: 1e-13 is ~500 ulp of headroom.
        CHECK(worst < 1e-13);
        CHECK(matrix_1d(n, 1) == w);
        CHECK(matrix_1d(n, 2) == w);
    }
}

TEST_CASE("textbook Haar on powers of two") {
    const double r = std::sqrt(0.5);
    const std::vector<double> w2 = matrix_1d(2, 0);
    // Exact up to the rounding of 1/sqrt(2) itself (1 ulp).
    CHECK(w2[0] == test::rel(r, 1e-15));
    CHECK(w2[1] == test::rel(r, 1e-15));
    CHECK(w2[2] == test::rel(r, 1e-15));
    CHECK(w2[3] == test::rel(-r, 1e-15));
    // n = 4: rows (1,1,1,1)/2, (1,1,-1,-1)/2, (1,-1,0,0)/sqrt2, (0,0,1,-1)/sqrt2.
    const std::vector<double> w4 = matrix_1d(4, 0);
    const double expect[16] = {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, -0.5, -0.5, r, -r, 0, 0, 0, 0, r, -r};
    for (int i = 0; i < 16; ++i) CHECK(w4[std::size_t(i)] == test::rel(expect[i], 1e-15));
}

TEST_CASE("a constant is one coefficient on any size (unbalanced Haar)") {
    for (const Decomposition dec : kBoth)
        for (const Int3 n : kSizes) {
            HaarTransform<double> t(n, dec);
            std::vector<double> v(n.volume(), 2.5);
            t.forward(v);
            INFO(str(n) << " " << basis::to_string(dec));
            // coefficient 0 = sum / sqrt(N); rounding of ~3*log2(n) rotations, relative 1e-13.
            CHECK(v[0] == test::rel(2.5 * std::sqrt(double(n.volume())), 1e-13));
            double rest = 0.0;
            for (std::size_t i = 1; i < v.size(); ++i) rest = std::max(rest, std::fabs(v[i]));
            CHECK(rest < 1e-12);
        }
}

TEST_CASE("the 3D transform is the tensor product of the 1D transforms (standard decomposition)") {
    for (const Int3 n : {Int3{5, 3, 4}, Int3{2, 7, 1}, Int3{3, 1, 6}}) {
        const std::vector<double> wx = matrix_1d(n.x, 0), wy = matrix_1d(n.y, 0), wz = matrix_1d(n.z, 0);
        const std::vector<double> f = test::light_field(n, 5);
        std::vector<double> fast = f;
        HaarTransform<double>(n, Decomposition::Standard).forward(fast);
        double worst = 0.0;
        test::for_each_cell(n, [&](int a, int b, int c) {
            double s = 0.0;
            test::for_each_cell(n, [&](int i, int j, int k) {
                s += wx[std::size_t(a) * n.x + i] * wy[std::size_t(b) * n.y + j] * wz[std::size_t(c) * n.z + k] *
                     f[std::size_t(i) + std::size_t(n.x) * (std::size_t(j) + std::size_t(n.y) * k)];
            });
            worst = std::max(
                worst,
                std::fabs(s - fast[std::size_t(a) + std::size_t(n.x) * (std::size_t(b) + std::size_t(n.y) * c)]));
        });
        INFO(str(n));
        CHECK(worst < 1e-13);  // values O(1), sums of <= 120 products: rounding ~1e-15 each
    }
}

TEST_CASE("both decompositions equal the literal reference and are orthonormal in 3D") {
    for (const Decomposition dec : kBoth) {
        for (const Int3 n : kSizes) {
            const std::vector<double> f = test::light_field(n, 8);
            std::vector<double> fast = f, ref = f;
            HaarTransform<double>(n, dec).forward(fast);
            basis::reference::haar_forward(ref, n, dec == Decomposition::Standard);
            double worst = 0.0;
            for (std::size_t i = 0; i < f.size(); ++i) worst = std::max(worst, std::fabs(fast[i] - ref[i]));
            INFO(str(n) << " " << basis::to_string(dec));
            // Same operations up to the factoring into U P: rounding only (coefficients up to ~1e2).
            CHECK(worst < 1e-12 * std::max(1.0, test::l2(f)));
        }
        // The full matrix of small mixed grids: W W^T = I.
        for (const Int3 n : {Int3{5, 3, 4}, Int3{2, 7, 3}, Int3{6, 1, 5}, Int3{3, 3, 3}}) {
            const std::size_t N = n.volume();
            HaarTransform<double> t(n, dec);
            std::vector<double> w(N * N), e(N);
            for (std::size_t j = 0; j < N; ++j) {
                std::fill(e.begin(), e.end(), 0.0);
                e[j] = 1.0;
                t.forward(e);
                for (std::size_t i = 0; i < N; ++i) w[i * N + j] = e[i];
            }
            double worst = 0.0;
            for (std::size_t a = 0; a < N; ++a)
                for (std::size_t b = 0; b < N; ++b) {
                    double dot = 0.0;
                    for (std::size_t c = 0; c < N; ++c) dot += w[a * N + c] * w[b * N + c];
                    worst = std::max(worst, std::fabs(dot - (a == b ? 1.0 : 0.0)));
                }
            INFO(str(n) << " " << basis::to_string(dec));
            CHECK(worst < 1e-13);  // double rounding over <= 15 steps per entry
            // The inverse inverts it.
            std::vector<double> x = test::light_field(n, 2), y = x;
            t.forward(y);
            t.inverse(y);
            CHECK(test::l2_diff(x, y) < 1e-14 * test::l2(x));
        }
    }
}

TEST_CASE("lossless round trip at xi = 0 in float32: relative RMS < 3e-7") {
    for (const Decomposition dec : kBoth)
        for (const Int3 n : kSizes) {
            basis::CompressionParams p;
            p.mode = basis::ThresholdMode::Absolute;
            p.xi = 0.0;
            p.precision = basis::Precision::Float32;
            p.decomposition = dec;
            INFO(str(n) << " " << basis::to_string(dec));
            const std::vector<double> f = test::light_field(n, 11);
            // The bake's path: forward in double, store float32, run-time inverse in float.
            std::vector<double> c = f;
            HaarTransform<double>(n, dec).forward(c);
            const basis::CompressedBasis b = basis::compress_coefficients(c, p);
            std::vector<float> h(n.volume(), 0.0f);
            basis::accumulate(b, 1.0f, h);
            HaarTransform<float>(n, dec).inverse(h);
            std::vector<double> back(h.begin(), h.end());
            const double rel = test::l2_diff(back, f) / test::l2(f);
            CHECK(rel < 3e-7);  // the required bound for float32 (unit roundoff 6e-8, ~log2(n) levels per axis)
            // Pure float forward + inverse stays within the same bound.
            std::vector<float> g(f.begin(), f.end());
            HaarTransform<float> tf(n, dec);
            tf.forward(g);
            tf.inverse(g);
            std::vector<double> back2(g.begin(), g.end());
            CHECK(test::l2_diff(back2, f) / test::l2(f) < 3e-7);
            CHECK(b.gamma == 0.0);  // nothing dropped at xi = 0 (exact zeros carry no energy)
        }
}

TEST_CASE("Parseval: the L2 error of a thresholded reconstruction is the norm of the dropped coefficients") {
    for (const Decomposition dec : kBoth)
        for (const Int3 n : kSizes) {
            INFO(str(n) << " " << basis::to_string(dec));
            const std::vector<double> f = test::light_field(n, 23);
            std::vector<double> c = f;
            HaarTransform<double> t(n, dec);
            t.forward(c);
            // Energy of the signal is preserved.
            CHECK(test::l2(c) == test::rel(test::l2(f), 1e-12));
            // Drop every coefficient below the median magnitude.
            std::vector<double> mags;
            for (double v : c) mags.push_back(std::fabs(v));
            std::nth_element(mags.begin(), mags.begin() + std::ptrdiff_t(mags.size() / 2), mags.end());
            const double thr = mags[mags.size() / 2];
            core::CompensatedSum dropped;
            for (double& v : c)
                if (std::fabs(v) <= thr && n.volume() > 1) {
                    dropped.add(v * v);
                    v = 0.0;
                }
            t.inverse(c);
            const double err = test::l2_diff(c, f), gamma = std::sqrt(dropped.value());
            if (gamma > 0.0) {
                CHECK(err == test::rel(gamma, 1e-5));  // the required bound; double gives ~1e-12
            } else {
                CHECK(err < 1e-14 * test::l2(f));
            }
            // The thresholded error has zero mean when coefficient 0 (the mean) is kept: a constant
            // "ambient" correction cannot reduce it (docs/basis.md).
            double mean = 0.0;
            for (std::size_t i = 0; i < f.size(); ++i) mean += c[i] - f[i];
            mean /= double(f.size());
            CHECK(std::fabs(mean) < 1e-12 * test::l2(f));
        }
}

TEST_CASE("Parseval through compress: reconstruction error equals gamma up to float32 storage rounding") {
    for (const Decomposition dec : kBoth)
        for (const Int3 n : {Int3{32, 32, 4}, Int3{33, 4, 7}, Int3{64, 48, 20}}) {
            INFO(str(n) << " " << basis::to_string(dec));
            const std::vector<double> f = test::light_field(n, 31);
            std::vector<double> c = f;
            HaarTransform<double> t(n, dec);
            t.forward(c);
            basis::CompressionParams p{basis::ThresholdMode::Energy, 0.999, basis::Precision::Float32, dec};
            const basis::CompressedBasis b = basis::compress_coefficients(c, p);
            std::vector<double> h(n.volume(), 0.0);
            basis::accumulate(b, 1.0, h);
            t.inverse(h);
            const double err = test::l2_diff(h, f);
            // err^2 = gamma^2 + (float32 rounding of kept values)^2; the latter is <= 2^-24 ||f||.
            CHECK(std::fabs(err - b.gamma) <= 1e-5 * b.gamma + 6e-8 * test::l2(f));
            CHECK(b.gamma <= std::sqrt(1.0 - 0.999) * b.norm * (1 + 1e-12));
        }
}
