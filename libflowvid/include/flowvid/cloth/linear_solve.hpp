#pragma once
// Preconditioned conjugate gradients on a BlockSparseMatrix with some
// vertices held fixed (Baraff-Witkin's filtered CG: the fixed rows and
// columns are removed from the system by masking).

#include "flowvid/cloth/block_matrix.hpp"

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace flowvid::cloth {

struct CgResult {
    int iterations = 0;
    bool converged = false;
    bool negative_curvature = false;  // A is not positive definite on the free space
    double relative_residual = 0.0;
};

class ConjugateGradient {
public:
    // Solves A x = b on the free vertices; x holds the start (its fixed
    // entries are left unchanged and must already be accounted for in b).
    CgResult solve(const BlockSparseMatrix& A, const Eigen::VectorXd& b, const std::vector<bool>& fixed,
                   Eigen::VectorXd& x, double relative_tolerance, int max_iterations);
    // Matrix-free: `apply(p, out)` computes out = A p; `diagonal` holds A's
    // 3x3 diagonal blocks (block-Jacobi preconditioner).
    using Operator = std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>;
    CgResult solve(const Operator& apply, const std::vector<Eigen::Matrix3d>& diagonal, const Eigen::VectorXd& b,
                   const std::vector<bool>& fixed, Eigen::VectorXd& x, double relative_tolerance, int max_iterations);

private:
    Eigen::VectorXd m_b, m_x, m_r, m_z, m_p, m_q, m_mask;
    std::vector<Eigen::Matrix3d> m_inverse_diagonal;
};

}  // namespace flowvid::cloth
