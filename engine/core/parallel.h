// fulgur::core — threads and time: OpenMP underneath (thread_count / set_thread_count, parallel_for),
// a scoped thread share, one background worker thread, and a stopwatch.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>

namespace fulgur::core {

/// Threads used by parallel regions (default: all hardware threads).
int thread_count() noexcept;
/// Sets the thread count for subsequent parallel regions (n >= 1).
void set_thread_count(int n);

/// For its lifetime, parallel regions started from the calling thread use n threads (n >= 1)
/// whatever set_thread_count says: a worker thread keeps its solves to its own share of the
/// cores. Nests (the innermost wins) and restores the previous value.
class ScopedThreadCount {
public:
    explicit ScopedThreadCount(int n);
    ~ScopedThreadCount();
    ScopedThreadCount(const ScopedThreadCount&) = delete;
    ScopedThreadCount& operator=(const ScopedThreadCount&) = delete;

private:
    int previous_;
};

/// One background thread that runs submitted jobs one at a time, in the order submitted,
/// each with its parallel regions kept to `threads` threads (ScopedThreadCount): the run
/// time's solves ahead of the frame (strikes, the sun) share the cores with the frame loop
/// this way. A job handles its own errors (an exception escaping a job is a programmer error
/// and terminates). Destruction lets the running job finish, drops queued ones and joins.
class Worker {
public:
    explicit Worker(int threads);
    ~Worker();
    Worker(const Worker&) = delete;
    Worker& operator=(const Worker&) = delete;

    /// Queues `job`. With `latest_only`, jobs queued and not yet started are dropped first:
    /// only the newest request matters (a sun that moved again before its solve began).
    void submit(std::function<void()> job, bool latest_only = false);
    /// While paused, no queued job starts; the running one finishes.
    void set_paused(bool paused);
    /// True while a job runs or is queued.
    bool busy() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Calls fn(i) for i in [begin, end) over thread_count() threads with a static schedule.
template <class F>
void parallel_for(std::int64_t begin, std::int64_t end, F&& fn) {
#pragma omp parallel for schedule(static) num_threads(thread_count())
    for (std::int64_t i = begin; i < end; ++i) fn(i);
}

/// Like parallel_for but with dynamic scheduling in chunks, for uneven work items.
template <class F>
void parallel_for_dynamic(std::int64_t begin, std::int64_t end, F&& fn, int chunk = 1) {
#pragma omp parallel for schedule(dynamic, chunk) num_threads(thread_count())
    for (std::int64_t i = begin; i < end; ++i) fn(i);
}

class Stopwatch {
public:
    Stopwatch() noexcept : start_(std::chrono::steady_clock::now()) {}
    void reset() noexcept { start_ = std::chrono::steady_clock::now(); }
    double seconds() const noexcept {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }
    double milliseconds() const noexcept { return seconds() * 1e3; }

private:
    std::chrono::steady_clock::time_point start_;
};

}  // namespace fulgur::core
