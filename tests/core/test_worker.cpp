// core::Worker: the background thread the run time's ahead-of-frame solves share.
#include "core/core.h"

#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

using namespace fulgur;

namespace {

// Spins until `done` (the worker's jobs are asynchronous; no timing is asserted).
template <class F>
void wait_until(F done) {
    while (!done()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

}  // namespace

TEST_CASE("Worker runs jobs in the order submitted, on its own share of threads") {
    core::Worker w(1);
    std::mutex mu;
    std::vector<int> order;
    std::vector<int> threads;
    for (int i = 0; i < 20; ++i)
        w.submit([&, i] {
            std::lock_guard<std::mutex> lock(mu);
            order.push_back(i);
            threads.push_back(core::thread_count());
        });
    wait_until([&] { return !w.busy(); });
    std::vector<int> expected(20);
    for (int i = 0; i < 20; ++i) expected[std::size_t(i)] = i;
    CHECK(order == expected);
    for (int t : threads) CHECK(t == 1);
}

TEST_CASE("Worker: latest_only drops queued jobs, never the running one") {
    core::Worker w(1);
    std::promise<void> release;
    std::shared_future<void> gate = release.get_future().share();
    std::atomic<bool> started{false};
    std::vector<int> ran;
    std::mutex mu;
    w.submit([&] {
        started = true;
        gate.wait();
        std::lock_guard<std::mutex> lock(mu);
        ran.push_back(0);
    });
    wait_until([&] { return started.load(); });
    for (int i = 1; i <= 3; ++i)
        w.submit(
            [&, i] {
                std::lock_guard<std::mutex> lock(mu);
                ran.push_back(i);
            },
            /*latest_only=*/true);
    CHECK(w.busy());
    release.set_value();
    wait_until([&] { return !w.busy(); });
    CHECK(ran == std::vector<int>{0, 3});
}

TEST_CASE("Worker: paused, nothing starts; resumed, the queue runs") {
    core::Worker w(1);
    w.set_paused(true);
    std::atomic<int> count{0};
    for (int i = 0; i < 3; ++i) w.submit([&] { ++count; });
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    CHECK(count.load() == 0);
    CHECK(w.busy());  // queued jobs count as busy
    w.set_paused(false);
    wait_until([&] { return !w.busy(); });
    CHECK(count.load() == 3);
}

TEST_CASE("Worker: destruction drops queued jobs and joins") {
    std::atomic<int> count{0};
    {
        core::Worker w(1);
        w.set_paused(true);
        for (int i = 0; i < 5; ++i) w.submit([&] { ++count; });
    }
    CHECK(count.load() == 0);
}
