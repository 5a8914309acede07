// fulgur-bench: benchmarks that print one JSON object per line.
//
// Each benchmark file registers itself with FULGUR_BENCH(name) { ... } and reports through
// ctx.emit(json). Machines are shared and noisy: report medians over repeats and a baseline
// measured in the same run (memory bandwidth from measure_bandwidth(), or the naive path),
// so ratios stay meaningful. Timings are never asserted in tests; they live here.
#pragma once

#include "common/registry.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace fulgur::distributed {
class Session;
}

namespace fulgur::bench {

struct Context {
    bool quick = false;  ///< --quick: smaller problems / fewer repeats (smoke runs)
    int max_threads = 2;
    /// The MPI ranks fulgur-bench runs on (under mpirun; one otherwise): only rank 0 emits.
    const distributed::Session* session = nullptr;
    /// Prints one JSON object on one line (adds "name" if missing) and flushes.
    void emit(const std::string& name, nlohmann::json j) const;
};

/// FULGUR_BENCH(lb, "help text") { ... uses ctx ... }
#define FULGUR_BENCH(name, help) FULGUR_REGISTRY_ENTRY(::fulgur::bench::Context, name, #name, help)

/// Median of the samples (copied and partially sorted).
double median(std::vector<double> v);

/// Runs fn `repeats` times and returns the median wall time in seconds.
double time_median(int repeats, const std::function<void()>& fn);

/// Sustained memory bandwidth in GB/s (10^9 bytes/s) measured now, STREAM-triad style
/// (a[i] = b[i] + s*c[i], counting 3 x 8 bytes per element, plus write-allocate ignored),
/// over `threads` threads on arrays much larger than the last-level cache. Median of 5.
double measure_bandwidth(int threads);

}  // namespace fulgur::bench
