#pragma once
// Optimizers for the free-flight parameters (thesis 2.3.4).
//
// FlightProblem is the objective E(p) = sum over frames of E_k (eq. 2.7)
// with E_k the continuous edge distance of silhouette_residuals.hpp, over a
// window of observed frames. Two optimizers minimise it:
//
//  * levenberg_marquardt: our own LM (Eigen, Marquardt's diagonal scaling) on
//    the edge-distance residuals. d r / d p = (d r / d pose_k)(d pose_k / d p)
//    with d pose_k / d p from the variational equations (dynamics.hpp),
//    gravity included: the whole Jacobian is analytic.
//  * hybrid_gradient: the thesis's method: d q / d p analytic (variational
//    equations), d E / d q by finite differences of the rendered metric
//    (eq. 2.12), d E / d p_env (gravity) by finite differences of E (eq.
//    2.14), combined by the chain rule (eq. 2.13) and followed downhill
//    (eq. 2.8) with a backtracking line search on the step length. The
//    metric is the XOR count (eq. 2.5, what the thesis used) or the edge
//    distance.
//
// Expected numerical outcomes are reported, never thrown.

#include "flowvid/progress.hpp"
#include "flowvid/rigid/dynamics.hpp"
#include "flowvid/rigid/silhouette_residuals.hpp"

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace flowvid::rigid {

using ParameterMatrix = Eigen::Matrix<double, kParameterCount, kParameterCount>;
using ParameterMask = std::array<bool, kParameterCount>;  // true = free
inline constexpr ParameterMask kAllParameters = {true, true, true, true, true, true, true,
                                                 true, true, true, true, true, true, true};
// Everything but gravity (for short windows, where gravity is poorly seen).
inline constexpr ParameterMask kWithoutGravity = {true, true, true, true, true, true, true,
                                                  true, true, true, true, true, false, false};

enum class HybridMetric { xor_pixels, edge_distance };

class FlightProblem {
public:
    // Frames [begin, end) of `frames`; their time_s is relative to the
    // parameters' reference time. Keeps references: the model and frames
    // must outlive the problem.
    FlightProblem(const SilhouetteModel& model, const std::vector<FrameObservation>& frames, std::size_t begin,
                  std::size_t end, SimulationSettings simulation = {});

    std::size_t frame_count() const { return m_end - m_begin; }
    const FrameObservation& frame(std::size_t i) const { return (*m_frames)[m_begin + i]; }
    const SilhouetteModel& model() const { return *m_model; }
    const SimulationSettings& simulation() const { return m_simulation; }

    // Poses of the window's frames.
    std::vector<Pose> poses(const FlightParameters& p) const;
    // E (px^2) and, optionally, every frame's E_k.
    double cost(const FlightParameters& p, SilhouetteModel::Scratch& scratch,
                std::vector<FrameCost>* frames = nullptr) const;
    // E and its Gauss-Newton terms: JtJ and Jtr with E = sum r^2 (gradient 2 Jtr).
    double normal_equations(const FlightParameters& p, SilhouetteModel::Scratch& scratch, ParameterMatrix& JtJ,
                            ParameterVector& Jtr) const;
    // Sum over frames of the XOR count (eq. 2.5), or of E_k, for hybrid_gradient.
    double metric(const FlightParameters& p, HybridMetric metric, SilhouetteModel::Scratch& scratch) const;

private:
    const SilhouetteModel* m_model;
    const std::vector<FrameObservation>* m_frames;
    std::size_t m_begin;
    std::size_t m_end;
    SimulationSettings m_simulation;
    std::vector<double> m_times;
};

struct OptimizerReport {
    enum class Status { converged, max_iterations, cancelled, failed };
    Status status = Status::max_iterations;
    std::string reason;
    int iterations = 0;
    int cost_evaluations = 0;
    double initial_cost = 0.0;
    double final_cost = 0.0;
};
const char* status_name(OptimizerReport::Status status);

struct LmSettings {
    int max_iterations = 30;
    ParameterMask free = kAllParameters;
    double initial_lambda = 1e-3;
    // Converged when an accepted step lowers E by less than this fraction.
    double relative_tolerance = 1e-5;
    Progress progress;  // polled between iterations (stage "optimize"); false cancels
};

struct HybridSettings {
    int max_iterations = 200;
    ParameterMask free = kAllParameters;
    HybridMetric metric = HybridMetric::edge_distance;
    // Finite-difference steps for d E_k / d pose (eq. 2.12) and d E / d p_env (eq. 2.14).
    double position_step_m = 0.002;
    double rotation_step_rad = 0.01;
    double gravity_step_rad = 0.002;
    // Characteristic sizes of the parameters: the descent runs in p / scale.
    double position_scale_m = 0.01;
    double rotation_scale_rad = 0.05;
    double velocity_scale_m_per_s = 0.05;
    double angular_velocity_scale_rad_per_s = 0.5;
    double gravity_scale_rad = 0.01;
    double relative_tolerance = 1e-5;
    Progress progress;  // polled between iterations (stage "optimize"); false cancels
};

struct OptimizerResult {
    FlightParameters parameters;
    OptimizerReport report;
};

OptimizerResult levenberg_marquardt(const FlightProblem& problem, const FlightParameters& start,
                                    const LmSettings& settings, SilhouetteModel::Scratch& scratch);
OptimizerResult hybrid_gradient(const FlightProblem& problem, const FlightParameters& start,
                                const HybridSettings& settings, SilhouetteModel::Scratch& scratch);

// Refines one frame's pose alone (6 numbers) with the same LM: used to
// polish orientation candidates before they are paired into starts.
struct PoseFit {
    Pose pose;
    double cost_px2 = 0.0;
    int iterations = 0;
};
PoseFit fit_pose(const SilhouetteModel& model, const FrameObservation& frame, const Pose& start,
                 SilhouetteModel::Scratch& scratch, int max_iterations = 15);

// Runs task(i, thread) for i in [0, count) on `threads` threads (0 = the
// hardware's). Tasks must not depend on which thread runs them, so results
// are the same for any thread count.
void parallel_for(std::size_t count, int threads, const std::function<void(std::size_t task, int thread)>& task);

}  // namespace flowvid::rigid
