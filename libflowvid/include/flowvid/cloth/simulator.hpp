#pragma once
// Time integration of a ClothModel with pinned vertices.
//
// Explicit: adaptive Runge-Kutta with an embedded error estimate (classic RK4
// with a 3rd-order FSAL estimate by default, as the thesis's adaptive 4th-order
// RK; Dormand-Prince 5(4) and Bogacki-Shampine 3(2) as options), step size
// controlled by absolute position and velocity tolerances; on stiff fabrics
// the controller settles at the stability limit. Its numerical damping is a
// fraction of the implicit methods' (measured in docs/cloth_model.md).
// Implicit: backward Euler or BDF2 with fixed substeps, Newton iterations (one
// by default, as Baraff and Witkin) solved by preconditioned conjugate
// gradients on the free vertices. Fast, but damps the motion.
//
// Expected numerical outcomes (blow-up, step collapse, cancel) are reported
// in SimulationReport, never thrown. The library never prints.

#include "flowvid/cloth/linear_solve.hpp"
#include "flowvid/cloth/model.hpp"
#include "flowvid/cloth/pins.hpp"
#include "flowvid/progress.hpp"

#include <Eigen/Core>

#include <atomic>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::cloth {

enum class Integrator {
    rk4_adaptive,        // classic RK4 with an embedded 3rd-order estimate (FSAL), the default
    dopri54,             // Dormand-Prince 5(4): accurate at tight tolerances, gains energy near its stability limit
    bogacki_shampine32,  // Bogacki-Shampine 3(2): cheaper steps, damps more
    implicit_euler,      // Baraff-Witkin backward Euler
    bdf2,                // second-order backward differences (less damping)
};
const char* integrator_name(Integrator integrator);
// The integrators by the short names the command line and its reports use
// (rk4, dopri54, bs32, implicit, bdf2).
const std::map<std::string, Integrator>& integrators_by_short_name();
const char* integrator_short_name(Integrator integrator);
// By its full name (integrator_name: "implicit_euler") or its short one
// ("implicit"); nullopt for neither.
std::optional<Integrator> integrator_from_name(const std::string& name);

struct SimulationSettings {
    Integrator integrator = Integrator::rk4_adaptive;
    unsigned force_terms = ForceTerm::all;
    // Explicit: RMS over free vertices of (error / tolerance) must stay <= 1.
    double position_tolerance_m = 1e-4;
    double velocity_tolerance_m_per_s = 1e-2;
    double initial_step_s = 1e-4;
    double min_step_s = 1e-8;       // below this the run ends with step_underflow
    double max_step_s = 1.0 / 60.0;
    // Implicit: steps per advance_to() call (a frame; more near contacts, so
    // that no vertex crosses half a contact layer in a step), Newton
    // iterations per step, CG.
    int implicit_substeps_per_frame = 5;
    int newton_iterations = 1;
    // CG stops at this residual relative to the right-hand side. 1e-3 moves
    // the 50-frame waving swatch by 0.8 mm RMS against 1e-5 (less than the
    // trial-to-trial spread of the captures) at half the cost.
    double cg_relative_tolerance = 1e-3;
    int cg_max_iterations = 400;
    // Symmetric Gauss-Seidel (SSOR in Eisenstat's form, sweeping the model's
    // fixed chunks in parallel): 2-3x fewer iterations than block Jacobi at
    // the same cost per iteration (docs/cloth_model.md, "Speed").
    Preconditioner cg_preconditioner = Preconditioner::symmetric_gauss_seidel;
    // Blow-up limits: speed and finiteness on every step, stretch on every frame.
    double max_speed_m_per_s = 100.0;
    double max_stretch_ratio = 5.0;
    // Worker threads for the element loops and the CG products (1 = none).
    // Results do not depend on this number: fixed chunks, summed in order.
    int threads = 1;
    // When set, the run ends as cancelled soon after *cancel becomes true
    // (checked every step, not only between frames: a frame can take
    // seconds at fine meshes). A flag, not a callback: it is read per step.
    const std::atomic<bool>* cancel = nullptr;
};

struct SimulationReport {
    enum class Status { ok, blew_up, step_underflow, cancelled };
    Status status = Status::ok;
    int frame = 0;        // 1-based: last frame completed (ok, cancelled) or the frame being computed
    double time_s = 0.0;  // simulation time when the run ended
    std::string reason;   // empty when ok
    bool ok() const { return status == Status::ok; }
};
const char* status_name(SimulationReport::Status status);

struct SimulationStatistics {
    long long steps = 0;
    long long rejected_steps = 0;
    long long force_evaluations = 0;
    long long jacobian_evaluations = 0;
    long long cg_iterations = 0;
    long long cg_not_converged = 0;
    double min_step_s = 0.0;
    double max_step_s = 0.0;
    double wall_time_s = 0.0;
};


class ClothSimulator {
public:
    ClothSimulator(ClothModel& model, std::vector<PinnedVertex> pins, SimulationSettings settings = {});
    ~ClothSimulator();
    ClothSimulator(const ClothSimulator&) = delete;
    ClothSimulator& operator=(const ClothSimulator&) = delete;

    // Pinned vertices are overwritten from their paths at `time_s`. Starts a
    // run: the model's rest fold angles (bending memory) are reset to 0; with
    // bend_memory_rate_per_s > 0 every accepted step then updates them
    // (ClothModel::update_rest_fold_angles).
    void set_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s);
    // Integrates to `time_s`, landing on it exactly. On failure the state is
    // the last good one and the report says why.
    SimulationReport advance_to(double time_s);

    const Eigen::VectorXd& positions() const { return m_x; }
    const Eigen::VectorXd& velocities() const { return m_v; }
    double time_s() const { return m_time; }
    const SimulationStatistics& statistics() const { return m_stats; }
    const std::vector<bool>& pinned_mask() const { return m_pinned; }
    ClothModel& model() { return m_model; }
    // Energy of the current state: kinetic + potential of the conservative terms.
    double total_energy();

private:
    struct Workspace;
    SimulationReport advance_explicit(double time_s);
    SimulationReport advance_implicit(double time_s);
    void apply_pins(Eigen::VectorXd& x, Eigen::VectorXd& v, double time_s) const;
    bool derivative(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& acceleration);
    void forces(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& force,
                BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode);
    std::string check_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const;

    ClothModel& m_model;
    std::vector<PinnedVertex> m_pins;
    std::vector<bool> m_pinned;
    SimulationSettings m_settings;
    Eigen::VectorXd m_x, m_v;
    Eigen::VectorXd m_x_previous, m_v_previous;  // BDF2 history
    bool m_have_previous = false;
    double m_previous_step = 0.0;
    double m_time = 0.0;
    double m_step = 0.0;
    double m_previous_error = 1e-4;
    SimulationStatistics m_stats;
    Workspace* m_work = nullptr;
};

// Per-frame output of a run: frames[k] holds the 3*#V positions at
// start_time + k / fps (frames[0] = the initial state).
struct SimulationResult {
    SimulationReport report;
    SimulationStatistics statistics;
    std::vector<Eigen::VectorXd> frames;
};

// Runs `frame_count` frames (the first is the initial state itself).
// Progress: stage "simulate" after each frame, fraction frames done of all,
// message "frame i/n"; false cancels (the report then says cancelled and the
// frames so far are kept).
SimulationResult simulate(ClothModel& model, const std::vector<PinnedVertex>& pins, const Eigen::VectorXd& x0,
                          const Eigen::VectorXd& v0, double start_time_s, double fps, int frame_count,
                          const SimulationSettings& settings, const Progress& progress = {});

}  // namespace flowvid::cloth
