#include "core/core.h"

#include <omp.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <string>
#include <thread>

namespace fulgur::core {

namespace {
std::atomic<int> g_threads{0};   // 0: not set, use the hardware count
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

struct Worker::Impl {
    const int threads;
    mutable std::mutex mu;
    std::condition_variable cv;
    std::deque<std::function<void()>> queue;
    bool running = false, paused = false, stop = false;
    std::thread thread;  // last: started once the members above exist

    explicit Impl(int n) : threads(n), thread([this] { run(); }) {}
    ~Impl() {
        {
            std::lock_guard<std::mutex> lock(mu);
            stop = true;
        }
        cv.notify_all();
        thread.join();
    }

    void run() {
        const ScopedThreadCount share(threads);
        for (;;) {
            std::function<void()> job;
            {
                std::unique_lock<std::mutex> lock(mu);
                running = false;
                cv.wait(lock, [&] { return stop || (!paused && !queue.empty()); });
                if (stop) return;
                job = std::move(queue.front());
                queue.pop_front();
                running = true;
            }
            job();
        }
    }
};

Worker::Worker(int threads) {
    FULGUR_ASSERT(threads >= 1, "Worker: threads must be >= 1");
    impl_ = std::make_unique<Impl>(threads);
}

Worker::~Worker() = default;

void Worker::submit(std::function<void()> job, bool latest_only) {
    FULGUR_ASSERT(job != nullptr, "Worker::submit: empty job");
    {
        std::lock_guard<std::mutex> lock(impl_->mu);
        if (latest_only) impl_->queue.clear();
        impl_->queue.push_back(std::move(job));
    }
    impl_->cv.notify_all();
}

void Worker::set_paused(bool paused) {
    {
        std::lock_guard<std::mutex> lock(impl_->mu);
        impl_->paused = paused;
    }
    impl_->cv.notify_all();
}

bool Worker::busy() const {
    std::lock_guard<std::mutex> lock(impl_->mu);
    return impl_->running || !impl_->queue.empty();
}

}  // namespace fulgur::core
