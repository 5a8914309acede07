// The bake (bake.h, docs/bake.md): the plan's lights solved in chunks by this process's
// threads and any helpers, checkpointed, written in light order into a checksummed .fgb.
#include "bake/bake.h"
#include "bake/detail/checkpoint.h"
#include "bake/detail/light.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <thread>

namespace fulgur::bake {

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& out,
            const Progress& progress) {
    PlanOptions po;
    po.estimate = false;
    return bake(s, density, make_plan(s, density, po), out, progress);
}

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const Progress& progress) {
    return bake(s, density, plan, out, BakeOptions{}, progress);
}

std::filesystem::path checkpoint_path(const std::filesystem::path& out) { return out.string() + ".ckpt"; }

namespace {

// The Report's sums over the lights' figures.
struct Totals {
    double single = 0.0, multiple = 0.0, compress = 0.0, ref2 = 0.0, err2 = 0.0, iterations = 0.0, max_iterations = 0.0,
           max_dropped = 0.0;
    std::size_t lattice_lights = 0, dropped = 0, unconverged = 0;
    std::uint64_t kept = 0;
    void add(const LightResult& r) {
        single += r.seconds_single;
        multiple += r.seconds_multiple;
        compress += r.seconds_compress;
        ref2 += r.ref2;
        err2 += r.err2;
        kept += r.coefficients;
        if (r.dropped_fraction >= 0.0) {
            ++dropped;
            max_dropped = std::max(max_dropped, r.dropped_fraction);
        }
        if (r.iterations >= 0) {
            ++lattice_lights;
            iterations += r.iterations;
            max_iterations = std::max(max_iterations, double(r.iterations));
            if (!r.converged) ++unconverged;
        }
    }
};

// Runs body(haar) on `threads` threads with the solvers' own parallel regions nested inside
// single-threaded (max-active-levels 1), each thread with its Haar plan; rethrows the first
// exception once all have stopped. `failed` tells the bodies to stop early. With `serve`,
// the calling thread (the team's thread 0) runs serve() instead, beside `threads` workers.
template <class Body, class Serve>
void run_team(const Plan& plan, const scene::Scene& s, int threads, std::atomic<bool>& failed, Body&& body,
              Serve* serve) {
    std::exception_ptr failure;
    std::mutex mu;
    const int saved_levels = omp_get_max_active_levels();
    omp_set_max_active_levels(1);
#pragma omp parallel num_threads(threads + (serve ? 1 : 0))
    {
        try {
            if (serve && omp_get_thread_num() == 0) {
                (*serve)();
            } else {
                basis::HaarTransform<double> haar(plan.lighting.dims, s.compression.decomposition);
                body(haar);
            }
        } catch (...) {
            std::lock_guard lock(mu);
            if (!failure) failure = std::current_exception();
            failed = true;
        }
    }
    omp_set_max_active_levels(saved_levels);
    if (failure) std::rethrow_exception(failure);
}

// The chunks to solve: the lights the checkpoint lacks, cut into chunks small enough to keep
// every worker busy to the end (light costs vary ~3x) and few enough to keep the checkpoint's
// files and the messages few. Alone and without a checkpoint: one light. The checkpoint's
// figures go into `totals`.
std::vector<Chunk> plan_chunks(const Plan& plan, const BakeOptions& options, const detail::Checkpoint* checkpoint,
                               Totals& totals) {
    const std::uint32_t n = std::uint32_t(plan.lights.count());
    const std::uint32_t workers = std::uint32_t(plan.threads + (options.helpers ? options.helpers->threads() : 0));
    std::uint32_t size = options.chunk;
    if (size == 0)
        size = (!checkpoint && !options.helpers) ? 1u : std::clamp(n / (4u * std::max(workers, 1u)), 1u, 64u);
    std::vector<Chunk> todo;
    std::uint32_t l = 0;
    auto cut = [&](std::uint32_t to) {
        for (; l < to; l = std::min(to, l + size)) todo.push_back({l, std::min(to, l + size)});
    };
    if (checkpoint)
        for (const detail::Checkpoint::Held& h : checkpoint->held()) {
            cut(h.chunk.begin);
            for (const LightResult& r : h.figures) totals.add(r);
            l = h.chunk.end;
        }
    cut(n);
    return todo;
}

// The report's figures from the lights' totals; a bake that would render an unlit cloud is
// refused (no file is written), naming the settings that made it so.
void check_and_sum(const scene::Scene& s, const Totals& totals, std::uint32_t n, Report& rep) {
    const std::string where = s.file_name();
    rep.lights_dropped = totals.dropped;
    rep.coefficients_kept = totals.kept;
    rep.unconverged = totals.unconverged;
    rep.max_dropped_fraction = totals.max_dropped;
    // Nothing scattered by any light (every light dropped at a fraction of 0, or every kept
    // light's bases zero): the medium's setting is named, not the threshold that then found
    // nothing.
    const bool all_dropped = rep.lights_dropped == n;
    if ((all_dropped && !(rep.max_dropped_fraction > 0.0)) ||
        (!all_dropped && rep.coefficients_kept == 0 && !(totals.ref2 > 0.0))) {
        const bool dark = s.medium.albedo == 0.0;
        throw core::Error(where + (dark ? ": medium.albedo" : ": medium.extinction"),
                          std::string(dark ? "0: the cloud absorbs all light and scatters none"
                                           : "the cloud scatters no light from any virtual light") +
                              ", so every basis is zero and the bake would light nothing");
    }
    if (all_dropped)
        throw core::Error(where + ": virtual_lights.drop_below",
                          "every one of the " + std::to_string(n) + " virtual lights scatters less than " +
                              core::format_number(s.drop_below) +
                              " of its power (largest: " + core::format_number(rep.max_dropped_fraction) +
                              ") and was dropped; the bake would light nothing: lower drop_below");
    if (rep.coefficients_kept == 0)
        throw core::Error(where + ": compression.xi",
                          "the threshold keeps no coefficient of any basis; the bake would light nothing: lower xi");
    // Per-stage times are summed over the worker threads (CPU seconds); the total is wall time.
    rep.seconds_single = totals.single;
    rep.seconds_multiple = totals.multiple;
    rep.seconds_compress = totals.compress;
    rep.relative_l2_error = totals.ref2 > 0.0 ? std::sqrt(totals.err2 / totals.ref2) : 0.0;
    rep.mean_solver_iterations = totals.lattice_lights ? totals.iterations / double(totals.lattice_lights) : 0.0;
    rep.max_solver_iterations = totals.max_iterations;
}

}  // namespace

std::vector<LightResult> bake_lights(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                                     std::uint32_t begin, std::uint32_t end) {
    FULGUR_ASSERT(begin <= end && end <= plan.lights.count(), "bake_lights: light range outside the plan");
    std::vector<LightResult> out(end - begin);
    std::atomic<std::uint32_t> next{begin};
    std::atomic<bool> failed{false};
    auto body = [&](basis::HaarTransform<double>& haar) {
        for (std::uint32_t l = next.fetch_add(1); l < end && !failed.load(); l = next.fetch_add(1))
            out[l - begin] = detail::bake_one(s, media, plan, haar, l);
    };
    run_team(plan, s, plan.threads, failed, body, static_cast<std::function<void()>*>(nullptr));
    return out;
}

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const BakeOptions& options, const Progress& progress) {
    core::Stopwatch total;
    Report rep;
    rep.threads = plan.threads;
    rep.lights = plan.lights.count();
    rep.raw_bytes = plan.raw_bytes;
    const solve::Media media = solve::make_media(s, density);
    // The output's lock for the whole bake, the checkpoint's removal included: one bake per
    // output, so one user of its checkpoint (the writer's own lock is then a no-op).
    const core::FileLock output_lock(out);
    basis::FgbWriter writer(out, plan.metadata);
    std::unique_ptr<detail::Checkpoint> checkpoint;
    if (!options.checkpoint.empty()) checkpoint = std::make_unique<detail::Checkpoint>(options.checkpoint, plan);

    const std::uint32_t n = std::uint32_t(plan.lights.count());
    Totals totals;
    const std::vector<Chunk> todo = plan_chunks(plan, options, checkpoint.get(), totals);
    rep.lights_resumed = checkpoint ? checkpoint->lights() : 0;

    std::mutex mu;  // guards totals, pending, done and the progress callback
    std::map<std::uint32_t, std::vector<LightResult>> pending;  // finished out of order (no checkpoint)
    std::uint32_t next_write = 0;
    std::size_t done = 0;
    const std::size_t to_do = n - rep.lights_resumed;
    auto advance = [&](std::size_t lights) {  // under mu
        done += lights;
        if (progress) progress(done, to_do, total.seconds());
    };
    // A finished chunk: into the checkpoint, or into the file once every light before it is
    // in (blocks go in light order: the file is the same however the work was split).
    auto deliver = [&](Chunk c, std::vector<LightResult>&& results) {
        if (checkpoint) checkpoint->add(c, results);
        std::lock_guard lock(mu);
        for (const LightResult& r : results) totals.add(r);
        if (checkpoint) {
            if (options.on_checkpoint) options.on_checkpoint(checkpoint->lights());
            return;
        }
        pending.emplace(c.begin, std::move(results));
        while (!pending.empty() && pending.begin()->first == next_write) {
            for (const LightResult& r : pending.begin()->second) writer.add(r.block);
            next_write += std::uint32_t(pending.begin()->second.size());
            pending.erase(pending.begin());
        }
    };
    std::atomic<std::size_t> next{0};
    std::atomic<bool> failed{false};
    auto take = [&]() -> std::optional<Chunk> {
        if (failed.load()) return std::nullopt;
        const std::size_t i = next.fetch_add(1);
        return i < todo.size() ? std::optional<Chunk>(todo[i]) : std::nullopt;
    };
    auto body = [&](basis::HaarTransform<double>& haar) {
        while (const std::optional<Chunk> c = take()) {
            std::vector<LightResult> results;
            results.reserve(c->size());
            for (std::uint32_t l = c->begin; l < c->end && !failed.load(); ++l) {
                results.push_back(detail::bake_one(s, media, plan, haar, l));
                std::lock_guard lock(mu);
                advance(1);
            }
            if (failed.load()) break;
            deliver(*c, std::move(results));
        }
    };
    // The calling thread serves the helpers (a message layer such as MPI is then called from
    // one thread only), polling every millisecond when idle. After a failure here it goes on
    // serving until every helper is released (no chunk is handed out any more), so the other
    // processes end with this one; only a failure of the messages themselves ends it at once.
    std::exception_ptr delivery_failure;
    std::function<void()> serve = [&] {
        const std::function<std::optional<Chunk>()> next_chunk = take;
        const std::function<void(Chunk, std::vector<LightResult> &&)> remote = [&](Chunk c,
                                                                                   std::vector<LightResult>&& r) {
            if (failed.load()) return;
            try {
                deliver(c, std::move(r));
                std::lock_guard lock(mu);
                advance(c.size());
            } catch (...) {
                if (!delivery_failure) delivery_failure = std::current_exception();
                failed = true;
            }
        };
        for (bool released = false; !released;) {
            bool busy = false;
            released = options.helpers->poll(next_chunk, remote, busy);
            if (!busy) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
    };
    run_team(plan, s, plan.threads, failed, body, options.helpers ? &serve : nullptr);
    if (delivery_failure) std::rethrow_exception(delivery_failure);

    check_and_sum(s, totals, n, rep);

    core::Stopwatch sw;
    if (checkpoint) checkpoint->copy_blocks(writer);
    writer.finish();
    if (checkpoint) checkpoint->remove();
    rep.seconds_write = sw.seconds();
    rep.file_bytes = std::filesystem::file_size(out);
    rep.compression_ratio = rep.file_bytes ? double(rep.raw_bytes) / double(rep.file_bytes) : 0.0;
    rep.seconds_total = total.seconds();
    return rep;
}

std::filesystem::path default_fgb_path(const scene::Scene& s) {
    if (s.path.empty()) return std::filesystem::path("scene.fgb");
    std::filesystem::path p = s.path;
    p.replace_extension(".fgb");
    return p;
}

bool up_to_date(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& fgb,
                std::string* why) {
    auto fail = [&](const std::string& m) {
        if (why) *why = m;
        return false;
    };
    std::error_code ec;
    if (!std::filesystem::exists(fgb, ec)) return fail(fgb.string() + ": no baked file");
    try {
        basis::FgbReader r(fgb);
        if (r.partial()) return fail(fgb.string() + ": a partial file (one bake job's lights), not a complete bake");
        r.check_metadata(expected_metadata(s, density));
    } catch (const core::Error& e) {
        return fail(e.what());
    }
    return true;
}

std::optional<Report> bake_if_stale(const scene::Scene& s, const core::Grid3<float>& density,
                                    const std::filesystem::path& fgb, const Progress& progress,
                                    const std::function<void(const std::string& why)>& on_stale) {
    std::string why;
    if (up_to_date(s, density, fgb, &why)) return std::nullopt;
    // Another process may be baking the same file (two fulgur-shot runs of one scene): wait
    // for it, then look again before baking.
    const core::FileLock lock(fgb);
    if (up_to_date(s, density, fgb, &why)) return std::nullopt;
    if (on_stale) on_stale(why);
    return bake(s, density, fgb, progress);
}

}  // namespace fulgur::bake
