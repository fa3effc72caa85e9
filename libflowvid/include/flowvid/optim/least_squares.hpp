#pragma once
// Levenberg-Marquardt for objectives that are a sum of squares, E = |r(x)|^2
// (a fit to measured 3D tracks is one: r holds every seen point's distance).
// Where annealing needs hundreds of evaluations to settle in a basin, this
// polish converges in a few Jacobians: n + 1 evaluations each (forward
// differences, run in parallel), then steps that cost one evaluation.
//
// It works in the unit cube of a ParameterSpace (log parameters move in log
// space) and keeps every step inside it. Deterministic: the result does not
// depend on the thread count.

#include "flowvid/progress.hpp"
#include "flowvid/optim/parameter_space.hpp"

#include <Eigen/Core>

#include <atomic>
#include <functional>

namespace flowvid::optim {

// Residuals at parameter *values*; `threads` is what the call may use itself.
// Every call must return a vector of the same length (a failed simulation:
// large residuals, not a shorter vector).
using ResidualFunction = std::function<Eigen::VectorXd(const Eigen::VectorXd& values, int threads)>;

struct LeastSquaresSettings {
    long long max_evaluations = 200;
    double budget_seconds = 0.0;              // 0: none
    double difference_step = 1e-3;            // forward difference, unit-cube coordinates
    double initial_damping = 1e-3;            // lambda, relative to diag(J^T J)
    double relative_tolerance = 1e-4;         // stop when an accepted step lowers E by less than this share
    int threads = 0;                          // 0: all cores
    const std::atomic<bool>* cancel = nullptr;
    // After every iteration: stage "least squares", evaluations over
    // max_evaluations, "N evaluations, best |r|^2, damping lambda"; false stops.
    Progress progress;
};

struct LeastSquaresResult {
    enum class Status { converged, max_evaluations, time_budget, cancelled, no_progress };
    Status status = Status::converged;
    Eigen::VectorXd best_values;
    Eigen::VectorXd best_unit;
    double best_value = 0.0;  // |r|^2 at best_values
    double start_value = 0.0;
    long long evaluations = 0;
    int iterations = 0;       // Jacobians computed
    double elapsed_s = 0.0;
};
const char* status_name(LeastSquaresResult::Status status);

// Polishes `start_values` (clamped into the space). Throws
// std::invalid_argument for a start whose residuals are not finite.
LeastSquaresResult levenberg_marquardt(const ResidualFunction& residuals, const ParameterSpace& space,
                                       const Eigen::VectorXd& start_values, const LeastSquaresSettings& settings);

}  // namespace flowvid::optim
