#include "flowvid/rigid/optimize.hpp"
#include "flowvid/threads.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <thread>

namespace flowvid::rigid {

// ---- Threads -------------------------------------------------------------------------

void parallel_for(std::size_t count, int threads, const std::function<void(std::size_t, int)>& task) {
    int n = resolve_thread_count(threads);
    n = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(n), count));
    if (n <= 1) {
        for (std::size_t i = 0; i < count; ++i) task(i, 0);
        return;
    }
    std::atomic<std::size_t> next{0};
    std::exception_ptr failure;
    std::mutex failure_mutex;
    std::vector<std::thread> workers;
    for (int t = 0; t < n; ++t)
        workers.emplace_back([&, t] {
            for (std::size_t i = next++; i < count; i = next++) {
                try {
                    task(i, t);
                } catch (...) {
                    std::lock_guard<std::mutex> lock(failure_mutex);
                    if (!failure) failure = std::current_exception();
                }
            }
        });
    for (std::thread& w : workers) w.join();
    if (failure) std::rethrow_exception(failure);
}

// ---- Problem -------------------------------------------------------------------------

FlightProblem::FlightProblem(const SilhouetteModel& model, const std::vector<FrameObservation>& frames,
                             std::size_t begin, std::size_t end, SimulationSettings simulation)
    : m_model(&model), m_frames(&frames), m_begin(std::min(begin, frames.size())),
      m_end(std::clamp(end, m_begin, frames.size())), m_simulation(simulation) {
    for (std::size_t i = m_begin; i < m_end; ++i) m_times.push_back(frames[i].time_s);
}

std::vector<Pose> FlightProblem::poses(const FlightParameters& p) const {
    SimulationSettings simulation = m_simulation;
    simulation.sensitivities = false;
    const Trajectory t = simulate(m_model->body(), p, m_times, simulation);
    std::vector<Pose> out;
    for (const RigidState& s : t.states) out.push_back(Pose::of(s));
    return out;
}

double FlightProblem::cost(const FlightParameters& p, SilhouetteModel::Scratch& scratch,
                           std::vector<FrameCost>* frames) const {
    const std::vector<Pose> poses = this->poses(p);
    if (frames) frames->clear();
    double sum = 0.0;
    for (std::size_t i = 0; i < poses.size(); ++i) {
        const FrameCost c = m_model->edge_cost(poses[i], frame(i), scratch);
        sum += c.cost_px2;
        if (frames) frames->push_back(c);
    }
    return sum;
}

double FlightProblem::normal_equations(const FlightParameters& p, SilhouetteModel::Scratch& scratch,
                                       ParameterMatrix& JtJ, ParameterVector& Jtr) const {
    SimulationSettings simulation = m_simulation;
    simulation.sensitivities = true;
    const Trajectory t = simulate(m_model->body(), p, m_times, simulation);
    JtJ.setZero();
    Jtr.setZero();
    double sum = 0.0;
    for (std::size_t i = 0; i < t.states.size(); ++i) {
        PoseNormalEquations normal;
        sum += m_model->edge_cost(Pose::of(t.states[i]), frame(i), scratch, &normal).cost_px2;
        const PoseJacobian J = t.pose_jacobian(i);
        JtJ.noalias() += J.transpose() * normal.JtJ * J;
        Jtr.noalias() += J.transpose() * normal.Jtr;
    }
    return sum;
}

double FlightProblem::metric(const FlightParameters& p, HybridMetric metric, SilhouetteModel::Scratch& scratch) const {
    if (metric == HybridMetric::edge_distance) return cost(p, scratch);
    const std::vector<Pose> poses = this->poses(p);
    double sum = 0.0;
    for (std::size_t i = 0; i < poses.size(); ++i) sum += static_cast<double>(m_model->overlap(poses[i], frame(i), scratch).xor_px);
    return sum;
}

const char* status_name(OptimizerReport::Status status) {
    switch (status) {
        case OptimizerReport::Status::converged: return "converged";
        case OptimizerReport::Status::max_iterations: return "max_iterations";
        case OptimizerReport::Status::cancelled: return "cancelled";
        case OptimizerReport::Status::failed: return "failed";
    }
    return "unknown";
}

// ---- Levenberg-Marquardt ----------------------------------------------------------------

namespace {

// Solves (JtJ + lambda diag(JtJ)) delta = -Jtr over the free parameters.
template <int N>
Eigen::Matrix<double, N, 1> damped_step(const Eigen::Matrix<double, N, N>& JtJ, const Eigen::Matrix<double, N, 1>& Jtr,
                                        double lambda, const std::array<bool, N>& free) {
    std::vector<int> index;
    for (int i = 0; i < N; ++i)
        if (free[static_cast<std::size_t>(i)]) index.push_back(i);
    const int m = static_cast<int>(index.size());
    Eigen::MatrixXd A(m, m);
    Eigen::VectorXd b(m);
    double max_diagonal = 0.0;
    for (int i : index) max_diagonal = std::max(max_diagonal, JtJ(i, i));
    const double floor = 1e-12 * std::max(max_diagonal, 1e-30);
    for (int r = 0; r < m; ++r) {
        b[r] = -Jtr[index[static_cast<std::size_t>(r)]];
        for (int c = 0; c < m; ++c) A(r, c) = JtJ(index[static_cast<std::size_t>(r)], index[static_cast<std::size_t>(c)]);
        A(r, r) += lambda * std::max(A(r, r), floor) + floor;
    }
    const Eigen::VectorXd x = A.ldlt().solve(b);
    Eigen::Matrix<double, N, 1> delta = Eigen::Matrix<double, N, 1>::Zero();
    for (int r = 0; r < m; ++r) delta[index[static_cast<std::size_t>(r)]] = x[r];
    return delta;
}

}  // namespace

OptimizerResult levenberg_marquardt(const FlightProblem& problem, const FlightParameters& start, const LmSettings& settings,
                                    SilhouetteModel::Scratch& scratch) {
    OptimizerResult result;
    result.parameters = start;
    OptimizerReport& report = result.report;
    ParameterMatrix JtJ;
    ParameterVector Jtr;
    double cost = problem.normal_equations(start, scratch, JtJ, Jtr);
    report.cost_evaluations = 1;
    report.initial_cost = cost;
    if (!std::isfinite(cost)) {
        report.status = OptimizerReport::Status::failed;
        report.reason = "the cost at the start is not finite";
        report.final_cost = cost;
        return result;
    }
    double lambda = settings.initial_lambda;
    report.status = OptimizerReport::Status::max_iterations;
    for (report.iterations = 0; report.iterations < settings.max_iterations; ++report.iterations) {
        if (settings.progress &&
            !settings.progress({"optimize", static_cast<double>(report.iterations) / settings.max_iterations, {}})) {
            report.status = OptimizerReport::Status::cancelled;
            report.reason = "cancelled";
            break;
        }
        bool accepted = false;
        double decrease = 0.0;
        while (lambda < 1e10) {
            const ParameterVector delta = damped_step<kParameterCount>(JtJ, Jtr, lambda, settings.free);
            if (!delta.allFinite()) {
                lambda *= 10.0;
                continue;
            }
            const FlightParameters candidate = result.parameters.perturbed(delta);
            const double candidate_cost = problem.cost(candidate, scratch);
            ++report.cost_evaluations;
            if (std::isfinite(candidate_cost) && candidate_cost < cost) {
                decrease = (cost - candidate_cost) / std::max(cost, 1e-300);
                result.parameters = candidate;
                lambda = std::max(lambda * 0.3, 1e-9);
                accepted = true;
                break;
            }
            lambda *= 5.0;
        }
        if (!accepted) {
            report.status = OptimizerReport::Status::converged;
            report.reason = "no step lowers the cost (damping at its limit)";
            break;
        }
        cost = problem.normal_equations(result.parameters, scratch, JtJ, Jtr);
        ++report.cost_evaluations;
        if (decrease < settings.relative_tolerance) {
            report.status = OptimizerReport::Status::converged;
            report.reason = "relative decrease below tolerance";
            ++report.iterations;
            break;
        }
    }
    report.final_cost = cost;
    return result;
}

PoseFit fit_pose(const SilhouetteModel& model, const FrameObservation& frame, const Pose& start,
                 SilhouetteModel::Scratch& scratch, int max_iterations) {
    PoseFit fit;
    fit.pose = start;
    PoseNormalEquations normal;
    double cost = model.edge_cost(start, frame, scratch, &normal).cost_px2;
    double lambda = 1e-3;
    const std::array<bool, 6> free = {true, true, true, true, true, true};
    for (fit.iterations = 0; fit.iterations < max_iterations; ++fit.iterations) {
        bool accepted = false;
        double decrease = 0.0;
        while (lambda < 1e10) {
            const Eigen::Matrix<double, 6, 1> delta = damped_step<6>(normal.JtJ, normal.Jtr, lambda, free);
            const Pose candidate = fit.pose.perturbed(delta);
            const double c = model.edge_cost(candidate, frame, scratch).cost_px2;
            if (delta.allFinite() && c < cost) {
                decrease = (cost - c) / std::max(cost, 1e-300);
                fit.pose = candidate;
                lambda = std::max(lambda * 0.3, 1e-9);
                accepted = true;
                break;
            }
            lambda *= 5.0;
        }
        if (!accepted) break;
        cost = model.edge_cost(fit.pose, frame, scratch, &normal).cost_px2;
        if (decrease < 1e-4) break;
    }
    fit.cost_px2 = cost;
    return fit;
}

// ---- The thesis's hybrid gradient descent -----------------------------------------------

namespace {

struct HybridGradient {
    double value = 0.0;
    ParameterVector gradient = ParameterVector::Zero();
    int evaluations = 0;
};

double frame_metric(const FlightProblem& problem, const Pose& pose, std::size_t i, HybridMetric metric,
                    SilhouetteModel::Scratch& scratch) {
    if (metric == HybridMetric::edge_distance) return problem.model().edge_cost(pose, problem.frame(i), scratch).cost_px2;
    return static_cast<double>(problem.model().overlap(pose, problem.frame(i), scratch).xor_px);
}

HybridGradient hybrid_gradient_at(const FlightProblem& problem, const FlightParameters& p, const HybridSettings& s,
                                  SilhouetteModel::Scratch& scratch) {
    HybridGradient out;
    std::vector<double> times;
    for (std::size_t i = 0; i < problem.frame_count(); ++i) times.push_back(problem.frame(i).time_s);
    SimulationSettings simulation = problem.simulation();
    simulation.sensitivities = true;
    const Trajectory t = simulate(problem.model().body(), p, times, simulation);
    for (std::size_t i = 0; i < t.states.size(); ++i) {
        const Pose pose = Pose::of(t.states[i]);
        out.value += frame_metric(problem, pose, i, s.metric, scratch);
        // dE_k / d pose by central differences of the rendered metric (eq. 2.12).
        Eigen::Matrix<double, 1, 6> dE_dpose;
        for (int k = 0; k < 6; ++k) {
            const double h = k < 3 ? s.position_step_m : s.rotation_step_rad;
            Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
            d[k] = h;
            dE_dpose[k] = (frame_metric(problem, pose.perturbed(d), i, s.metric, scratch) -
                           frame_metric(problem, pose.perturbed(-d), i, s.metric, scratch)) /
                          (2.0 * h);
        }
        out.evaluations += 12;
        // Chain rule with the variational equations' d pose / d p (eq. 2.13).
        const PoseJacobian J = t.pose_jacobian(i);
        out.gradient.head<12>() += (dE_dpose * J.leftCols<12>()).transpose();
    }
    // Gravity by finite differences of the whole objective (eq. 2.14).
    for (int k = 12; k < 14; ++k) {
        if (!s.free[static_cast<std::size_t>(k)]) continue;
        ParameterVector d = ParameterVector::Zero();
        d[k] = s.gravity_step_rad;
        out.gradient[k] = (problem.metric(p.perturbed(d), s.metric, scratch) - problem.metric(p.perturbed(-d), s.metric, scratch)) /
                          (2.0 * s.gravity_step_rad);
        out.evaluations += 2;
    }
    for (int k = 0; k < kParameterCount; ++k)
        if (!s.free[static_cast<std::size_t>(k)]) out.gradient[k] = 0.0;
    return out;
}

}  // namespace

OptimizerResult hybrid_gradient(const FlightProblem& problem, const FlightParameters& start, const HybridSettings& s,
                                SilhouetteModel::Scratch& scratch) {
    OptimizerResult result;
    result.parameters = start;
    OptimizerReport& report = result.report;
    ParameterVector scale;
    scale << Eigen::Vector3d::Constant(s.position_scale_m), Eigen::Vector3d::Constant(s.rotation_scale_rad),
        Eigen::Vector3d::Constant(s.velocity_scale_m_per_s), Eigen::Vector3d::Constant(s.angular_velocity_scale_rad_per_s),
        s.gravity_scale_rad, s.gravity_scale_rad;

    HybridGradient g = hybrid_gradient_at(problem, start, s, scratch);
    report.cost_evaluations = g.evaluations;
    report.initial_cost = g.value;
    double value = g.value;
    double step = 1.0;  // in scaled units
    int small_steps = 0;
    report.status = OptimizerReport::Status::max_iterations;
    for (report.iterations = 0; report.iterations < s.max_iterations; ++report.iterations) {
        if (s.progress && !s.progress({"optimize", static_cast<double>(report.iterations) / s.max_iterations, {}})) {
            report.status = OptimizerReport::Status::cancelled;
            report.reason = "cancelled";
            break;
        }
        // p <- p - lambda dE/dp (eq. 2.8) in scaled coordinates, lambda by backtracking.
        const ParameterVector scaled = g.gradient.cwiseProduct(scale);
        const double norm = scaled.norm();
        if (!(norm > 0.0) || !std::isfinite(norm)) {
            report.status = OptimizerReport::Status::converged;
            report.reason = "zero gradient";
            break;
        }
        const ParameterVector direction = -scaled.cwiseProduct(scale) / norm;
        bool accepted = false;
        double trial = std::min(2.0 * step, 4.0);
        for (int halving = 0; halving < 14; ++halving, trial *= 0.5) {
            const FlightParameters candidate = result.parameters.perturbed(trial * direction);
            const double v = problem.metric(candidate, s.metric, scratch);
            ++report.cost_evaluations;
            if (std::isfinite(v) && v < value) {
                const double decrease = (value - v) / std::max(value, 1e-300);
                small_steps = decrease < s.relative_tolerance ? small_steps + 1 : 0;
                result.parameters = candidate;
                step = trial;
                accepted = true;
                break;
            }
        }
        if (!accepted) {
            report.status = OptimizerReport::Status::converged;
            report.reason = "no step along the gradient lowers the metric";
            break;
        }
        g = hybrid_gradient_at(problem, result.parameters, s, scratch);
        report.cost_evaluations += g.evaluations;
        value = g.value;
        if (small_steps >= 3) {
            report.status = OptimizerReport::Status::converged;
            report.reason = "relative decrease below tolerance";
            ++report.iterations;
            break;
        }
    }
    report.final_cost = value;
    return result;
}

}  // namespace flowvid::rigid
