#include "flowvid/optim/least_squares.hpp"

#include "timing.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/thread_pool.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace flowvid::optim {

const char* status_name(LeastSquaresResult::Status status) {
    switch (status) {
        case LeastSquaresResult::Status::converged: return "converged";
        case LeastSquaresResult::Status::max_evaluations: return "max_evaluations";
        case LeastSquaresResult::Status::time_budget: return "time_budget";
        case LeastSquaresResult::Status::cancelled: return "cancelled";
        case LeastSquaresResult::Status::no_progress: return "no_progress";
    }
    return "?";
}

namespace {

using Clock = std::chrono::steady_clock;

Eigen::VectorXd clamp_unit(Eigen::VectorXd u) { return u.cwiseMax(0.0).cwiseMin(1.0); }

}  // namespace

LeastSquaresResult levenberg_marquardt(const ResidualFunction& residuals, const ParameterSpace& space,
                                       const Eigen::VectorXd& start_values, const LeastSquaresSettings& settings) {
    const Clock::time_point started = Clock::now();
    const int n = space.size();
    const int threads =
        resolve_thread_count(settings.threads);
    ThreadPool pool(threads);
    LeastSquaresResult result;
    auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - started).count(); };
    auto stop = [&](LeastSquaresResult::Status& status) {
        if (settings.cancel && settings.cancel->load()) {
            status = LeastSquaresResult::Status::cancelled;
            return true;
        }
        if (result.evaluations >= settings.max_evaluations) {
            status = LeastSquaresResult::Status::max_evaluations;
            return true;
        }
        if (settings.budget_seconds > 0.0 && elapsed() >= settings.budget_seconds) {
            status = LeastSquaresResult::Status::time_budget;
            return true;
        }
        return false;
    };

    // The start is evaluated at exactly the values given (a round trip through
    // the unit cube moves them by an ulp, and a chaotic objective notices).
    const Eigen::VectorXd start = space.clamp_values(start_values);
    Eigen::VectorXd x = clamp_unit(space.to_unit(start));
    Eigen::VectorXd x_values = start;
    Eigen::VectorXd r = residuals(start, threads);
    ++result.evaluations;
    if (!r.allFinite()) throw std::invalid_argument("levenberg_marquardt: the start's residuals are not finite");
    double value = r.squaredNorm();
    result.start_value = value;
    double lambda = settings.initial_damping;
    const double h = settings.difference_step;
    result.status = LeastSquaresResult::Status::converged;

    while (!stop(result.status)) {
        // Forward differences, one column per parameter, in parallel (each
        // call on one thread): columns land in fixed slots, so the thread
        // count does not change the result. A step that would leave the cube
        // goes the other way.
        if (result.evaluations + n > settings.max_evaluations) {
            result.status = LeastSquaresResult::Status::max_evaluations;
            break;
        }
        Eigen::MatrixXd J(r.size(), n);
        std::vector<Eigen::VectorXd> columns(static_cast<std::size_t>(n));
        pool.run(static_cast<std::size_t>(n), [&](std::size_t j, int) {
            Eigen::VectorXd xj = x;
            const double step = x(static_cast<Eigen::Index>(j)) + h <= 1.0 ? h : -h;
            xj(static_cast<Eigen::Index>(j)) += step;
            columns[j] = (residuals(space.to_values(xj), 1) - r) / step;
        });
        result.evaluations += n;
        ++result.iterations;
        for (int j = 0; j < n; ++j) {
            const Eigen::VectorXd& c = columns[static_cast<std::size_t>(j)];
            if (c.size() != r.size()) throw std::invalid_argument("levenberg_marquardt: residual length changed");
            J.col(j) = c.allFinite() ? c : Eigen::VectorXd::Zero(r.size());  // a failed neighbour: no slope known
        }
        const Eigen::MatrixXd JtJ = J.transpose() * J;
        const Eigen::VectorXd g = J.transpose() * r;
        Eigen::VectorXd scale = JtJ.diagonal().cwiseMax(1e-12 * std::max(1.0, JtJ.diagonal().maxCoeff()));

        // Damped steps until one lowers E (one evaluation each).
        bool accepted = false;
        double improvement = 0.0;
        for (int attempt = 0; attempt < 12 && !stop(result.status); ++attempt) {
            Eigen::MatrixXd A = JtJ;
            A.diagonal() += lambda * scale;
            const Eigen::VectorXd delta = A.ldlt().solve(-g);
            const Eigen::VectorXd x_new = clamp_unit(x + delta);
            if ((x_new - x).norm() < 1e-12) break;
            const Eigen::VectorXd r_new = residuals(space.to_values(x_new), threads);
            ++result.evaluations;
            const double value_new = r_new.allFinite() ? r_new.squaredNorm() : std::numeric_limits<double>::infinity();
            if (value_new < value) {
                improvement = (value - value_new) / value;
                x = x_new;
                x_values = space.to_values(x_new);
                r = r_new;
                value = value_new;
                lambda = std::max(lambda / 3.0, 1e-9);
                accepted = true;
                break;
            }
            lambda *= 4.0;
        }
        if (settings.progress &&
            !settings.progress({"least squares",
                                settings.max_evaluations > 0
                                    ? std::min(1.0, static_cast<double>(result.evaluations) / settings.max_evaluations)
                                    : 0.0,
                                detail::progress_message(result.evaluations, value, "damping", lambda)})) {
            result.status = LeastSquaresResult::Status::cancelled;
            break;
        }
        if (!accepted) {
            if (result.status == LeastSquaresResult::Status::converged) result.status = LeastSquaresResult::Status::no_progress;
            break;
        }
        if (improvement < settings.relative_tolerance) {
            result.status = LeastSquaresResult::Status::converged;
            break;
        }
    }
    result.best_unit = x;
    result.best_values = x_values;
    result.best_value = value;
    result.elapsed_s = elapsed();
    return result;
}

}  // namespace flowvid::optim
