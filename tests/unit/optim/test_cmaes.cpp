// CMA-ES (optim/cmaes.hpp) against known minima: a rotated, ill-conditioned
// ellipsoid (the shape of a cloth fit's valley, where parameters trade off
// against each other) and Rosenbrock's curved valley, each against the
// annealing given the same evaluations; determinism across thread counts;
// the box, evaluation limit, cancellation and minimize's dispatch.

#include "flowvid/optim/cmaes.hpp"
#include "flowvid/thread_pool.hpp"

#include <gtest/gtest.h>

#include <Eigen/QR>

#include <atomic>
#include <cmath>

using namespace flowvid::optim;

namespace {

ParameterSpace unit_space(int n) {
    std::vector<Parameter> parameters;
    for (int i = 0; i < n; ++i) parameters.push_back({std::string(1, char('a' + i)), 0.0, 1.0, false});
    return ParameterSpace(parameters);
}

// sum_i 10^(k i / (n - 1)) (R (x - c))_i^2, with R a fixed random rotation
// and c inside the cube: minimum 0 at c, condition number 10^k.
struct Ellipsoid {
    Eigen::MatrixXd rotation;
    Eigen::VectorXd centre;
    Eigen::VectorXd scales;
    double operator()(const Eigen::VectorXd& x) const { return (scales.array() * (rotation * (x - centre)).array().square()).sum(); }
};

Ellipsoid ellipsoid(int n, double log_condition) {
    Ellipsoid e;
    Eigen::MatrixXd m(n, n);
    Eigen::VectorXd c(n);
    // Deterministic "random" numbers (the test's own, no library RNG).
    double s = 0.123;
    const auto next = [&s] {
        s = std::fmod(s * 9301.0 + 0.49297, 1.0);
        return s;
    };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) m(i, j) = next() - 0.5;
    for (int i = 0; i < n; ++i) c(i) = 0.3 + 0.4 * next();
    e.rotation = Eigen::HouseholderQR<Eigen::MatrixXd>(m).householderQ();
    e.centre = c;
    e.scales.resize(n);
    for (int i = 0; i < n; ++i) e.scales(i) = std::pow(10.0, log_condition * i / std::max(1, n - 1));
    return e;
}

// Rosenbrock on [0, 1]^n, shifted so its minimum (0) lies at 0.6 in every coordinate.
double rosenbrock(const Eigen::VectorXd& u) {
    double f = 0.0;
    for (int i = 0; i + 1 < u.size(); ++i) {
        const double x = 4.0 * (u(i) - 0.6) + 1.0, y = 4.0 * (u(i + 1) - 0.6) + 1.0;
        f += 100.0 * (y - x * x) * (y - x * x) + (1.0 - x) * (1.0 - x);
    }
    return f;
}

AnnealingResult run_cmaes(const std::function<double(const Eigen::VectorXd&)>& f, int n, long long evaluations, int threads = 1,
                          std::uint64_t seed = 1) {
    flowvid::ThreadPool pool(threads);
    Evaluator evaluator([&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f(x); }, unit_space(n), &pool);
    CmaesSettings s;
    s.seed = seed;
    s.initial_sigma = 0.2;
    s.max_evaluations = evaluations;
    s.step_tolerance = 1e-12;
    s.tolerance = 0.0;
    return cmaes(evaluator, Eigen::VectorXd::Constant(n, 0.5), s);
}

AnnealingResult run_annealing(const std::function<double(const Eigen::VectorXd&)>& f, int n, long long evaluations) {
    Evaluator evaluator([&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f(x); }, unit_space(n), nullptr);
    AnnealingSettings s;
    s.seed = 1;
    s.max_evaluations = evaluations;
    s.fit_schedule_to_budget = true;
    s.initial_step = 0.2;
    return anneal(evaluator, Eigen::VectorXd::Constant(n, 0.5), s);
}

}  // namespace

TEST(Cmaes, FindsTheMinimumOfARotatedIllConditionedEllipsoidWhereTheAnnealingStalls) {
    const int n = 10;
    const Ellipsoid e = ellipsoid(n, 4.0);  // condition 1e4
    const auto f = [&e](const Eigen::VectorXd& x) { return e(x); };
    const AnnealingResult c = run_cmaes(f, n, 6000);
    const AnnealingResult a = run_annealing(f, n, 6000);
    std::printf("ellipsoid 10-D, 6000 evaluations: CMA-ES %.3g (distance %.3g), annealing %.3g\n", c.best_value,
                (c.best_unit - e.centre).norm(), a.best_value);
    EXPECT_LT(c.best_value, 1e-10);  // the minimum is 0
    EXPECT_LT((c.best_unit - e.centre).norm(), 1e-4);
    EXPECT_LT(c.best_value, 1e-3 * a.best_value);
}

TEST(Cmaes, FollowsRosenbrocksCurvedValleyToItsMinimum) {
    const int n = 6;
    const AnnealingResult c = run_cmaes(rosenbrock, n, 8000);
    std::printf("Rosenbrock 6-D, 8000 evaluations: CMA-ES %.3g in %lld evaluations\n", c.best_value, c.evaluations);
    EXPECT_LT(c.best_value, 1e-8);
    EXPECT_NEAR(c.best_unit(0), 0.6, 1e-3);
    EXPECT_NEAR(c.best_unit(n - 1), 0.6, 1e-3);
}

TEST(Cmaes, SameSeedGivesBitIdenticalResultsForAnyThreadCount) {
    const Ellipsoid e = ellipsoid(6, 2.0);
    const auto f = [&e](const Eigen::VectorXd& x) { return e(x); };
    const AnnealingResult one = run_cmaes(f, 6, 600, 1);
    const AnnealingResult two = run_cmaes(f, 6, 600, 2);
    const AnnealingResult other_seed = run_cmaes(f, 6, 600, 2, 2);
    EXPECT_EQ(one.best_value, two.best_value);
    EXPECT_EQ(one.best_unit, two.best_unit);
    EXPECT_EQ(one.evaluations, two.evaluations);
    EXPECT_NE(one.best_value, other_seed.best_value);
}

TEST(Cmaes, StaysInTheBoxAndStopsAtTheEvaluationLimitAndOnCancel) {
    // The minimum lies outside the cube (at -1): the search must press
    // against the face x0 = 0 without ever evaluating outside.
    std::atomic<int> outside{0};
    const auto f = [&outside](const Eigen::VectorXd& x) {
        if (!ParameterSpace::inside_unit_cube(x)) ++outside;
        return (x.array() + 1.0).square().sum();
    };
    const AnnealingResult r = run_cmaes(f, 4, 203);
    EXPECT_EQ(outside.load(), 0);
    EXPECT_EQ(r.evaluations, 203);  // the start, then generations of 8, the last one cut
    EXPECT_EQ(r.status, AnnealingResult::Status::max_evaluations);
    EXPECT_LT(r.best_unit.maxCoeff(), 0.05);  // at the corner nearest the minimum

    Evaluator evaluator([&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f(x); }, unit_space(4), nullptr);
    CmaesSettings s;
    int generations = 0;
    s.progress = [&generations](const flowvid::ProgressReport& p) {
        EXPECT_EQ(p.stage, "cmaes");
        EXPECT_EQ(p.message.rfind(std::to_string(1 + 8 * (generations + 1)) + " evaluations", 0), 0u) << p.message;
        return ++generations < 3;
    };
    const AnnealingResult cancelled = cmaes(evaluator, Eigen::VectorXd::Constant(4, 0.5), s);
    EXPECT_EQ(cancelled.status, AnnealingResult::Status::cancelled);
    EXPECT_EQ(cancelled.evaluations, 1 + 3 * 8);  // 4 + floor(3 ln 4) = 8 per generation
}

TEST(Cmaes, MinimizeRunsItAfterTheDesignWithinTheSameEvaluations) {
    const int n = 8;
    const Ellipsoid e = ellipsoid(n, 3.0);
    const auto f = [&e](const Eigen::VectorXd& x, const EvaluationContext&) { return e(x); };
    MinimizeSettings s;
    s.design_points = 40;
    s.threads = 2;
    s.annealing.max_evaluations = 1500;
    s.method = SearchMethod::cmaes;
    const MinimizeResult c = minimize(f, unit_space(n), s);
    s.method = SearchMethod::annealing;
    s.annealing.fit_schedule_to_budget = true;
    const MinimizeResult a = minimize(f, unit_space(n), s);
    std::printf("minimize, ellipsoid 8-D, 1500 evaluations: CMA-ES %.3g, annealing %.3g\n", c.annealing.best_value,
                a.annealing.best_value);
    EXPECT_EQ(c.evaluations, 1500);
    EXPECT_LE(c.annealing.best_value, c.design.best_value());
    EXPECT_LT(c.annealing.best_value, 1e-3);
    EXPECT_LT(c.annealing.best_value, 1e-2 * a.annealing.best_value);
    EXPECT_STREQ(search_method_name(SearchMethod::cmaes), "cmaes");

    // A known point better than every design point (the fit's start) is
    // where CMA-ES starts; a worse one is ignored.
    s.method = SearchMethod::cmaes;
    s.cmaes_known_unit = e.centre + Eigen::VectorXd::Constant(n, 0.01);
    s.cmaes_known_value = e(s.cmaes_known_unit);
    ASSERT_LT(s.cmaes_known_value, c.design.best_value());
    const MinimizeResult known = minimize(f, unit_space(n), s);
    EXPECT_EQ(known.annealing.start_value, s.cmaes_known_value);
    s.cmaes_known_value = 2.0 * c.design.best_value();
    EXPECT_EQ(minimize(f, unit_space(n), s).annealing.start_value, c.design.best_value());
}
