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
// sun_mpi, sky_mpi: the default storm's static light (content/scenes/storm.json, its own
//   settings: sky::solve_settings, sky::static_media), 1 thread per rank: the sun's solve
//   (median of 5) or the sky's (of 2) on one rank, on one rank with max_threads threads, and
//   on all ranks (distributed::static_light_settings), the speed-up, whether the fields are
//   bit-identical, and the parts of the solve's time: what the ranks share (the lattice's
//   steps; the single scattering and the order-2 Monte Carlo, or the sky's dome samples) and
//   what every rank repeats (the lattice's set-up and read-out, the averaging onto the
//   lighting grid).
#include "bench/bench.h"
#include "bench/lb_problem.h"
#include "bench/paper_config.h"

#include "core/core.h"
#include "distributed/detail/lattice.h"
#include "distributed/distributed.h"
#include "sky/sky.h"

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

using namespace fulgur;

namespace {

std::vector<char> read_bytes(const std::filesystem::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

bool same_bits(const sky::LightField& a, const sky::LightField& b) {
    return same_bits(a.single.data, b.single.data) && same_bits(a.multiple.data, b.multiple.data) &&
           a.iterations == b.iterations && a.stored == b.stored;
}

// Repeated solves of one configuration: the medians of the wall time and of its parts (the
// single scattering with order 2, or the dome samples; the lattice's iteration; the rest: the
// lattice's set-up and read-out, the averaging onto the lighting grid), and the last fields.
struct Timings {
    std::vector<double> total, single, lattice, rest;
    std::vector<sky::LightField> fields;
    void add(double seconds, std::vector<sky::LightField> f) {
        double s = 0.0, l = 0.0;
        for (const sky::LightField& x : f) {
            s = std::max(s, x.seconds_single);  // the sky's ends share one pass over the samples
            l += x.seconds_multiple;
        }
        total.push_back(seconds);
        single.push_back(s);
        lattice.push_back(l);
        rest.push_back(seconds - s - l);
        fields = std::move(f);
    }
    void put(nlohmann::json& j, const std::string& suffix) const {
        j["seconds_" + suffix] = bench::median(total);
        j["seconds_single_and_order2_" + suffix] = bench::median(single);
        j["seconds_lattice_" + suffix] = bench::median(lattice);
        j["seconds_rest_" + suffix] = bench::median(rest);
    }
};

// The default storm's static light as fulgur-bake solves it.
struct Storm {
    scene::Scene s = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    core::Grid3<float> density = scene::make_density(s);
    solve::Media media = sky::static_media(s, density);
    sky::SolveSettings settings = sky::solve_settings(s, density);
    std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
};

// The sun (sky = false) or the sky of the storm, `repeats` times, on rank 0 alone (one thread,
// then max_threads) and on all ranks (one thread each); emits on rank 0.
void static_light_mpi(const bench::Context& ctx, bool sky_dome, int repeats) {
    const distributed::Session& session = *ctx.session;
    const Storm c;
    FULGUR_ASSERT(c.s.sun.has_value() && c.s.sky.has_value(), "the default storm has a moon and a sky");
    const transport::DirectionalSource unit{c.s.sun->direction, 1.0};
    const bool uniform = c.s.sky->zenith() == c.s.sky->horizon();  // as sky::plan_scene decides
    auto solve = [&](const sky::SolveSettings& st) -> std::vector<sky::LightField> {
        if (!sky_dome) return {sky::solve_directional(c.media, std::span(&unit, 1), c.dirs, st)};
        sky::SkyField f = sky::solve_sky(c.media, uniform, c.dirs, st);
        if (uniform) return {std::move(f.uniform)};
        return {std::move(f.zenith), std::move(f.horizon)};
    };
    auto once = [&](const sky::SolveSettings& st, Timings& t) {
        core::Stopwatch sw;
        std::vector<sky::LightField> f = solve(st);
        t.add(sw.seconds(), std::move(f));
    };
    const int saved = core::thread_count();
    const sky::SolveSettings spread = distributed::static_light_settings(session, c.settings);
    Timings one, threads, all;
    double single_alone = 0.0;
    // The three configurations take turns, so that the shared machine's slow spells fall on
    // all of them alike.
    for (int r = 0; r < repeats; ++r) {
        if (session.rank() == 0) {
            core::set_thread_count(1);
            once(c.settings, one);
            if (!sky_dome && r == 0) {
                // The exact single scattering alone (the rest of seconds_single is order 2).
                transport::SourceField tmp(c.media.transport.density.geom, c.dirs);
                core::Grid3<float> phi;
                transport::SingleScatteringOptions ss = c.settings.single_options;
                ss.uncollided_fluence = &phi;
                core::Stopwatch sw;
                transport::single_scattering(c.media.transport, unit, tmp, ss);
                single_alone = sw.seconds();
            }
            core::set_thread_count(ctx.max_threads);
            once(c.settings, threads);
        }
        (void)session.broadcast(0);  // the other ranks wait (polling) for rank 0's one-rank solves
        core::set_thread_count(1);
        once(spread, all);
    }
    core::set_thread_count(saved);
    if (session.rank() != 0) return;
    bool identical = one.fields.size() == all.fields.size();
    for (std::size_t i = 0; identical && i < one.fields.size(); ++i)
        identical = same_bits(one.fields[i], all.fields[i]);
    const double t1 = bench::median(one.total), tn = bench::median(all.total);
    nlohmann::json j = {
        {"scene", "content/scenes/storm.json"},
        {"light", sky_dome ? (uniform ? "sky (uniform)" : "sky (zenith and horizon)") : "sun"},
        {"transport_grid",
         {c.media.transport.density.dims().x, c.media.transport.density.dims().y, c.media.transport.density.dims().z}},
        {"directions", c.dirs.size()},
        {"exact_orders", c.settings.exact_orders},
        {"order2_paths", c.settings.order2_paths},
        {"ranks", session.size()},
        {"threads_per_rank", 1},
        {"repeats", repeats},
        {"lattice_steps", one.fields.front().iterations},
        {"speedup", t1 / tn},
        {"parallel_efficiency", t1 / tn / double(session.size())},
        {"speedup_of_" + std::to_string(ctx.max_threads) + "_threads", t1 / bench::median(threads.total)},
        {"bit_identical", identical},
        {"note", session.size() == 1 ? "one rank: run under mpirun -np 2 for the speed-up" : ""}};
    if (sky_dome) {
        j["dome_samples"] = c.settings.sky_paths > 0 ? 0 : c.settings.sky_samples;
        j["dome_paths"] = c.settings.sky_paths;  // > 0: the dome by its own Monte Carlo, a basis per rank
    }
    one.put(j, "1_rank");
    threads.put(j, "1_rank_" + std::to_string(ctx.max_threads) + "_threads");
    all.put(j, "all_ranks");
    if (!sky_dome) {
        j["seconds_single_alone_1_rank"] = single_alone;
        j["seconds_order2_1_rank"] = bench::median(one.single) - single_alone;
    }
    // Of the one-rank solve: the parts the ranks share out (the lattice's steps, in slabs; the
    // sky's dome samples; the sun's single scattering beside its order 2, itself on one rank)
    // and what every rank repeats (the rest).
    j["fraction_lattice_1_rank"] = bench::median(one.lattice) / t1;
    j["fraction_rest_1_rank"] = bench::median(one.rest) / t1;
    if (sky_dome) {
        j["fraction_dome_samples_1_rank"] = bench::median(one.single) / t1;
    } else {
        j["fraction_single_1_rank"] = single_alone / t1;
        j["fraction_order2_1_rank"] = (bench::median(one.single) - single_alone) / t1;
    }
    ctx.emit(sky_dome ? "sky_mpi" : "sun_mpi", j);
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

FULGUR_BENCH(sun_mpi, "the default storm's sun solve, 1 thread per rank: 1 rank vs all, bit-identity (under mpirun)") {
    static_light_mpi(ctx, false, ctx.quick ? 1 : 5);
}

FULGUR_BENCH(sky_mpi, "the default storm's sky solve, 1 thread per rank: 1 rank vs all, bit-identity (under mpirun)") {
    static_light_mpi(ctx, true, ctx.quick ? 1 : 2);
}
