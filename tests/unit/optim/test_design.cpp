// Space-filling starts (thesis 2.4.5): the 4^n grid and a scrambled Halton
// design. Shows that on an objective of low effective dimension (a few
// parameters matter, as in cloth fits) Halton finds a better start with far
// fewer evaluations, and that on an isotropic one it is as good per point.

#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/design.hpp"
#include "flowvid/optim/test_functions.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>

using namespace flowvid::optim;

namespace {

double best_of(const TestFunction& f, const std::vector<Eigen::VectorXd>& points) {
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::VectorXd& u : points) best = std::min(best, f.f(f.space.to_values(u)));
    return best;
}

}  // namespace

TEST(Design, GridHasCellCentres) {
    const auto grid = grid_design(3, 4);
    ASSERT_EQ(grid.size(), 64u);
    std::set<double> values;
    for (const auto& p : grid)
        for (int d = 0; d < 3; ++d) values.insert(p(d));
    EXPECT_EQ(values, (std::set<double>{0.125, 0.375, 0.625, 0.875}));
    std::set<std::vector<double>> distinct;
    for (const auto& p : grid) distinct.insert({p(0), p(1), p(2)});
    EXPECT_EQ(distinct.size(), 64u);
    EXPECT_THROW(grid_design(12, 4), std::invalid_argument);  // 16.7 million points
}

// Scrambled Halton keeps the stratification of the sequence: the first b^k
// points put exactly one point in every interval [i / b^k, (i + 1) / b^k) of
// a dimension with base b. Deterministic for a seed, different across seeds.
TEST(Design, HaltonIsStratifiedAndSeeded) {
    const auto a = halton_design(5, 81, 7), b = halton_design(5, 81, 7), c = halton_design(5, 81, 8);
    ASSERT_EQ(a.size(), 81u);
    for (std::size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i], b[i]);
        EXPECT_TRUE(ParameterSpace::inside_unit_cube(a[i]));
        EXPECT_LT(a[i].maxCoeff(), 1.0);
    }
    EXPECT_NE(a[3], c[3]);
    auto strata = [&](int dimension, int count) {
        std::set<int> cells;
        for (int i = 0; i < count; ++i) cells.insert(static_cast<int>(std::floor(a[static_cast<std::size_t>(i)](dimension) * count)));
        return cells.size();
    };
    EXPECT_EQ(strata(0, 64), 64u);  // base 2
    EXPECT_EQ(strata(1, 81), 81u);  // base 3
    EXPECT_EQ(strata(2, 25), 25u);  // base 5
    EXPECT_THROW(halton_design(33, 4, 1), std::invalid_argument);
}

// The demonstration asked for by the thesis's 4^9-point search: on Rastrigin
// in 2 of 6 (and 8) dimensions, Halton with 1/64 of the grid's evaluations
// starts lower on average over 10 shifted instances, because the grid shows
// only 4 values of each coordinate. On plain 4-D Rastrigin the two are equal
// per point (within 25 %).
TEST(Design, HaltonFindsAsGoodAStartWithFarFewerEvaluations) {
    for (int n : {6, 8}) {
        const int grid_points = static_cast<int>(std::pow(4, n)), halton_points = grid_points / 64;
        double grid_sum = 0.0, halton_sum = 0.0;
        int halton_better = 0;
        for (std::uint64_t shift = 1; shift <= 10; ++shift) {
            const TestFunction f = rastrigin_low_dimensional(n, 2, shift);
            const double g = best_of(f, grid_design(n, 4));
            const double h = best_of(f, halton_design(n, halton_points, shift));
            grid_sum += g;
            halton_sum += h;
            halton_better += h <= g;
        }
        std::printf("[measured] rastrigin 2-in-%d: grid %d evaluations, mean best %.2f; halton %d evaluations, "
                    "mean best %.2f (better or equal in %d/10)\n",
                    n, grid_points, grid_sum / 10, halton_points, halton_sum / 10, halton_better);
        EXPECT_LT(halton_sum, grid_sum) << n;
        EXPECT_GE(halton_better, 7) << n;
    }
    double grid_sum = 0.0, halton_sum = 0.0;
    for (std::uint64_t shift = 1; shift <= 10; ++shift) {
        const TestFunction f = rastrigin(4, shift);
        grid_sum += best_of(f, grid_design(4, 4));
        halton_sum += best_of(f, halton_design(4, 256, shift));
    }
    std::printf("[measured] rastrigin 4-D, 256 points each: grid mean best %.2f, halton %.2f\n", grid_sum / 10,
                halton_sum / 10);
    EXPECT_NEAR(halton_sum / grid_sum, 1.0, 0.25);
}

TEST(Design, EvaluatesInParallelIntoFixedSlots) {
    const TestFunction f = ackley(3, 5);
    flowvid::ThreadPool pool(2);
    Evaluator evaluator([&](const Eigen::VectorXd& x, const EvaluationContext& context) {
        EXPECT_GE(context.worker, 0);
        EXPECT_LT(context.worker, 2);
        EXPECT_EQ(context.spare_threads, 1);
        return f.f(x);
    }, f.space, &pool);
    const auto points = halton_design(3, 100, 3);
    const DesignResult result = evaluate_design(evaluator, DesignKind::halton, points);
    ASSERT_EQ(result.values.size(), 100u);
    for (std::size_t i = 0; i < points.size(); ++i) EXPECT_EQ(result.values[i], f.f(f.space.to_values(points[i])));
    for (double v : result.values) EXPECT_GE(v, result.best_value());
    EXPECT_GT(result.spread(), 0.0);
    EXPECT_EQ(evaluator.evaluations(), 100);

    std::atomic<bool> cancel{true};
    const DesignResult cancelled = evaluate_design(evaluator, DesignKind::halton, points, &cancel);
    EXPECT_TRUE(cancelled.cancelled);
}
