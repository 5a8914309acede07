#include "core/core.h"

#include <omp.h>

#include <atomic>
#include <string>

namespace fulgur::core {

namespace {
std::atomic<int> g_threads{0};  // 0: not set, use the hardware count
}

int thread_count() noexcept {
    const int n = g_threads.load(std::memory_order_relaxed);
    return n > 0 ? n : omp_get_num_procs();
}

void set_thread_count(int n) {
    if (n < 1) throw Error("threads", "thread count must be >= 1, got " + std::to_string(n));
    g_threads.store(n, std::memory_order_relaxed);
}

}  // namespace fulgur::core
