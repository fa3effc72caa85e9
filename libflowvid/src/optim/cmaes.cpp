#include "flowvid/optim/cmaes.hpp"

#include "flowvid/random.hpp"
#include "search_result.hpp"
#include "timing.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <vector>

namespace flowvid::optim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
using detail::Clock;
using detail::progress_message;
using detail::seconds_since;

// Standard normal numbers from the portable generator (Box-Muller, both
// numbers of a pair used), so the samples are the same on every platform.
class Gaussian {
public:
    explicit Gaussian(std::uint64_t seed) : m_random(seed) {}
    double next() {
        if (m_has_spare) {
            m_has_spare = false;
            return m_spare;
        }
        const double radius = std::sqrt(-2.0 * std::log(m_random.open_unit()));
        const double angle = 2.0 * 3.14159265358979323846 * m_random.open_unit();
        m_spare = radius * std::sin(angle);
        m_has_spare = true;
        return radius * std::cos(angle);
    }

private:
    Random m_random;
    double m_spare = 0.0;
    bool m_has_spare = false;
};

// Folds a coordinate back into [0, 1] by mirroring at the faces.
double reflect_into_unit(double u) {
    if (!std::isfinite(u)) return 0.5;
    double t = std::fmod(std::abs(u), 2.0);
    return t > 1.0 ? 2.0 - t : t;
}

}  // namespace

AnnealingResult cmaes(Evaluator& evaluator, const Eigen::VectorXd& start_unit, const CmaesSettings& settings,
                      double start_value) {
    const int n = evaluator.space().size();
    if (n < 1) throw std::invalid_argument("cmaes: the parameter space is empty");
    if (start_unit.size() != n) throw std::invalid_argument("cmaes: start has the wrong dimension");
    if (!(settings.initial_sigma > 0.0)) throw std::invalid_argument("cmaes: initial_sigma must be > 0");
    const Clock::time_point started = Clock::now();
    const long long before = evaluator.evaluations();

    // Strategy constants (Hansen's defaults).
    const int lambda = settings.population > 0 ? std::max(2, settings.population)
                                               : 4 + static_cast<int>(std::floor(3.0 * std::log(double(n))));
    const int mu = lambda / 2;
    Eigen::VectorXd weights(mu);
    for (int i = 0; i < mu; ++i) weights(i) = std::log(0.5 * (lambda + 1)) - std::log(double(i + 1));
    weights /= weights.sum();
    const double mu_eff = 1.0 / weights.squaredNorm();
    const double dn = static_cast<double>(n);
    const double c_sigma = (mu_eff + 2.0) / (dn + mu_eff + 5.0);
    const double d_sigma = 1.0 + 2.0 * std::max(0.0, std::sqrt((mu_eff - 1.0) / (dn + 1.0)) - 1.0) + c_sigma;
    const double c_c = (4.0 + mu_eff / dn) / (dn + 4.0 + 2.0 * mu_eff / dn);
    const double c_1 = 2.0 / ((dn + 1.3) * (dn + 1.3) + mu_eff);
    const double c_mu = std::min(1.0 - c_1, 2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((dn + 2.0) * (dn + 2.0) + mu_eff));
    const double expected_norm = std::sqrt(dn) * (1.0 - 1.0 / (4.0 * dn) + 1.0 / (21.0 * dn * dn));

    Gaussian gaussian(settings.seed);
    Eigen::VectorXd mean = start_unit.unaryExpr([](double u) { return std::clamp(u, 0.0, 1.0); });
    double sigma = settings.initial_sigma;
    Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(n, n);
    Eigen::MatrixXd basis = Eigen::MatrixXd::Identity(n, n);  // eigenvectors of C
    Eigen::VectorXd scales = Eigen::VectorXd::Ones(n);        // square roots of its eigenvalues
    Eigen::VectorXd path_sigma = Eigen::VectorXd::Zero(n), path_c = Eigen::VectorXd::Zero(n);

    AnnealingResult result;
    long long used = 0;
    double generation_seconds = 0.0;  // the slowest generation so far, per point evaluated
    Eigen::VectorXd best = mean;
    double best_value = start_value;
    AnnealingResult::Status status = AnnealingResult::Status::converged;
    const auto out_of_time = [&](long long points) {
        if (!(settings.budget_seconds > 0.0)) return false;
        const double per_point = generation_seconds > 0.0 ? generation_seconds : settings.evaluation_seconds_hint;
        return seconds_since(started) + per_point * static_cast<double>(points) > settings.budget_seconds;
    };
    if (std::isnan(best_value)) {
        if (out_of_time(1)) {
            status = AnnealingResult::Status::time_budget;
        } else {
            best_value = evaluator.evaluate(mean);
            ++used;
        }
    }
    if (!std::isfinite(best_value)) best_value = kInf;
    result.start_value = best_value;

    int generation = 0;
    int failed_generations = 0;  // in a row, every point +inf or NaN
    while (status == AnnealingResult::Status::converged) {
        if (settings.cancel && settings.cancel->load()) {
            status = AnnealingResult::Status::cancelled;
            break;
        }
        long long count = lambda;
        if (settings.max_evaluations > 0) count = std::min<long long>(count, settings.max_evaluations - used);
        if (count <= 0) {
            status = AnnealingResult::Status::max_evaluations;
            break;
        }
        // A generation runs as one batch: its wall time is about that of
        // ceil(count / threads) evaluations.
        const long long rounds = (count + evaluator.threads() - 1) / evaluator.threads();
        if (out_of_time(rounds)) {
            status = AnnealingResult::Status::time_budget;
            break;
        }
        // Sample (every z is drawn, whatever happens to the point, so the
        // random sequence does not depend on the objective).
        std::vector<Eigen::VectorXd> points(static_cast<std::size_t>(count));
        for (auto& point : points) {
            Eigen::VectorXd z(n);
            for (int i = 0; i < n; ++i) z(i) = gaussian.next();
            point = (mean + sigma * (basis * scales.cwiseProduct(z))).unaryExpr(&reflect_into_unit);
        }
        const Clock::time_point batch_started = Clock::now();
        const std::vector<double> values = evaluator.evaluate(points, settings.cancel);
        generation_seconds = std::max(generation_seconds, seconds_since(batch_started) / static_cast<double>(rounds));
        used += count;
        ++generation;
        for (std::size_t k = 0; k < points.size(); ++k)
            if (values[k] < best_value) {
                best_value = values[k];
                best = points[k];
            }
        result.history.push_back({used, sigma, best_value});
        if (settings.cancel && settings.cancel->load()) {
            status = AnnealingResult::Status::cancelled;
            break;
        }
        if (settings.progress) {
            const double elapsed_s = seconds_since(started);
            const double left = settings.max_evaluations > 0 ? double(settings.max_evaluations - used) : 0.0;
            double eta_s = left * elapsed_s / std::max<double>(1.0, double(used));
            if (settings.budget_seconds > 0.0) eta_s = std::min(eta_s, std::max(0.0, settings.budget_seconds - elapsed_s));
            const double fraction = elapsed_s + eta_s > 0.0 ? elapsed_s / (elapsed_s + eta_s) : 1.0;
            if (!settings.progress({"cmaes", fraction, progress_message(used, best_value, "sigma", sigma, eta_s)})) {
                status = AnnealingResult::Status::cancelled;
                break;
            }
        }
        if (count < lambda) {  // the budget's remainder: no update from a cut generation
            status = AnnealingResult::Status::max_evaluations;
            break;
        }

        // Rank (failed evaluations, +inf or NaN, last; ties by sample order).
        std::vector<int> order(static_cast<std::size_t>(lambda));
        std::iota(order.begin(), order.end(), 0);
        const auto key = [&](int k) { return std::isnan(values[std::size_t(k)]) ? kInf : values[std::size_t(k)]; };
        std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return key(a) < key(b); });
        if (!std::isfinite(key(order[0]))) {  // nothing to learn from: sample again, a few times
            if (++failed_generations >= 10) break;
            continue;
        }
        failed_generations = 0;

        // Steps of the repaired points (what was evaluated), in units of sigma.
        Eigen::MatrixXd steps(n, mu);
        for (int i = 0; i < mu; ++i) steps.col(i) = (points[std::size_t(order[std::size_t(i)])] - mean) / sigma;
        const Eigen::VectorXd mean_step = steps * weights;
        mean += sigma * mean_step;

        // C^(-1/2) times the mean step, for the step-size path.
        const Eigen::VectorXd whitened = basis * (basis.transpose() * mean_step).cwiseQuotient(scales);
        path_sigma = (1.0 - c_sigma) * path_sigma + std::sqrt(c_sigma * (2.0 - c_sigma) * mu_eff) * whitened;
        const double path_norm = path_sigma.norm();
        const double correction = std::sqrt(1.0 - std::pow(1.0 - c_sigma, 2.0 * generation));
        const bool stalled = path_norm / correction >= (1.4 + 2.0 / (dn + 1.0)) * expected_norm;
        const double h_sigma = stalled ? 0.0 : 1.0;
        path_c = (1.0 - c_c) * path_c + h_sigma * std::sqrt(c_c * (2.0 - c_c) * mu_eff) * mean_step;

        Eigen::MatrixXd rank_mu = Eigen::MatrixXd::Zero(n, n);
        for (int i = 0; i < mu; ++i) rank_mu += weights(i) * steps.col(i) * steps.col(i).transpose();
        covariance = (1.0 - c_1 - c_mu) * covariance +
                     c_1 * (path_c * path_c.transpose() + (1.0 - h_sigma) * c_c * (2.0 - c_c) * covariance) +
                     c_mu * rank_mu;
        sigma *= std::exp((c_sigma / d_sigma) * (path_norm / expected_norm - 1.0));
        sigma = std::min(sigma, 1.0);  // steps beyond the cube's size only reflect

        covariance = 0.5 * (covariance + covariance.transpose());
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(covariance);
        basis = eigen.eigenvectors();
        scales = eigen.eigenvalues().cwiseMax(1e-20).cwiseSqrt();

        // Converged: the distribution is smaller than the tolerance, or the
        // whole generation sits within the tolerance of the best value.
        if (sigma * scales.maxCoeff() < settings.step_tolerance) break;
        const double spread = key(order.back()) - key(order.front());
        if (std::isfinite(spread) && spread <= settings.tolerance * (std::abs(best_value) + 1e-12)) break;
    }

    detail::close_result(result, status, best, best_value, evaluator.space());
    result.evaluations = evaluator.evaluations() - before;
    result.iterations = generation;
    result.stages = generation;
    result.initial_temperature = settings.initial_sigma;
    result.final_temperature = sigma;
    result.elapsed_s = seconds_since(started);
    return result;
}

}  // namespace flowvid::optim
