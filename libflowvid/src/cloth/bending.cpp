// Bending terms of the cloth model: the hinge energy on the signed dihedral
// angle with its damping, and the bending memory's rest folds
// (docs/cloth_model.md).

#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include "flowvid/cloth/geometry.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace flowvid::cloth {

using detail::at;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using detail::fold_difference;

Eigen::VectorXd ClothModel::rest_fold_angles_rad() const {
    if (m_rest_fold_rad.empty()) return Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m_edges.size()));
    return Eigen::Map<const Eigen::VectorXd>(m_rest_fold_rad.data(), static_cast<Eigen::Index>(m_rest_fold_rad.size()));
}

void ClothModel::set_rest_fold_angles_rad(const Eigen::VectorXd& angles_rad) {
    if (angles_rad.size() != static_cast<Eigen::Index>(m_edges.size()))
        throw std::invalid_argument("set_rest_fold_angles_rad: " + std::to_string(angles_rad.size()) +
                                    " angles for " + std::to_string(m_edges.size()) + " interior edges");
    if (!angles_rad.allFinite()) throw std::invalid_argument("set_rest_fold_angles_rad: non-finite angle");
    m_rest_fold_rad.assign(angles_rad.data(), angles_rad.data() + angles_rad.size());
}

void ClothModel::reset_rest_fold_angles() { m_rest_fold_rad.clear(); }

void ClothModel::update_rest_fold_angles(const Eigen::VectorXd& x, double dt_s, Eigen::VectorXd* bending_force_change) {
    const double rate = m_material.bend_memory_rate_per_s;
    if (!(rate > 0.0) || !(dt_s > 0.0)) return;
    if (m_rest_fold_rad.empty()) m_rest_fold_rad.assign(m_edges.size(), 0.0);
    // Exact for a held fold over any sequence of steps: the factors e^{-r dt} multiply.
    const double fraction = -std::expm1(-rate * dt_s);
    const double kb = m_material.bend_N_m;
    const bool correct = bending_force_change != nullptr && kb != 0.0;
    Vector12d g;
    for (size_t ei = 0; ei < m_edges.size(); ++ei) {
        const EdgeData& e = m_edges[ei];
        double theta = 0.0;
        // Degenerate hinges exert no bending force and keep their memory.
        if (!dihedral_angle_gradient(at(x, e.v[0]), at(x, e.v[1]), at(x, e.v[2]), at(x, e.v[3]), theta, g)) continue;
        double& theta0 = m_rest_fold_rad[ei];
        const double step = fraction * fold_difference(theta, theta0);
        theta0 = std::remainder(theta0 + step, 2.0 * M_PI);
        // f = -k w (theta - theta0) g: raising theta0 by `step` adds k w step g.
        if (correct)
            for (int a = 0; a < 4; ++a)
                bending_force_change->segment<3>(3 * e.v[static_cast<size_t>(a)]) += (kb * e.weight * step) * g.segment<3>(3 * a);
    }
}

void ClothModel::add_bending(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd& f,
                             BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                             size_t begin, size_t end, const Eigen::VectorXd* product_of,
                             Eigen::VectorXd* product) const {
    const bool exact = mode == JacobianMode::exact;
    const double kb = (terms & ForceTerm::bending) ? m_material.bend_N_m : 0.0;
    const double cb = (terms & ForceTerm::bending_damping) ? m_material.bend_damping_N_m_s : 0.0;
    if (kb == 0.0 && cb == 0.0) return;
    // The definite Jacobian keeps only the Gauss-Newton term g g^T: no Hessian.
    const bool need_hessian = dfdx != nullptr && exact;
    // Bending memory: the elastic part acts on theta - theta0 (null: flat rest).
    const double* rest = m_rest_fold_rad.empty() ? nullptr : m_rest_fold_rad.data();
    Vector12d g;
    Matrix12d H;
    for (size_t ei = begin; ei < end; ++ei) {
        const EdgeData& e = m_edges[ei];
        const Vector3d x0 = at(x, e.v[0]), x1 = at(x, e.v[1]), x2 = at(x, e.v[2]), x3 = at(x, e.v[3]);
        double theta = 0.0;
        const bool ok = need_hessian ? dihedral_angle_hessian(x0, x1, x2, x3, theta, g, H)
                                     : dihedral_angle_gradient(x0, x1, x2, x3, theta, g);
        if (!ok && lin) {
            lin->hinge_coefficient[ei] = 0.0;
            continue;
        }
        if (ok && !dfdx && !dfdv && !lin) {
            // Forces only (explicit integration).
            double coef = kb * (rest ? fold_difference(theta, rest[ei]) : theta);
            if (cb != 0.0)
                for (int a = 0; a < 4; ++a) coef += cb * g.segment<3>(3 * a).dot(at(v, e.v[static_cast<size_t>(a)]));
            coef *= e.weight;
            for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[static_cast<size_t>(a)]) -= coef * g.segment<3>(3 * a);
            continue;
        }
        if (!ok) continue;
        double theta_dot = 0.0;
        Vector12d vl;
        if (cb != 0.0) {
            for (int a = 0; a < 4; ++a) vl.segment<3>(3 * a) = at(v, e.v[static_cast<size_t>(a)]);
            theta_dot = g.dot(vl);
        }
        const double w = e.weight;
        const double bend = rest ? fold_difference(theta, rest[ei]) : theta;
        const double coef = w * (kb * bend + cb * theta_dot);
        for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[static_cast<size_t>(a)]) -= coef * g.segment<3>(3 * a);
        if (lin) {
            lin->hinge_gradient[ei] = g;
            lin->hinge_coefficient[ei] = -w * (lin->sx * kb + lin->sv * cb);
            if (product_of && product && kb != 0.0) {
                double s = 0.0;
                for (int a = 0; a < 4; ++a) s += g.segment<3>(3 * a).dot(at(*product_of, e.v[static_cast<size_t>(a)]));
                s *= -w * kb;
                for (int a = 0; a < 4; ++a) product->segment<3>(3 * e.v[static_cast<size_t>(a)]) += s * g.segment<3>(3 * a);
            }
            continue;
        }
        if (dfdx && !exact) {
            // Only the 3x3 blocks of -w kb g g^T.
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdx->block(e.slots[static_cast<size_t>(4 * a + b)]).noalias() -=
                        (w * kb) * g.segment<3>(3 * a) * g.segment<3>(3 * b).transpose();
        } else if (dfdx) {
            Matrix12d K = -(w * kb) * (g * g.transpose());
            {
                K -= (w * kb * bend) * H;
                if (cb != 0.0) K -= (w * cb) * (theta_dot * H + g * (H * vl).transpose());
            }
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdx->block(e.slots[static_cast<size_t>(4 * a + b)]) += K.block<3, 3>(3 * a, 3 * b);
        }
        if (dfdv && cb != 0.0) {
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdv->block(e.slots[static_cast<size_t>(4 * a + b)]) -=
                        (w * cb) * g.segment<3>(3 * a) * g.segment<3>(3 * b).transpose();
        }
    }
}

}  // namespace flowvid::cloth
