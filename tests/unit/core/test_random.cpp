// The library's one random source (flowvid/random.hpp) gives the same numbers
// everywhere: its first values are pinned here against an independent
// implementation of xoshiro256** seeded by splitmix64 (Python, integers), so
// that any change to the generator or its distributions shows.

#include "flowvid/random.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

using flowvid::Random;

TEST(Random, FirstValuesArePinned) {
    Random random(42);
    EXPECT_EQ(random.next(), 0x15780b2e0c2ec716ull);
    EXPECT_EQ(random.next(), 0x6104d9866d113a7eull);
    EXPECT_EQ(random.next(), 0xae17533239e499a1ull);
    EXPECT_EQ(random.next(), 0xecb8ad4703b360a1ull);
    EXPECT_EQ(Random(42).uniform(), 0.08386297105988216);  // the top 53 bits of the first value
    Random digits(7);
    std::vector<std::uint64_t> drawn;
    for (int i = 0; i < 5; ++i) drawn.push_back(digits.below(10));
    EXPECT_EQ(drawn, (std::vector<std::uint64_t>{4, 4, 8, 4, 4}));
    Random gauss(1);  // Box-Muller: both values of the first pair
    EXPECT_DOUBLE_EQ(gauss.normal(), -0.8327414344656706);
    EXPECT_DOUBLE_EQ(gauss.normal(), -0.10752148995724745);
}

TEST(Random, DistributionsHaveTheirMomentsAndRanges) {
    Random random(2026);
    const int n = 200000;
    double sum = 0.0, sum_squares = 0.0, low = 1.0, high = -1.0;
    std::array<int, 6> counts{};
    for (int i = 0; i < n; ++i) {
        const double z = random.normal();
        sum += z;
        sum_squares += z * z;
        const double u = random.symmetric();
        low = std::min(low, u);
        high = std::max(high, u);
        ++counts[random.below(6)];
    }
    EXPECT_NEAR(sum / n, 0.0, 0.01);
    EXPECT_NEAR(sum_squares / n, 1.0, 0.01);
    EXPECT_GE(low, -1.0);
    EXPECT_LT(high, 1.0);
    EXPECT_LT(low, -0.999);
    EXPECT_GT(high, 0.999);
    for (int c : counts) EXPECT_NEAR(c, n / 6.0, 5.0 * std::sqrt(n / 6.0));
    EXPECT_GT(Random(3).open_unit(), 0.0);
}

TEST(Random, ShufflesAndSeedsAreTheSameEverywhere) {
    std::vector<int> order = {0, 1, 2, 3, 4, 5, 6, 7};
    Random(11).shuffle(order.begin(), order.end());
    std::vector<int> again = {0, 1, 2, 3, 4, 5, 6, 7};
    Random(11).shuffle(again.begin(), again.end());
    EXPECT_EQ(order, again);
    std::vector<int> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(sorted, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7}));  // a permutation
    // FNV-1a 64, its published values for "" and "a".
    EXPECT_EQ(flowvid::seed_from_text("", 0), 0xcbf29ce484222325ull);
    EXPECT_EQ(flowvid::seed_from_text("a", 1), 0xaf63dc4c8601ec8cull);
    EXPECT_NE(flowvid::derive_seed(5, 0), flowvid::derive_seed(5, 1));
}
