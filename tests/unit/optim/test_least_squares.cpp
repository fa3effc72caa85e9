// Levenberg-Marquardt (optim/least_squares.hpp): it finds the least-squares
// solution of problems whose answer is known (a linear system, Rosenbrock's
// valley as residuals, a log-scaled exponential decay), stays inside the
// box when the unconstrained optimum lies outside it, and gives the same
// point for any thread count.

#include "flowvid/optim/least_squares.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstdio>

using namespace flowvid::optim;

TEST(LeastSquares, LinearProblemReachesTheNormalEquationsSolution) {
    // r = A x - b, 12 residuals, 3 unknowns on linear scales.
    Eigen::MatrixXd A(12, 3);
    Eigen::VectorXd b(12);
    for (int i = 0; i < 12; ++i) {
        const double t = 0.1 * i;
        A.row(i) << 1.0, t, t * t;
        b(i) = 0.3 - 1.2 * t + 0.7 * t * t + 0.01 * std::sin(7.0 * i);  // not exactly representable
    }
    const Eigen::VectorXd exact = A.colPivHouseholderQr().solve(b);
    const ParameterSpace space({{"c0", -5.0, 5.0}, {"c1", -5.0, 5.0}, {"c2", -5.0, 5.0}});
    LeastSquaresSettings settings;
    settings.max_evaluations = 200;
    settings.relative_tolerance = 1e-12;
    const LeastSquaresResult r = levenberg_marquardt(
        [&](const Eigen::VectorXd& x, int) -> Eigen::VectorXd { return A * x - b; }, space, Eigen::Vector3d::Zero(), settings);
    std::printf("[ measured ] linear: %d Jacobians, %lld evaluations, |x - x*| = %.2e\n", r.iterations, r.evaluations,
                (r.best_values - exact).norm());
    EXPECT_LT((r.best_values - exact).norm(), 1e-5);
    EXPECT_NEAR(r.best_value, (A * exact - b).squaredNorm(), 1e-9);
    EXPECT_LT(r.best_value, r.start_value);
}

TEST(LeastSquares, RosenbrockValleyAndTheBoxBoundary) {
    // Rosenbrock as residuals (10 (y - x^2), 1 - x): minimum at (1, 1).
    const auto rosenbrock = [](const Eigen::VectorXd& p, int) -> Eigen::VectorXd {
        return Eigen::Vector2d(10.0 * (p(1) - p(0) * p(0)), 1.0 - p(0));
    };
    LeastSquaresSettings settings;
    settings.max_evaluations = 400;
    settings.relative_tolerance = 1e-14;
    settings.difference_step = 1e-6;
    const LeastSquaresResult inside = levenberg_marquardt(rosenbrock, ParameterSpace({{"x", -2.0, 2.0}, {"y", -2.0, 3.0}}),
                                                          Eigen::Vector2d(-1.2, 1.0), settings);
    std::printf("[ measured ] Rosenbrock: (%.6f, %.6f) after %lld evaluations, E %.2e\n", inside.best_values(0),
                inside.best_values(1), inside.evaluations, inside.best_value);
    EXPECT_NEAR(inside.best_values(0), 1.0, 1e-3);
    EXPECT_NEAR(inside.best_values(1), 1.0, 2e-3);
    // With x <= 0.5 the constrained optimum is on the boundary, x = 0.5, y = 0.25.
    const LeastSquaresResult bounded = levenberg_marquardt(rosenbrock, ParameterSpace({{"x", -2.0, 0.5}, {"y", -2.0, 3.0}}),
                                                           Eigen::Vector2d(-1.2, 1.0), settings);
    EXPECT_LE(bounded.best_values(0), 0.5);
    EXPECT_NEAR(bounded.best_values(0), 0.5, 1e-3);
    EXPECT_NEAR(bounded.best_values(1), 0.25, 1e-2);
}

TEST(LeastSquares, LogScaledParametersAndAnyThreadCountGiveTheSamePoint) {
    // Decay y = a exp(-k t) sampled at 20 times, fitted with a and k on log scales.
    const auto decay = [](const Eigen::VectorXd& p, int) -> Eigen::VectorXd {
        Eigen::VectorXd r(20);
        for (int i = 0; i < 20; ++i) {
            const double t = 0.25 * i;
            r(i) = p(0) * std::exp(-p(1) * t) - 3.0 * std::exp(-0.8 * t);
        }
        return r;
    };
    const ParameterSpace space({{"a", 1e-2, 1e2, true}, {"k", 1e-3, 1e1, true}});
    LeastSquaresSettings settings;
    settings.max_evaluations = 300;
    settings.relative_tolerance = 1e-14;
    settings.threads = 1;
    const LeastSquaresResult one = levenberg_marquardt(decay, space, Eigen::Vector2d(0.5, 0.05), settings);
    settings.threads = 2;
    const LeastSquaresResult two = levenberg_marquardt(decay, space, Eigen::Vector2d(0.5, 0.05), settings);
    EXPECT_NEAR(one.best_values(0), 3.0, 1e-4);
    EXPECT_NEAR(one.best_values(1), 0.8, 1e-5);
    EXPECT_TRUE(one.best_values == two.best_values) << "the thread count changed the result";
    EXPECT_EQ(one.evaluations, two.evaluations);
}
