#pragma once
// Static equilibrium: positions where the net force on every free vertex is
// zero, found by minimising the potential energy with a line-searched Newton
// method: Gauss-Newton steps (definite Hessian, inexact CG solves, Levenberg
// shift if needed) while folds form, exact Newton steps (sparse LDL^T, whose
// pivots also tell that the Hessian is definite) near the minimum for
// quadratic convergence. Converges to a local minimum near the start: hung
// cloth has many, so the start (and SwatchOptions::initial_bow) picks one.

#include "flowvid/cloth/model.hpp"

#include <Eigen/Core>

#include <atomic>
#include <string>
#include <vector>

namespace flowvid::cloth {

struct EquilibriumOptions {
    // Converged when every free vertex's net force is below this fraction of
    // its weight m g, or below residual_force_floor_N when that is > 0.
    double relative_residual_tolerance = 1e-8;
    double residual_force_floor_N = 0.0;
    // Soft fabrics need many: a fitted silk (bending 3.5e-9 N m) hung from
    // the flat start takes 450-500 iterations at 24x24 and 48x48, a few
    // seconds (400 refused its drape). Each iteration lowers the energy.
    int max_iterations = 2000;
    // Far from equilibrium the steps use the definite (Gauss-Newton) Hessian
    // solved by CG to this relative tolerance; near it, exact Newton steps
    // with a sparse LDL^T factorisation give quadratic convergence.
    double inexact_newton_tolerance = 1e-3;
    int cg_max_iterations = 500;
    // When set and true, the solve stops at the next iteration, not converged,
    // with EquilibriumReport::cancelled.
    const std::atomic<bool>* cancel = nullptr;
};

struct EquilibriumReport {
    bool converged = false;
    int iterations = 0;
    long long cg_iterations = 0;
    double max_residual_force_N = 0.0;       // over free vertices
    double max_residual_over_weight = 0.0;   // max |f_i| / (m_i |g|)
    double potential_energy_J = 0.0;
    std::string reason;                      // why it stopped when not converged
    bool cancelled = false;                  // stopped by EquilibriumOptions::cancel
};

// `x` (3*#V) is the start and receives the result; vertices with fixed[i]
// keep their positions. Uses the conservative terms of the model (elastic,
// gravity, contacts); velocities are zero at rest, so damping and drag vanish.
// Resets the model's rest fold angles to 0 (bending memory belongs to the
// dynamic run that starts from this equilibrium).
EquilibriumReport solve_static_equilibrium(ClothModel& model, const std::vector<bool>& fixed, Eigen::VectorXd& x,
                                           const EquilibriumOptions& options = {});

}  // namespace flowvid::cloth
