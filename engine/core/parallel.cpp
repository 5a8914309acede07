#include "core/core.h"

#include <omp.h>

#include <atomic>
#include <string>

namespace fulgur::core {

namespace {
std::atomic<int> g_threads{0};  // 0: not set, use the hardware count
thread_local int t_threads = 0;  // ScopedThreadCount on this thread; 0: none
}  // namespace

int thread_count() noexcept {
    if (t_threads > 0) return t_threads;
    const int n = g_threads.load(std::memory_order_relaxed);
    return n > 0 ? n : omp_get_num_procs();
}

ScopedThreadCount::ScopedThreadCount(int n) : previous_(t_threads) {
    FULGUR_ASSERT(n >= 1, "ScopedThreadCount: n must be >= 1");
    t_threads = n;
}

ScopedThreadCount::~ScopedThreadCount() { t_threads = previous_; }

void set_thread_count(int n) {
    if (n < 1) throw Error("threads", "thread count must be >= 1, got " + std::to_string(n));
    g_threads.store(n, std::memory_order_relaxed);
}

}  // namespace fulgur::core
