// The library's one thread pool (flowvid/thread_pool.hpp): every index of
// every job runs exactly once, whoever claims it, also when the pool's
// threads outnumber the cores and jobs follow each other faster than the
// workers wake; a task's exception reaches the caller.

#include "flowvid/thread_pool.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include <stdexcept>

using flowvid::ThreadPool;

TEST(ThreadPool, EveryTaskOfEveryJobRunsExactlyOnce) {
    for (const int threads : {2, 3, 8}) {
        ThreadPool pool(threads);
        std::vector<int> runs(16, 0);
        long long wrong = 0;
        for (int job = 0; job < 20000; ++job) {
            const int count = 1 + job % 7;
            std::vector<std::atomic<int>> seen(static_cast<size_t>(count));
            for (auto& s : seen) s.store(0);
            pool.run(static_cast<std::size_t>(count), [&](std::size_t k, int) { seen[k].fetch_add(1); });
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

TEST(ThreadPool, FinishesWhenABusyThreadCompetesForTheCores) {
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
    ThreadPool pool(4);
    std::atomic<long long> sum{0};
    for (int job = 0; job < 2000; ++job) pool.run(4, [&](std::size_t k, int) { sum.fetch_add(static_cast<long long>(k) + 1); });
    stop.store(true);
    for (std::thread& t : busy) t.join();
    EXPECT_EQ(sum.load(), 2000LL * (1 + 2 + 3 + 4));
}

TEST(ThreadPool, SaysWhichWorkerRunsAnIndexAndPassesTheFirstErrorOn) {
    ThreadPool pool(2);
    EXPECT_EQ(pool.threads(), 2);
    std::vector<std::atomic<int>> hits(1000);
    std::atomic<int> bad_worker{0};
    for (int round = 0; round < 20; ++round)
        pool.run(hits.size(), [&](std::size_t i, int worker) {
            hits[i]++;
            if (worker < 0 || worker >= 2) bad_worker++;
        });
    for (auto& h : hits) EXPECT_EQ(h.load(), 20);
    EXPECT_EQ(bad_worker.load(), 0);
    // A throw on either thread reaches the caller, once the job is over.
    for (int round = 0; round < 50; ++round) {
        std::atomic<int> ran{0};
        EXPECT_THROW(pool.run(100,
                              [&](std::size_t i, int) {
                                  ran++;
                                  if (i == 37) throw std::runtime_error("boom");
                              }),
                     std::runtime_error);
        EXPECT_LE(ran.load(), 100);  // indices not started when it threw are skipped
    }
    // Still usable afterwards.
    std::atomic<int> count{0};
    pool.run(10, [&](std::size_t, int) { count++; });
    EXPECT_EQ(count.load(), 10);
}
