// One rule for every `threads` setting (flowvid/threads.hpp): a positive
// count as it is, 0 or less every core, never fewer than one.

#include "flowvid/threads.hpp"
#include "flowvid/thread_pool.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <thread>

TEST(Threads, APositiveCountIsTakenAsItIsAndZeroMeansEveryCore) {
    const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    EXPECT_EQ(flowvid::resolve_thread_count(1), 1);
    EXPECT_EQ(flowvid::resolve_thread_count(3), 3);
    EXPECT_EQ(flowvid::resolve_thread_count(64), 64);
    EXPECT_EQ(flowvid::resolve_thread_count(0), cores);
    EXPECT_EQ(flowvid::resolve_thread_count(-2), cores);
    // The thread pool follows the same rule.
    EXPECT_EQ(flowvid::ThreadPool(0).threads(), cores);
    EXPECT_EQ(flowvid::ThreadPool(2).threads(), 2);
}
