// The cloth worker pool: every task of every job runs exactly once, whoever
// claims it, also when the pool's threads outnumber the cores and jobs follow
// each other faster than the workers wake.

#include "flowvid/cloth/worker_pool.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

namespace fcd = flowvid::cloth::detail;

TEST(WorkerPool, EveryTaskOfEveryJobRunsExactlyOnce) {
    for (const int threads : {2, 3, 8}) {
        fcd::WorkerPool pool(threads);
        std::vector<int> runs(16, 0);
        long long wrong = 0;
        for (int job = 0; job < 20000; ++job) {
            const int count = 1 + job % 7;
            std::vector<std::atomic<int>> seen(static_cast<size_t>(count));
            for (auto& s : seen) s.store(0);
            pool.run(count, [&](int k) { seen[static_cast<size_t>(k)].fetch_add(1); });
            for (int k = 0; k < count; ++k) {
                const int n = seen[static_cast<size_t>(k)].load();
                if (n != 1) ++wrong;
                runs[static_cast<size_t>(k)] += n;
            }
        }
        EXPECT_EQ(wrong, 0) << threads << " threads";
        // Task 0 runs in every job, task 6 in one job of seven.
        EXPECT_EQ(runs[0], 20000);
        EXPECT_EQ(runs[6], 20000 / 7);
    }
}

TEST(WorkerPool, FinishesWhenABusyThreadCompetesForTheCores) {
    // Another thread spinning on every core: the caller claims the workers'
    // tasks when they are not scheduled, so every job still completes.
    std::atomic<bool> stop{false};
    std::vector<std::thread> busy;
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    for (unsigned c = 0; c < cores; ++c)
        busy.emplace_back([&] {
            while (!stop.load()) {
            }
        });
    fcd::WorkerPool pool(4);
    std::atomic<long long> sum{0};
    for (int job = 0; job < 2000; ++job) pool.run(4, [&](int k) { sum.fetch_add(k + 1); });
    stop.store(true);
    for (std::thread& t : busy) t.join();
    EXPECT_EQ(sum.load(), 2000LL * (1 + 2 + 3 + 4));
}
