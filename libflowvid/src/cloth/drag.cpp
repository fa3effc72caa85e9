// Air drag of the cloth model: the thesis's nonlinear normal drag, linear
// normal and tangential drag, relative to the wind (docs/cloth_model.md).

#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include <Eigen/Geometry>

#include <cmath>

namespace flowvid::cloth {

using detail::at;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using detail::cross_matrix;

void ClothModel::add_drag(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& f,
                          BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                          size_t begin, size_t end) const {
    const double kN = m_material.drag_normal_kg_per_m3, kf = m_material.drag_degradation_s2_per_m2;
    const double kT = m_material.drag_tangential_kg_per_m2_s;
    const double kL = m_material.drag_linear_normal_kg_per_m2_s;
    const double c_plate = m_environment.wind_pressure_kg_per_m3;
    const bool field = static_cast<bool>(m_environment.wind_field);
    const Matrix3d I = Matrix3d::Identity();
    for (size_t ti = begin; ti < end; ++ti) {
        const TriangleData& t = m_triangles[ti];
        const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
        const Vector3d N = (x1 - x0).cross(x2 - x0);
        const double Nn = N.norm();
        if (lin) lin->drag_block[ti].setZero();
        if (!(Nn > 0.0)) continue;
        const Vector3d n = N / Nn;
        const double a = 0.5 * Nn;
        const Vector3d wind = field ? m_environment.wind_field((x0 + x1 + x2) / 3.0, time_s) : m_environment.wind_m_per_s;
        const Vector3d vrel = (at(v, t.v[0]) + at(v, t.v[1]) + at(v, t.v[2])) / 3.0 - wind;
        const double s = vrel.dot(n);
        const double q = 1.0 + kf * s * s;
        const double h = kN * s * std::abs(s) / q + kL * s;       // signed normal drag magnitude
        const double hp = 2.0 * kN * std::abs(s) / (q * q) + kL;  // dh/ds
        // The wind's plate push (Environment::wind_pressure_kg_per_m3).
        const double sw = wind.dot(n);
        const Vector3d ftri = -a * ((h - kT * s) * n + kT * vrel) + a * c_plate * sw * std::abs(sw) * n;
        for (int k = 0; k < 3; ++k) f.segment<3>(3 * t.v[static_cast<size_t>(k)]) += ftri / 3.0;
        if (lin) {
            lin->drag_block[ti] = (-lin->sv * a / 9.0) * ((hp - kT) * n * n.transpose() + kT * I);
            continue;
        }
        if (dfdv) {
            const Matrix3d D = (-a / 9.0) * ((hp - kT) * n * n.transpose() + kT * I);
            for (int s9 = 0; s9 < 9; ++s9) dfdv->block(t.slots[static_cast<size_t>(s9)]) += D;
        }
        if (dfdx && mode == JacobianMode::exact) {
            const Vector3d vT = vrel - s * n;
            // a n = N / 2 and s = vrel.N/|N|; the plate push is (c/2) q(w.N/|N|) N, q(s) = s|s|.
            const Matrix3d dF_dN = -0.5 * ((hp - kT) * n * vT.transpose() + (h - kT * s) * I + kT * vrel * n.transpose()) +
                                   0.5 * c_plate * (sw * std::abs(sw) * I + 2.0 * std::abs(sw) * n * (wind - sw * n).transpose());
            const Matrix3d dN[3] = {cross_matrix(x2 - x1), -cross_matrix(x2 - x0), cross_matrix(x1 - x0)};
            for (int b = 0; b < 3; ++b) {
                const Matrix3d K = dF_dN * dN[b] / 3.0;
                for (int a2 = 0; a2 < 3; ++a2) dfdx->block(t.slots[static_cast<size_t>(3 * a2 + b)]) += K;
            }
        }
    }
}

}  // namespace flowvid::cloth
