// The Haar transform the run time inverts every frame (per output direction), against a
// memcpy of the same bytes measured in the same run. One thread; medians of batches.
#include "bench/bench.h"

#include "basis/basis.h"
#include "basis/detail/haar_reference.h"
#include "core/core.h"

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace {

using fulgur::core::Int3;

// Median over `batches` of the time per call of `fn`, each batch running it `per_batch` times.
template <class F>
double per_call_us(int batches, int per_batch, F&& fn) {
    std::vector<double> t;
    for (int b = 0; b < batches; ++b) {
        fulgur::core::Stopwatch w;
        for (int r = 0; r < per_batch; ++r) fn();
        t.push_back(w.seconds() / per_batch * 1e6);
    }
    return fulgur::bench::median(t);
}

}  // namespace

FULGUR_BENCH(haar,
             "3D Haar transform (float32 inverse/forward, float64 forward), both decompositions, vs memcpy of the same "
             "bytes; 1 thread") {
    using namespace fulgur;
    const Int3 sizes[] = {{32, 32, 4}, {64, 64, 16}, {32, 32, 24}, {64, 48, 20}};
    const int batches = ctx.quick ? 5 : 21;
    for (const Int3 n : sizes) {
        for (const basis::Decomposition dec : {basis::Decomposition::NonStandard, basis::Decomposition::Standard}) {
            const std::size_t cells = n.volume();
            // Work per batch ~ a few ms, so timer resolution does not matter.
            const int per_batch = int(std::max<std::size_t>(4, (ctx.quick ? 1u << 20 : 1u << 23) / cells));
            core::Rng rng(1, 2);
            std::vector<float> data(cells), copy(cells);
            for (float& v : data) v = float(rng.uniform() - 0.25);
            const std::vector<float> original = data;
            std::vector<double> data64(data.begin(), data.end());
            basis::HaarTransform<float> tf(n, dec);
            basis::HaarTransform<double> td(n, dec);

            const double memcpy_us = per_call_us(batches, per_batch, [&] {
                std::memcpy(copy.data(), data.data(), cells * sizeof(float));
                asm volatile("" : : "r"(copy.data()) : "memory");
            });
            const double inverse_us = per_call_us(batches, per_batch, [&] { tf.inverse(data); });
            const double forward_us = per_call_us(batches, per_batch, [&] { tf.forward(data); });
            const double forward64_us = per_call_us(batches, per_batch, [&] { td.forward(data64); });

            // Accuracy of one float32 forward + inverse on the original data.
            data = original;
            tf.forward(data);
            tf.inverse(data);
            const double roundtrip = core::relative_l2(data, original);
            ctx.emit("haar", {{"grid", std::to_string(n.x) + "x" + std::to_string(n.y) + "x" + std::to_string(n.z)},
                              {"decomposition", std::string(basis::to_string(dec))},
                              {"cells", cells},
                              {"threads", 1},
                              {"inverse_f32_us", inverse_us},
                              {"forward_f32_us", forward_us},
                              {"forward_f64_us", forward64_us},
                              {"memcpy_us", memcpy_us},
                              {"inverse_over_memcpy", inverse_us / memcpy_us},
                              {"roundtrip_f32_rel_rms", roundtrip}});
        }
    }
}

// ---------------------------------------------------------------------------------------
// Why this scheme: kept coefficients at the same error for alternative Haar schemes, all
// orthonormal (the slow double reference of basis/detail/haar_reference.h):
//   nonstandard + unbalanced (the default: one level on every axis, recurse on the low block)
//   standard + unbalanced   (full 1D transform per axis; weighted last pair)
//   standard + plain        (1/sqrt2 everywhere, odd element passed through unweighted)

FULGUR_BENCH(
    haar_schemes,
    "kept coefficients at 0.1%, 1%, 5% relative L2 error: non-standard vs standard, unbalanced vs plain Haar") {
    using namespace fulgur;
    const Int3 sizes[] = {{32, 32, 4}, {32, 32, 24}, {33, 31, 20}};
    for (const Int3 n : sizes) {
        // A unit point light's field on the grid: 1/r^2 with extinction, inside (peaked)
        // and below the grid (smooth), in voxel units.
        for (const char* where : {"inside", "below"}) {
            const bool inside = where[0] == 'i';
            const double px = 0.37 * n.x, py = 0.55 * n.y, pz = inside ? 0.4 * n.z : -3.0;
            std::vector<double> f(n.volume());
            for (int k = 0; k < n.z; ++k)
                for (int j = 0; j < n.y; ++j)
                    for (int i = 0; i < n.x; ++i) {
                        const double dx = i + 0.5 - px, dy = j + 0.5 - py, dz = k + 0.5 - pz;
                        const double r2 = dx * dx + dy * dy + dz * dz;
                        f[std::size_t(i) + std::size_t(n.x) * (std::size_t(j) + std::size_t(n.y) * std::size_t(k))] =
                            std::exp(-0.15 * std::sqrt(r2)) / (r2 + 0.25);
                    }
            nlohmann::json row = {{"grid", std::to_string(n.x) + "x" + std::to_string(n.y) + "x" + std::to_string(n.z)},
                                  {"light", where}};
            const struct {
                const char* name;
                bool standard, unbalanced;
            } schemes[] = {{"nonstandard_unbalanced", false, true},
                           {"nonstandard_plain", false, false},
                           {"standard_unbalanced", true, true},
                           {"standard_plain", true, false}};
            for (const auto& s : schemes) {
                std::vector<double> c = f;
                basis::reference::haar_forward(c, n, s.standard, s.unbalanced);
                for (const double err : {0.001, 0.01, 0.05}) {
                    const auto b = basis::compress_coefficients(
                        c, {basis::ThresholdMode::Energy, 1.0 - err * err, basis::Precision::Float32});
                    row[std::string("kept_") + s.name + "_err" + std::to_string(err).substr(0, 5)] = b.size();
                }
            }
            row["cells"] = n.volume();
            ctx.emit("haar_schemes", row);
        }
    }
}
