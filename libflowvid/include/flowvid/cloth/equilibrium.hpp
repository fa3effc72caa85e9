#pragma once
// Static equilibrium: positions where the net force on every free vertex is
// zero, found by minimising the potential energy with a line-searched Newton
// method: Gauss-Newton steps (definite Hessian, factorised on meshes up to
// 40x40 with a step limit, inexact CG solves on larger ones; Levenberg shift
// if needed) while folds form, exact Newton steps (sparse LDL^T, whose pivots also tell that the Hessian is
// definite) near the minimum for quadratic convergence. Converges to a local minimum near the start: hung
// cloth has many, so the start (and SwatchOptions::initial_bow) picks one.

#include "flowvid/cloth/model.hpp"

#include <Eigen/Core>

#include <atomic>
#include <string>
#include <vector>

namespace flowvid::cloth {

// A soft pull of one vertex towards a plane through a measured point, for
// registering a drape to a measured surface: energy
// 0.5 stiffness (normal . (x - point))^2, so the vertex slides freely within
// the plane and the fabric's own energy decides where.
struct PlaneAnchor {
    int vertex = -1;
    Eigen::Vector3d point_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
    double stiffness_N_per_m = 0.0;
};

struct EquilibriumOptions {
    // Converged when every free vertex's net force is below this fraction of
    // its weight m g, or below residual_force_floor_N when that is > 0.
    double relative_residual_tolerance = 1e-8;
    double residual_force_floor_N = 0.0;
    // Soft fabrics need many: a fitted silk (bending 3.5e-9 N m) hung from
    // the flat start takes 450-500 iterations at 24x24 and 48x48, a few
    // seconds (400 refused its drape). Each iteration lowers the energy.
    int max_iterations = 2000;
    // Far from equilibrium the steps use the definite (Gauss-Newton) Hessian,
    // on meshes above factorised_max_free_vertices solved by CG to this
    // relative tolerance; near it, exact Newton steps
    // with a sparse LDL^T factorisation give quadratic convergence.
    double inexact_newton_tolerance = 1e-3;
    int cg_max_iterations = 500;
    // Meshes with up to this many free vertices solve the definite steps by
    // sparse LDL^T factorisation instead of CG. Soft fabrics make that
    // system ill-conditioned: CG stops at its iteration cap short of its
    // tolerance (480 of 500 iterations a step at 48x48), so its steps are
    // poorer and the solve needs more of them. Factorised, a fitted silk's
    // solve from the flat start takes 180 Newton iterations instead of 442,
    // and a fit's candidates settle 1.9x faster at 24x24 and 2.3x at 16x16
    // (flowvid_bench_equilibrium); a factorisation costs more than CG's
    // iterations as the mesh grows and breaks even near 40x40. 0: always CG.
    int factorised_max_free_vertices = 1600;
    // Factorised steps move no vertex further than this many mean rest edge
    // lengths (the line search starts from the shortened step). An exact
    // step can cross into another of a soft drape's many equilibria: without
    // the limit, the starts settled from the captures' scanned drapes (14, with
    // fitted presets) ended 1.1 mm further from the truth than CG's on
    // average; with it, 0.1 mm nearer (nearer in 9 of 14, by -6 to +5 mm).
    // 0: no limit.
    double factorised_max_step_edges = 1.0;
    // When set and true, the solve stops at the next iteration, not converged,
    // with EquilibriumReport::cancelled.
    const std::atomic<bool>* cancel = nullptr;
    // Extra energies minimised with the fabric's (none: the fabric's own
    // equilibrium). Anchors on fixed vertices are ignored; one on a vertex
    // the mesh does not have throws std::invalid_argument.
    std::vector<PlaneAnchor> anchors;
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
