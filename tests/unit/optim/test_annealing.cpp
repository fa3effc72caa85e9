// Simulated annealing (downhill simplex + Metropolis fluctuations, thesis
// 2.4.5) against the plain downhill simplex on shifted multimodal functions,
// determinism across thread counts, limits, cancellation and progress, the
// variability analysis of table 2.2, and the parameter space and pool.

#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/test_functions.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <stdexcept>

using namespace flowvid::optim;

namespace {

Objective objective_of(const TestFunction& f) {
    return [&f](const Eigen::VectorXd& x, const EvaluationContext&) { return f.f(x); };
}

struct Outcome {
    int successes = 0;
    double mean_value = 0.0;
    double mean_evaluations = 0.0;
};

// Both methods start from the same Halton design (16 n points) on the same
// shifted instance; `temperature` < 0 is annealing, 0 the plain simplex.
Outcome run(TestFunction (*make)(int, std::uint64_t), int n, int instances, double temperature) {
    Outcome o;
    for (int i = 1; i <= instances; ++i) {
        const TestFunction f = make(n, static_cast<std::uint64_t>(i));
        MinimizeSettings s;
        s.threads = 1;
        s.annealing.seed = static_cast<std::uint64_t>(i);
        s.annealing.initial_temperature = temperature;
        s.annealing.max_evaluations = 30000;
        const MinimizeResult r = minimize(objective_of(f), f.space, s);
        o.successes += r.annealing.best_value < f.success_threshold;
        o.mean_value += r.annealing.best_value / instances;
        o.mean_evaluations += static_cast<double>(r.evaluations) / instances;
    }
    return o;
}

}  // namespace

TEST(ParameterSpace, MapsLinearAndLogBoundsAndReportsEveryProblem) {
    const ParameterSpace space({{"bend", 1e-7, 1e-3, true}, {"drag", 0.0, 10.0, false}});
    Eigen::VectorXd u(2);
    u << 0.5, 0.25;
    const Eigen::VectorXd v = space.to_values(u);
    EXPECT_NEAR(v(0), 1e-5, 1e-15);  // geometric middle of 1e-7 .. 1e-3
    EXPECT_DOUBLE_EQ(v(1), 2.5);
    EXPECT_NEAR((space.to_unit(v) - u).norm(), 0.0, 1e-12);
    EXPECT_EQ(space.index_of("drag"), 1);
    EXPECT_EQ(space.index_of("mass"), -1);
    try {
        ParameterSpace bad({{"a", 0.0, 1.0, true}, {"b", 2.0, 1.0, false}, {"a", 0.1, 1.0, false}});
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("'a': is searched in log space"), std::string::npos) << message;
        EXPECT_NE(message.find("'b': needs finite bounds"), std::string::npos) << message;
        EXPECT_NE(message.find("repeats a name"), std::string::npos) << message;
    }
}

// Ackley in 2-9 D (10 shifted instances each) and Rastrigin in 2 D: the
// annealer reaches the global minimum's basin more often than the plain
// simplex from the same starts; on Rastrigin in 4 and 6 D, whose ~11^n local
// minima defeat both most of the time, it ends far lower on average.
TEST(Annealing, FindsGlobalMinimaMoreReliablyThanPlainSimplex) {
    struct Case {
        TestFunction (*make)(int, std::uint64_t);
        const char* name;
        int n;
        int min_successes;  // of 10, for annealing
    };
    const Case cases[] = {{ackley, "ackley", 2, 10}, {ackley, "ackley", 4, 10}, {ackley, "ackley", 6, 10},
                          {ackley, "ackley", 9, 7},  {rastrigin, "rastrigin", 2, 9}};
    for (const Case& c : cases) {
        const Outcome sa = run(c.make, c.n, 10, -1.0), simplex = run(c.make, c.n, 10, 0.0);
        std::printf("[measured] %s %d-D: annealing %d/10 (mean %.3f, %.0f evaluations), simplex %d/10 (mean %.3f, "
                    "%.0f evaluations)\n",
                    c.name, c.n, sa.successes, sa.mean_value, sa.mean_evaluations, simplex.successes,
                    simplex.mean_value, simplex.mean_evaluations);
        EXPECT_GE(sa.successes, c.min_successes) << c.name << c.n;
        EXPECT_GT(sa.successes, simplex.successes) << c.name << c.n;
    }
    for (int n : {4, 6}) {
        const Outcome sa = run(rastrigin, n, 10, -1.0), simplex = run(rastrigin, n, 10, 0.0);
        std::printf("[measured] rastrigin %d-D: annealing %d/10 (mean %.3f, %.0f evaluations), simplex %d/10 "
                    "(mean %.3f, %.0f evaluations)\n",
                    n, sa.successes, sa.mean_value, sa.mean_evaluations, simplex.successes, simplex.mean_value,
                    simplex.mean_evaluations);
        EXPECT_LT(sa.mean_value, 0.6 * simplex.mean_value) << n;
        EXPECT_GE(sa.successes, simplex.successes) << n;
    }
}

// Same seed, 1 or 2 threads: bit-identical results and histories. The
// objective sees how many threads it may use itself.
TEST(Annealing, IsDeterministicForASeedWhateverTheThreadCount) {
    const TestFunction f = rastrigin_low_dimensional(5, 2, 3);
    MinimizeResult results[2];
    for (int threads : {1, 2}) {
        MinimizeSettings s;
        s.threads = threads;
        s.annealing.seed = 42;
        s.annealing.max_evaluations = 6000;
        std::atomic<int> max_spare{0};
        Objective objective = [&](const Eigen::VectorXd& x, const EvaluationContext& context) {
            int seen = max_spare.load();
            while (context.spare_threads > seen && !max_spare.compare_exchange_weak(seen, context.spare_threads)) {
            }
            return f.f(x);
        };
        results[threads - 1] = minimize(objective, f.space, s);
        EXPECT_EQ(max_spare.load(), threads);  // single evaluations may use every thread
    }
    const MinimizeResult &a = results[0], &b = results[1];
    EXPECT_EQ(a.design.values, b.design.values);
    EXPECT_EQ(a.annealing.best_value, b.annealing.best_value);
    EXPECT_EQ(a.annealing.best_values, b.annealing.best_values);
    EXPECT_EQ(a.evaluations, b.evaluations);
    EXPECT_EQ(a.annealing.iterations, b.annealing.iterations);
    ASSERT_EQ(a.annealing.history.size(), b.annealing.history.size());
    for (std::size_t i = 0; i < a.annealing.history.size(); ++i) {
        EXPECT_EQ(a.annealing.history[i].best_value, b.annealing.history[i].best_value);
        EXPECT_EQ(a.annealing.history[i].temperature, b.annealing.history[i].temperature);
    }
    // Another seed takes another path.
    MinimizeSettings s;
    s.threads = 1;
    s.annealing.seed = 43;
    s.annealing.max_evaluations = 6000;
    EXPECT_NE(minimize(objective_of(f), f.space, s).annealing.best_values, a.annealing.best_values);
}

TEST(Annealing, ReportsProgressAndStopsOnCancelAndLimits) {
    const TestFunction f = ackley(4, 2);
    flowvid::ThreadPool pool(1);
    Evaluator evaluator(objective_of(f), f.space, &pool);
    AnnealingSettings s;
    std::vector<flowvid::ProgressReport> seen;
    s.progress = [&](const flowvid::ProgressReport& p) {
        seen.push_back(p);
        return seen.size() < 5;  // cancel after the fifth stage
    };
    const Eigen::VectorXd start = Eigen::VectorXd::Constant(4, 0.3);
    const AnnealingResult r = anneal(evaluator, start, s);
    EXPECT_EQ(r.status, AnnealingResult::Status::cancelled);
    ASSERT_EQ(seen.size(), 5u);
    // One report per stage, each stage in the history: cooler, no worse, more evaluations.
    ASSERT_EQ(r.history.size(), seen.size());
    for (std::size_t i = 1; i < seen.size(); ++i) {
        EXPECT_LT(r.history[i].temperature, r.history[i - 1].temperature);
        EXPECT_LE(r.history[i].best_value, r.history[i - 1].best_value);
        EXPECT_GT(r.history[i].evaluations, r.history[i - 1].evaluations);
        EXPECT_EQ(seen[i].stage, "annealing");
        EXPECT_GT(seen[i].fraction, 0.0);
        EXPECT_LE(seen[i].fraction, 1.0);
        EXPECT_EQ(seen[i].message.rfind(std::to_string(r.history[i].evaluations) + " evaluations, best ", 0), 0u)
            << seen[i].message;
    }
    EXPECT_EQ(r.history.back().best_value, r.best_value);

    AnnealingSettings limited;
    limited.max_evaluations = 500;
    const AnnealingResult l = anneal(evaluator, start, limited);
    EXPECT_EQ(l.status, AnnealingResult::Status::max_evaluations);
    EXPECT_LE(l.evaluations, 500 + 4 + 1);  // a shrink may finish its batch
    EXPECT_LE(l.best_value, l.start_value);

    std::atomic<bool> cancel{true};
    AnnealingSettings flagged;
    flagged.cancel = &cancel;
    EXPECT_EQ(anneal(evaluator, start, flagged).status, AnnealingResult::Status::cancelled);

    // Everything infinite: reported, not thrown.
    Evaluator broken([](const Eigen::VectorXd&, const EvaluationContext&) { return std::nan(""); }, f.space);
    AnnealingSettings few;
    few.max_evaluations = 50;
    EXPECT_EQ(anneal(broken, start, few).status, AnnealingResult::Status::no_finite_value);
}

// Table 2.2 in miniature: a parameter the objective pins down (a, log space)
// varies little across runs from +-5 % starts; one it hardly sees (b) varies a lot.
TEST(Variability, SeparatesDeterminedFromUndeterminedParameters) {
    const ParameterSpace space({{"a", 1e-3, 1e3, true}, {"b", 1e-3, 1e3, true}});
    const Objective objective = [](const Eigen::VectorXd& x, const EvaluationContext&) {
        const double la = std::log10(x(0)) - 0.7, lb = std::log10(x(1)) + 1.0;
        return 100.0 * la * la + 1e-6 * lb * lb + 0.3 * std::sin(40.0 * la) * std::sin(40.0 * la);
    };
    VariabilitySettings s;
    s.runs = 5;
    s.threads = 2;
    s.annealing.max_evaluations = 800;
    s.annealing.seed = 11;
    Eigen::VectorXd start(2);
    start << 3.0, 30.0;
    const VariabilityReport report = variability_analysis(objective, space, start, s);
    ASSERT_EQ(report.runs.size(), 5u);
    ASSERT_EQ(report.parameters.size(), 2u);
    for (const Eigen::VectorXd& st : report.starts) {
        EXPECT_NEAR(st(0), 3.0, 0.15 + 1e-12);
        EXPECT_NEAR(st(1), 30.0, 1.5 + 1e-12);
    }
    std::printf("[measured] variability: a %.2f %% (mean %.4g), b %.2f %% (mean %.4g)\n",
                report.parameters[0].variability_percent, report.parameters[0].mean,
                report.parameters[1].variability_percent, report.parameters[1].mean);
    EXPECT_NEAR(report.parameters[0].mean, std::pow(10.0, 0.7), 0.05);
    EXPECT_LT(report.parameters[0].variability_percent, 1.0);
    EXPECT_GT(report.parameters[1].variability_percent, 10.0 * report.parameters[0].variability_percent);
    EXPECT_LE(report.best_value, report.worst_value);

    // The same analysis on one thread gives the same numbers.
    s.threads = 1;
    const VariabilityReport again = variability_analysis(objective, space, start, s);
    for (std::size_t i = 0; i < report.runs.size(); ++i)
        EXPECT_EQ(again.runs[i].best_values, report.runs[i].best_values);
}
