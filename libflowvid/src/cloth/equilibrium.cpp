#include "flowvid/cloth/equilibrium.hpp"

#include "flowvid/cloth/linear_solve.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace flowvid::cloth {

namespace {

constexpr unsigned kStaticTerms = ForceTerm::conservative;

struct Residual {
    double max_force = 0.0;
    double max_over_weight = 0.0;
    double norm = 0.0;
};

Residual residual(const ClothModel& model, const std::vector<bool>& fixed, const Eigen::VectorXd& f) {
    Residual r;
    const double g = std::max(model.environment().gravity_m_per_s2.norm(), 1e-300);
    double sum = 0.0;
    for (int i = 0; i < model.vertex_count(); ++i) {
        if (fixed[static_cast<size_t>(i)]) continue;
        const double fi = f.segment<3>(3 * i).norm();
        r.max_force = std::max(r.max_force, fi);
        r.max_over_weight = std::max(r.max_over_weight, fi / (model.vertex_masses_kg()(i) * g));
        sum += fi * fi;
    }
    r.norm = std::sqrt(sum);
    return r;
}

double anchor_energy_J(const std::vector<PlaneAnchor>& anchors, const std::vector<bool>& fixed, const Eigen::VectorXd& x) {
    double sum = 0.0;
    for (const PlaneAnchor& a : anchors) {
        if (fixed[static_cast<size_t>(a.vertex)]) continue;
        const double gap_m = a.normal.dot(x.segment<3>(3 * a.vertex) - a.point_m);
        sum += 0.5 * a.stiffness_N_per_m * gap_m * gap_m;
    }
    return sum;
}

// The anchors' forces added to f and their (constant, definite) Jacobians to K.
void add_anchors(const std::vector<PlaneAnchor>& anchors, const std::vector<bool>& fixed, const Eigen::VectorXd& x,
                 Eigen::VectorXd& f, BlockSparseMatrix* K) {
    for (const PlaneAnchor& a : anchors) {
        if (fixed[static_cast<size_t>(a.vertex)]) continue;
        const double gap_m = a.normal.dot(x.segment<3>(3 * a.vertex) - a.point_m);
        f.segment<3>(3 * a.vertex) -= a.stiffness_N_per_m * gap_m * a.normal;
        if (K) K->block(K->diagonal_slot(a.vertex)) -= a.stiffness_N_per_m * a.normal * a.normal.transpose();
    }
}

}  // namespace

EquilibriumReport solve_static_equilibrium(ClothModel& model, const std::vector<bool>& fixed, Eigen::VectorXd& x,
                                           const EquilibriumOptions& options) {
    EquilibriumReport report;
    // Bending memory acts only during a dynamic run: the rest state before it is flat.
    model.reset_rest_fold_angles();
    const int n = model.vertex_count();
    for (const PlaneAnchor& a : options.anchors)
        if (a.vertex < 0 || a.vertex >= n)
            throw std::invalid_argument("solve_static_equilibrium: anchor on vertex " + std::to_string(a.vertex) +
                                        " of a mesh with " + std::to_string(n));
    std::vector<int> dof(static_cast<size_t>(n), -1);
    int free_dofs = 0;
    for (int i = 0; i < n; ++i)
        if (!fixed[static_cast<size_t>(i)]) {
            dof[static_cast<size_t>(i)] = free_dofs;
            free_dofs += 3;
        }
    const Eigen::VectorXd zero_v = Eigen::VectorXd::Zero(3 * n);
    Eigen::VectorXd f, f_trial, x_trial;
    BlockSparseMatrix K = model.make_jacobian_matrix();
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd rhs(free_dofs), step(free_dofs);
    ConjugateGradient cgs;
    const bool factorised = free_dofs / 3 <= options.factorised_max_free_vertices;
    // The factorised steps' limit (0: none): a multiple of the mean rest edge.
    double max_step_m = 0.0;
    if (factorised && options.factorised_max_step_edges > 0.0 && !model.mesh().triangles.empty()) {
        const std::vector<Eigen::Vector2d>& uv = model.mesh().material_uv_m;
        double sum_m = 0.0;
        for (const std::array<int, 3>& t : model.mesh().triangles)
            for (std::size_t k = 0; k < 3; ++k)
                sum_m += (uv[static_cast<std::size_t>(t[k])] - uv[static_cast<std::size_t>(t[(k + 1) % 3])]).norm();
        max_step_m =
            options.factorised_max_step_edges * sum_m / (3.0 * static_cast<double>(model.mesh().triangles.size()));
    }

    // The model's conservative forces, energy and Jacobian with the anchors'.
    auto evaluate = [&](const Eigen::VectorXd& at, Eigen::VectorXd& forces, BlockSparseMatrix* jacobian,
                        JacobianMode mode) {
        model.evaluate(at, zero_v, 0.0, kStaticTerms, forces, jacobian, nullptr, mode);
        add_anchors(options.anchors, fixed, at, forces, jacobian);
    };
    auto energy_of = [&](const Eigen::VectorXd& at) {
        return model.potential_energy(at, kStaticTerms) + anchor_energy_J(options.anchors, fixed, at);
    };
    double energy = energy_of(x);
    // Levenberg-Marquardt on the exact Hessian: when -K + shift M is not
    // positive definite (a saddle, compression) the shift grows until it is;
    // it shrinks after every good step, so the end game is plain Newton.
    double shift = 0.0;        // 1/s^2, multiplies the mass matrix
    bool use_exact = false;
    int exact_cooldown = 0;
    double shift_scale = 0.0;  // typical stiffness / mass, set on the first iteration
    bool pattern_analyzed = false;
    size_t analyzed_nonzeros = 0;
    // Exact Newton steps that no longer shrink the residual: rounding limit.
    int stalled_exact_steps = 0;
    double previous_exact_residual = std::numeric_limits<double>::infinity();
    int stalled_steps = 0;  // any steps
    double previous_residual = std::numeric_limits<double>::infinity();

    for (int it = 0; it <= options.max_iterations; ++it) {
        evaluate(x, f, &K, use_exact ? JacobianMode::exact : JacobianMode::definite);
        const Residual r = residual(model, fixed, f);
        report.iterations = it;
        if (options.cancel && options.cancel->load(std::memory_order_relaxed)) {
            report.cancelled = true;
            report.reason = "cancelled (iteration " + std::to_string(it) + ")";
            return report;
        }
        report.max_residual_force_N = r.max_force;
        report.max_residual_over_weight = r.max_over_weight;
        report.potential_energy_J = energy;
        if (!std::isfinite(r.norm)) {
            report.reason = "non-finite forces (iteration " + std::to_string(it) + ")";
            return report;
        }
        if (r.max_over_weight <= options.relative_residual_tolerance ||
            (options.residual_force_floor_N > 0.0 && r.max_force <= options.residual_force_floor_N)) {
            report.converged = true;
            return report;
        }
        // Rounding limit: exact Newton has stopped reducing the residual for
        // three steps while it is within 100x the tolerance (on a 48x48 mesh
        // a vertex's weight, the tolerance's scale, nears the rounding error
        // of the elastic forces: cotton stalled at 1.02e-8 of it).
        if (use_exact) {
            stalled_exact_steps = r.norm < 0.5 * previous_exact_residual ? 0 : stalled_exact_steps + 1;
            previous_exact_residual = std::min(previous_exact_residual, r.norm);
            if (stalled_exact_steps >= 3 && r.max_over_weight <= 100.0 * options.relative_residual_tolerance) {
                report.converged = true;
                return report;
            }
        }
        // The same limit met by the definite steps, which creep there (a
        // solve started at an equilibrium another solve had found sat at
        // 1.03e-8 for 400 iterations): ten steps without halving the residual.
        stalled_steps = r.norm < 0.5 * previous_residual ? 0 : stalled_steps + 1;
        previous_residual = std::min(previous_residual, r.norm);
        if (stalled_steps >= 10 && r.max_over_weight <= 100.0 * options.relative_residual_tolerance) {
            report.converged = true;
            return report;
        }
        if (it == options.max_iterations) break;
        if (shift_scale == 0.0) {
            double trace_k = 0.0, trace_m = 0.0;
            for (int i = 0; i < n; ++i)
                if (!fixed[static_cast<size_t>(i)]) {
                    trace_k += std::abs(K.block(K.diagonal_slot(i)).trace());
                    trace_m += 3.0 * model.vertex_masses_kg()(i);
                }
            shift_scale = trace_m > 0.0 ? std::max(trace_k / trace_m, 1e-12) : 1.0;
        }

        Eigen::VectorXd dx = Eigen::VectorXd::Zero(3 * n);
        bool solved = false;
        // (-K + shift M) dx = f on the free vertices, factorised: its pivots
        // tell whether the system is definite (near a stable minimum when K
        // is exact). False when it is not, dx untouched.
        auto factorised_step = [&]() {
            triplets.clear();
            K.for_each_block([&](int i, int j, const Eigen::Matrix3d& b) {
                const int di = dof[static_cast<size_t>(i)], dj = dof[static_cast<size_t>(j)];
                if (di < 0 || dj < 0) return;
                for (int a = 0; a < 3; ++a)
                    for (int c = 0; c < 3; ++c) triplets.emplace_back(di + a, dj + c, -b(a, c));
            });
            for (int i = 0; i < n; ++i) {
                const int di = dof[static_cast<size_t>(i)];
                if (di < 0) continue;
                for (int a = 0; a < 3; ++a) {
                    triplets.emplace_back(di + a, di + a, shift * model.vertex_masses_kg()(i));
                    rhs(di + a) = f(3 * i + a);
                }
            }
            Eigen::SparseMatrix<double> A(free_dofs, free_dofs);
            A.setFromTriplets(triplets.begin(), triplets.end());
            // The pattern is fixed unless contacts add blocks: analyse it once.
            if (!pattern_analyzed || static_cast<size_t>(A.nonZeros()) != analyzed_nonzeros) {
                solver.analyzePattern(A);
                pattern_analyzed = true;
                analyzed_nonzeros = static_cast<size_t>(A.nonZeros());
            }
            solver.factorize(A);
            if (solver.info() != Eigen::Success || !(solver.vectorD().array() > 0.0).all()) return false;
            step = solver.solve(rhs);
            if (!step.allFinite()) return false;
            for (int i = 0; i < n; ++i)
                if (dof[static_cast<size_t>(i)] >= 0) dx.segment<3>(3 * i) = step.segment<3>(dof[static_cast<size_t>(i)]);
            return true;
        };
        // Gauss-Newton step on the definite Hessian, shifted until it solves:
        // factorised on small meshes, else CG to a loose tolerance (far from
        // equilibrium, folds still forming, the steps are only approximate
        // anyway).
        auto definite_step = [&]() {
            for (int attempt = 0; attempt < 30; ++attempt) {
                dx.setZero();
                if (factorised) {
                    if (factorised_step()) return true;
                } else {
                    K.scale(-1.0);
                    for (int i = 0; i < n; ++i)
                        K.block(K.diagonal_slot(i)).diagonal().array() += shift * model.vertex_masses_kg()(i);
                    const CgResult cg =
                        cgs.solve(K, f, fixed, dx, options.inexact_newton_tolerance, options.cg_max_iterations);
                    report.cg_iterations += cg.iterations;
                    if (!cg.negative_curvature && dx.allFinite()) return true;
                    evaluate(x, f, &K, JacobianMode::definite);
                }
                shift = shift == 0.0 ? 1e-6 * shift_scale : shift * 10.0;
            }
            return false;
        };
        if (use_exact) {
            // Exact Newton step, factorised: definite pivots mean we are near
            // a stable minimum.
            solved = factorised_step();
            if (!solved) {
                // Not yet near a minimum: back to the definite model for a while.
                use_exact = false;
                exact_cooldown = 5;
                evaluate(x, f, &K, JacobianMode::definite);
            }
        }
        if (!solved) solved = definite_step();
        if (!solved) {
            report.reason = "no positive definite Newton system (iteration " + std::to_string(it) + ")";
            return report;
        }
        // A long factorised step may leap into another equilibrium than the
        // one nearest the start: shorten it to the limit.
        bool shortened = false;
        if (max_step_m > 0.0) {
            double largest_m = 0.0;
            for (int i = 0; i < n; ++i) largest_m = std::max(largest_m, dx.segment<3>(3 * i).norm());
            if (largest_m > max_step_m) {
                dx *= max_step_m / largest_m;
                shortened = true;
            }
        }
        const double slope = -f.dot(dx);  // dE/ds at s = 0, negative for a descent direction
        // Backtracking line search on the energy; when energy differences drown
        // in rounding (near convergence), on the residual norm instead.
        double s = 1.0;
        bool accepted = false;
        for (int ls = 0; ls < 40; ++ls) {
            x_trial = x + s * dx;
            const double e_trial = energy_of(x_trial);
            const double tiny = 1e-13 * (std::abs(energy) + 1e-30);
            if (std::isfinite(e_trial) && e_trial <= energy + 1e-4 * s * slope && e_trial - energy < -tiny) {
                accepted = true;
                energy = e_trial;
                break;
            }
            if (std::isfinite(e_trial) && std::abs(e_trial - energy) <= tiny) {
                evaluate(x_trial, f_trial, nullptr, JacobianMode::definite);
                if (residual(model, fixed, f_trial).norm < r.norm) {
                    accepted = true;
                    energy = e_trial;
                    break;
                }
            }
            s *= 0.5;
        }
        if (!accepted) {
            // No step lowers energy or residual while within 100x the
            // tolerance: the same rounding limit.
            if (r.max_over_weight <= 100.0 * options.relative_residual_tolerance) {
                report.converged = true;
                return report;
            }
            // A poor model of the energy: trust it less.
            shift = shift == 0.0 ? 1e-4 * shift_scale : shift * 10.0;
            if (shift > 1e6 * shift_scale) {
                report.reason = "the line search found no decrease (iteration " + std::to_string(it) + ")";
                return report;
            }
            continue;
        }
        // Exact Newton once the definite model makes full steps near the
        // equilibrium (not every time: an indefinite factorisation is wasted).
        if (exact_cooldown > 0) --exact_cooldown;
        if (!use_exact && s == 1.0 && !shortened && r.max_over_weight < 1.0 && exact_cooldown == 0) use_exact = true;
        x = x_trial;
        // Full steps: trust the quadratic model more; short ones: less.
        shift = s == 1.0 ? shift * 0.1 : shift * 2.0;
        if (shift < 1e-10 * shift_scale) shift = 0.0;
    }
    report.reason = "no convergence in " + std::to_string(options.max_iterations) + " iterations";
    return report;
}

}  // namespace flowvid::cloth
