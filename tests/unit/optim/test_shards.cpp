// A minimize() split into shards for a farm (MinimizeSettings::shard_index /
// shard_count, docs/farm.md): together the shards evaluate exactly the
// design of the unsharded search, each anneals on its own seed with the
// annealing evaluations of a whole search, and the split does not depend on
// threads.

#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/test_functions.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <vector>

using namespace flowvid::optim;

namespace {

MinimizeSettings settings_for(int shard, int count, int threads) {
    MinimizeSettings s;
    s.design_points = 20;
    s.threads = threads;
    s.annealing.seed = 11;
    s.annealing.max_evaluations = 120;
    s.shard_index = shard;
    s.shard_count = count;
    return s;
}

bool same_point(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return a.size() == b.size() && a == b; }

}  // namespace

TEST(MinimizeShards, TogetherTheyEvaluateExactlyTheWholeDesign) {
    const TestFunction f = rastrigin(3, 4);
    const Objective objective = [&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f.f(x); };
    const MinimizeResult whole = minimize(objective, f.space, settings_for(0, 0, 1));
    ASSERT_EQ(whole.design.points.size(), 20u);
    EXPECT_EQ(whole.design_points_total, 20);

    std::vector<MinimizeResult> shards;
    for (int i = 1; i <= 3; ++i) shards.push_back(minimize(objective, f.space, settings_for(i, 3, 1)));
    // Shard i has points i-1, i-1+3, ... of the same design, with the same values.
    for (int i = 0; i < 3; ++i) {
        const MinimizeResult& s = shards[static_cast<std::size_t>(i)];
        EXPECT_EQ(s.design_points_total, 20);
        ASSERT_EQ(s.design.points.size(), static_cast<std::size_t>((20 - i + 2) / 3)) << "shard " << i + 1;
        for (std::size_t k = 0; k < s.design.points.size(); ++k) {
            const std::size_t at = static_cast<std::size_t>(i) + 3 * k;
            EXPECT_TRUE(same_point(s.design.points[k], whole.design.points[at])) << "shard " << i + 1 << " point " << k;
            EXPECT_EQ(s.design.values[k], whole.design.values[at]);
        }
        // Each anneals for the whole search's annealing evaluations (120 - 20), not more.
        EXPECT_LE(s.annealing.evaluations, 100) << "shard " << i + 1;
        EXPECT_LE(s.annealing.best_value, s.design.best_value());
    }
    // The best design point of the whole search is the best of one of the shards.
    double best_of_shards = shards[0].design.best_value();
    for (const MinimizeResult& s : shards) best_of_shards = std::min(best_of_shards, s.design.best_value());
    EXPECT_EQ(best_of_shards, whole.design.best_value());
    // Independent restarts: the shards' annealing seeds differ, so their searches do.
    EXPECT_FALSE(same_point(shards[0].annealing.best_unit, shards[1].annealing.best_unit));
}

TEST(MinimizeShards, AShardDoesNotDependOnThreads) {
    const TestFunction f = ackley(4, 2);
    const Objective objective = [&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f.f(x); };
    const MinimizeResult one = minimize(objective, f.space, settings_for(2, 4, 1));
    const MinimizeResult two = minimize(objective, f.space, settings_for(2, 4, 2));
    EXPECT_TRUE(same_point(one.annealing.best_values, two.annealing.best_values));
    EXPECT_EQ(one.annealing.best_value, two.annealing.best_value);
    EXPECT_EQ(one.evaluations, two.evaluations);
}

TEST(MinimizeShards, RefusesImpossibleSplits) {
    const TestFunction f = rastrigin(2, 1);
    const Objective objective = [&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f.f(x); };
    EXPECT_THROW(minimize(objective, f.space, settings_for(4, 3, 1)), std::invalid_argument);
    EXPECT_THROW(minimize(objective, f.space, settings_for(0, 3, 1)), std::invalid_argument);
    EXPECT_THROW(minimize(objective, f.space, settings_for(1, 21, 1)), std::invalid_argument);  // more shards than points
}
