#include "bench/bench.h"

#include "core/core.h"
#include "distributed/distributed.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>

namespace fulgur::bench {

void Context::emit(const std::string& name, nlohmann::json j) const {
    if (session && session->rank() != 0) return;
    if (!j.contains("name")) j["name"] = name;
    std::cout << j.dump() << std::endl;
}

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    if (v.size() % 2) return *mid;
    const double hi = *mid;
    return 0.5 * (hi + *std::max_element(v.begin(), mid));
}

double time_median(int repeats, const std::function<void()>& fn) {
    std::vector<double> t;
    for (int r = 0; r < std::max(1, repeats); ++r) {
        core::Stopwatch w;
        fn();
        t.push_back(w.seconds());
    }
    return median(t);
}

double measure_bandwidth(int threads) {
    const std::size_t n = std::size_t(1) << 24;  // 3 arrays x 128 MiB: far beyond any cache
    std::unique_ptr<double[]> a(new double[n]), b(new double[n]), c(new double[n]);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::int64_t i = 0; i < std::int64_t(n); ++i) {  // first touch by the same threads
        a[std::size_t(i)] = 0.0;
        b[std::size_t(i)] = 1.0;
        c[std::size_t(i)] = 2.0;
    }
    const double s = 3.0;
    std::vector<double> rates;
    for (int r = 0; r < 5; ++r) {
        core::Stopwatch w;
#pragma omp parallel for schedule(static) num_threads(threads)
        for (std::int64_t i = 0; i < std::int64_t(n); ++i)
            a[std::size_t(i)] = b[std::size_t(i)] + s * c[std::size_t(i)];
        rates.push_back(3.0 * 8.0 * double(n) / w.seconds() / 1e9);
    }
    volatile double sink = a[n / 2];
    (void)sink;
    return median(rates);
}

}  // namespace fulgur::bench

int main(int argc, char** argv) {
    // Under mpirun the ranks run the named benchmarks together (bench_mpi.cpp); rank 0 prints.
    const fulgur::distributed::Session session(argc, argv);
    fulgur::bench::Context ctx;
    ctx.session = &session;
    return fulgur::app::registry_main(
        argc, argv,
        {"fulgur-bench", "benchmark", "Runs the named benchmarks (all if none), printing one JSON object per line.",
         10},
        ctx);
}
