#include "flowvid/cloth/linear_solve.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace flowvid::cloth {


CgResult ConjugateGradient::solve(const BlockSparseMatrix& A, const Eigen::VectorXd& b, const std::vector<bool>& fixed,
                                  Eigen::VectorXd& x, double relative_tolerance, int max_iterations) {
    std::vector<Eigen::Matrix3d> diagonal(static_cast<size_t>(A.block_rows()));
    for (int i = 0; i < A.block_rows(); ++i) diagonal[static_cast<size_t>(i)] = A.block(A.diagonal_slot(i));
    return solve([&](const Eigen::VectorXd& p, Eigen::VectorXd& out) { A.multiply(p, out); }, diagonal, b, fixed, x,
                 relative_tolerance, max_iterations);
}

CgResult ConjugateGradient::solve(const Operator& apply, const std::vector<Eigen::Matrix3d>& diagonal,
                                  const Eigen::VectorXd& b, const std::vector<bool>& fixed, Eigen::VectorXd& x,
                                  double relative_tolerance, int max_iterations) {
    const int n = static_cast<int>(diagonal.size());
    m_inverse_diagonal.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
        const Eigen::Matrix3d& d = diagonal[static_cast<size_t>(i)];
        bool invertible = false;
        Eigen::Matrix3d inv;
        d.computeInverseWithCheck(inv, invertible);
        // Block Jacobi; fall back to the scalar diagonal for a singular block.
        if (!invertible || !inv.allFinite()) {
            inv.setZero();
            for (int k = 0; k < 3; ++k) inv(k, k) = d(k, k) != 0.0 ? 1.0 / d(k, k) : 0.0;
        }
        m_inverse_diagonal[static_cast<size_t>(i)] = fixed[static_cast<size_t>(i)] ? Eigen::Matrix3d::Zero() : inv;
    }
    auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
        z.resize(r.size());
        for (int i = 0; i < n; ++i) z.segment<3>(3 * i).noalias() = m_inverse_diagonal[static_cast<size_t>(i)] * r.segment<3>(3 * i);
    };

    // Fixed vertices as a 0/1 vector: masking is then one vectorised product.
    m_mask.resize(3 * n);
    for (int i = 0; i < n; ++i) m_mask.segment<3>(3 * i).setConstant(fixed[static_cast<size_t>(i)] ? 0.0 : 1.0);
    const auto mask = [&](Eigen::VectorXd& v) { v.array() *= m_mask.array(); };

    CgResult result;
    m_b = b;
    mask(m_b);
    const double b_norm = m_b.norm();
    if (b_norm == 0.0) {
        for (int i = 0; i < n; ++i)
            if (!fixed[static_cast<size_t>(i)]) x.segment<3>(3 * i).setZero();
        result.converged = true;
        return result;
    }
    // Fixed entries of x take part in A x, but b already holds their effect:
    // work on the free part only.
    m_x = x;
    mask(m_x);
    apply(m_x, m_q);
    m_r = m_b - m_q;
    mask(m_r);
    precondition(m_r, m_z);
    m_p = m_z;
    double rz = m_r.dot(m_z);
    const double target = relative_tolerance * b_norm;
    double r_norm = m_r.norm();
    int it = 0;
    while (r_norm > target && it < max_iterations) {
        apply(m_p, m_q);
        const double pq = m_p.dot(m_q);  // m_p is zero on fixed entries
        if (!(pq > 0.0)) {
            result.negative_curvature = true;
            break;
        }
        const double alpha = rz / pq;
        m_x.noalias() += alpha * m_p;
        m_r.noalias() -= alpha * (m_q.array() * m_mask.array()).matrix();
        r_norm = m_r.norm();
        ++it;
        if (r_norm <= target) break;
        precondition(m_r, m_z);
        const double rz_new = m_r.dot(m_z);
        m_p = m_z + (rz_new / rz) * m_p;
        rz = rz_new;
    }
    for (int i = 0; i < n; ++i)
        if (!fixed[static_cast<size_t>(i)]) x.segment<3>(3 * i) = m_x.segment<3>(3 * i);
    result.iterations = it;
    result.relative_residual = r_norm / b_norm;
    result.converged = r_norm <= target;
    return result;
}

}  // namespace flowvid::cloth
