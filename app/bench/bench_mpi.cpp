// The bake and the lattice over MPI ranks (engine/distributed, docs/distributed.md). Run
// fulgur-bench under the launcher, one core per rank:
//   mpirun -np 2 --bind-to none fulgur-bench bake_mpi lb_mpi
// Each benchmark first measures the one-process case on rank 0 alone (the other ranks wait
// without spinning), then all ranks together, in the same run; without mpirun only the first.
//
// bake_mpi: Dobashi 2007's configuration (paper_config) on 1 thread per rank: wall time on
//   one rank and on all, speed-up, parallel efficiency, whether the files are byte-identical,
//   and what the scaling model of docs/distributed.md takes: seconds per light and bytes each
//   light sends to rank 0.
// lb_mpi: the 128^3 lattice of the lb benchmark, 1 thread per rank: MLUPS of the shared-memory
//   fast kernel on 1 and 2 threads and of the z-slab lattice on all ranks, the halo bytes per
//   step and the memory bandwidth measured in the same run.
#include "bench/bench.h"
#include "bench/lb_problem.h"
#include "bench/paper_config.h"

#include "core/core.h"
#include "distributed/detail/lattice.h"
#include "distributed/distributed.h"

#include <filesystem>
#include <fstream>
#include <iterator>

using namespace fulgur;

namespace {

std::vector<char> read_bytes(const std::filesystem::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

}  // namespace

FULGUR_BENCH(bake_mpi, "distributed bake, paper configuration, 1 thread per rank: 1 rank vs all (run under mpirun)") {
    const distributed::Session& session = *ctx.session;
    const int saved = core::thread_count();
    core::set_thread_count(1);
    bench::PaperConfig c = bench::paper_config(32, 4, 0.9999);
    c.plan.threads = 1;
    const std::filesystem::path dir = std::filesystem::temp_directory_path();
    const std::filesystem::path one = dir / "fulgur_bench_mpi_1.fgb", all = dir / "fulgur_bench_mpi_n.fgb";
    bake::Report r1;
    double bw = 0.0;
    if (session.rank() == 0) {
        bw = bench::measure_bandwidth(1);
        r1 = bake::bake(c.scene, c.density, c.plan, one);
    }
    (void)session.broadcast(0);  // the other ranks wait (polling) for rank 0's one-rank bake
    const std::optional<bake::Report> rn = distributed::bake(session, c.scene, c.density, c.plan, all);
    if (session.rank() == 0) {
        const double speedup = r1.seconds_total / rn->seconds_total;
        const bool identical = read_bytes(one) == read_bytes(all);
        ctx.emit("bake_mpi",
                 {{"config", "paper 32x32x4, 20x20x7 lights, 26 dirs, energy xi 0.9999"},
                  {"ranks", session.size()},
                  {"threads_per_rank", 1},
                  {"lights", r1.lights},
                  {"seconds_1_rank", r1.seconds_total},
                  {"seconds_all_ranks", rn->seconds_total},
                  {"speedup", speedup},
                  {"parallel_efficiency", speedup / double(session.size())},
                  {"byte_identical", identical},
                  {"seconds_per_light", r1.seconds_total / double(r1.lights)},
                  {"file_bytes", r1.file_bytes},
                  {"bytes_sent_per_light", double(r1.file_bytes) / double(r1.lights) + 80.0},
                  {"raw_MB", double(r1.raw_bytes) / 1e6},
                  {"baseline_triad_GBps_1_thread", bw},
                  {"note", session.size() == 1 ? "one rank: run under mpirun -np 2 for the speed-up" : ""}});
        std::filesystem::remove(one);
        std::filesystem::remove(all);
    }
    core::set_thread_count(saved);
}

FULGUR_BENCH(lb_mpi,
             "z-slab lattice-Boltzmann MLUPS at 128^3 over the ranks vs the shared-memory kernel (under mpirun)") {
    using namespace transport;
    using namespace transport::lb;
    const distributed::Session& session = *ctx.session;
    const int saved = core::thread_count();
    const int n = ctx.quick ? 64 : 128, steps = ctx.quick ? 10 : 20, repeats = ctx.quick ? 3 : 5;
    const Problem p = bench::lb_problem(n, LbAbsorption::Physical);
    const double bytes = 2.0 * 4.0 * 18 + 8.0;  // per site update, as the lb benchmark counts
    nlohmann::json j = {{"grid", n}, {"ranks", session.size()}, {"steps_timed", steps}, {"repeats", repeats}};
    if (session.rank() == 0) {
        for (int threads = 1; threads <= ctx.max_threads; ++threads) {
            core::set_thread_count(threads);
            j["triad_GBps_" + std::to_string(threads) + "_threads"] = bench::measure_bandwidth(threads);
            std::unique_ptr<Kernel> k = make_kernel(p, LbKernel::Fast);
            k->step();
            k->step();
            // Single steps, as the slab lattice takes them (the fused two-step sweep is faster).
            const double t = bench::time_median(repeats, [&] {
                for (int s = 0; s < steps; ++s) k->step();
            });
            j["MLUPS_shared_" + std::to_string(threads) + "_threads"] = double(p.sites()) * steps / t / 1e6;
        }
    }
    (void)session.broadcast(0);
    core::set_thread_count(1);
    distributed::LatticeSlab slab(session, p);
    slab.step();
    slab.step();
    (void)session.broadcast(0);
    const double t = bench::time_median(repeats, [&] {
        for (int s = 0; s < steps; ++s) slab.step();
    });
    const double mlups = double(p.sites()) * steps / t / 1e6;
    j["MLUPS_slabs_1_thread_per_rank"] = mlups;
    j["ms_per_step"] = 1e3 * t / steps;
    j["speedup_vs_shared_1_thread"] = mlups / j.value("MLUPS_shared_1_threads", mlups);
    j["halo_bytes_per_step_per_face"] = double(slab.halo_floats_per_step()) * 4.0;
    j["bytes_per_site_update"] = bytes;
    j["implied_GBps"] = mlups * 1e6 * bytes / 1e9;
    ctx.emit("lb_mpi", j);
    core::set_thread_count(saved);
}
