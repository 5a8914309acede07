// Lattice-Boltzmann kernel throughput: million lattice-site updates per second (MLUPS) at
// 128^3 on 1 and 2 threads, fast and naive (Appendix B) kernels, with the memory bandwidth
// measured in the same run and the bandwidth the fast kernel implies.
#include "bench/bench.h"
#include "bench/lb_problem.h"

#include "core/core.h"
#include "transport/detail/lb_solver.h"

#include <algorithm>
#include <fstream>

using namespace fulgur;
using namespace fulgur::transport;
using namespace fulgur::transport::lb;

namespace {

// A full lattice of medium (every row collides: the kernel's worst case), a sun on the top
// face and a volume source, physical or conservative absorption.
Problem bench_problem(int n, LbAbsorption abs) {
    const core::Int3 d{n, n, n};
    const Medium m{0.02, 0.99, 0.6};
    Problem p = Problem::uniform(d, site_coefficients(m, 25.0, 0.5), corrected_phase(0.6), abs);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            p.inflow.push_back({p.index(x, y, n - 1), 6, 1.0f});
            p.inflow_per_step += 1.0;
        }
    std::array<double, kQ> e{};
    for (int q = 1; q < kQ; ++q) e[std::size_t(q)] = weight(q);
    p.add_source(p.index(n / 2, n / 2, n / 2), e, site_coefficients(m, 25.0, 0.5));
    return p;
}

// The 1-minute load average (Linux), or -1: the machine is shared, and a figure measured
// next to other work says little without it.
double load_average() {
    std::ifstream f("/proc/loadavg");
    double l = -1.0;
    if (!(f >> l)) return -1.0;
    return l;
}

}  // namespace

transport::lb::Problem fulgur::bench::lb_problem(int n, LbAbsorption absorption) {
    return bench_problem(n, absorption);
}

FULGUR_BENCH(lb, "lattice-Boltzmann MLUPS at 128^3, fast vs naive kernel, 1 and 2 threads, vs memory bandwidth") {
    const int n = ctx.quick ? 64 : 128;
    const int repeats = ctx.quick ? 3 : 5;
    const int saved_threads = core::thread_count();
    for (LbAbsorption abs : {LbAbsorption::Physical, LbAbsorption::Conservative}) {
        const Problem p = bench_problem(n, abs);
        const int dirs = abs == LbAbsorption::Physical ? 18 : 19;
        // Bytes per site update of the in-place kernel: read + write every direction, read
        // the two per-site extinction values (the rest direction is never touched in the
        // physical model). This is the traffic of one step alone; the fused two-step sweep
        // reuses a plane's lines from the last-level cache for the second step, so its
        // memory traffic is lower and "implied_GBps" an upper bound.
        const double bytes = 2.0 * 4.0 * dirs + 8.0;
        double mlups_1 = 0.0;
        for (int threads = 1; threads <= ctx.max_threads; ++threads) {
            core::set_thread_count(threads);
            const double bw = bench::measure_bandwidth(threads);
            Simulation fast(p, LbKernel::Fast);
            fast.step_two();  // warm up (first touch done in the constructor)
            // Steps in pairs, as Simulation::run() takes them (one sweep per pair).
            const int steps = ctx.quick ? 10 : 20;
            const double t = bench::time_median(repeats, [&] {
                for (int s = 0; s < steps; s += 2) fast.step_two();
            });
            const double mlups = double(p.sites()) * steps / t / 1e6;
            const double implied = mlups * 1e6 * bytes / 1e9;
            if (threads == 1) mlups_1 = mlups;
            ctx.emit("lb", {{"kernel", "fast"},
                            {"absorption", abs == LbAbsorption::Physical ? "physical" : "conservative"},
                            {"grid", n},
                            {"threads", threads},
                            {"MLUPS", mlups},
                            {"ms_per_step", 1e3 * t / steps},
                            {"bytes_per_site_update", bytes},
                            {"implied_GBps", implied},
                            {"triad_GBps", bw},
                            {"fraction_of_triad", implied / bw},
                            {"speedup_vs_1_thread", mlups / mlups_1},
                            {"steps_per_sweep", 2},
                            {"load_average_1min", load_average()},
                            {"steps_timed", steps},
                            {"repeats", repeats}});
        }
    }
    // Naive kernel (single-threaded by construction), fewer steps: it is ~50x slower.
    {
        core::set_thread_count(1);
        const Problem p = bench_problem(n, LbAbsorption::Physical);
        Simulation naive(p, LbKernel::Naive);
        naive.step();
        const int steps = 2;
        const double t = bench::time_median(3, [&] {
            for (int s = 0; s < steps; ++s) naive.step();
        });
        ctx.emit("lb", {{"kernel", "naive"},
                        {"absorption", "physical"},
                        {"grid", n},
                        {"threads", 1},
                        {"MLUPS", double(p.sites()) * steps / t / 1e6},
                        {"ms_per_step", 1e3 * t / steps},
                        {"note", "Appendix B: AoS, dense 19x19 Theta built per site, separate stream pass"},
                        {"paper_MLUPS_P4", 2097152.0 / 6.15 / 1e6}});
    }
    core::set_thread_count(saved_threads);
}
