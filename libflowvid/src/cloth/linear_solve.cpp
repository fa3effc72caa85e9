#include "flowvid/cloth/linear_solve.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace flowvid::cloth {

namespace {

// Inverse of a diagonal block; the scalar diagonal's for a singular one.
Eigen::Matrix3d block_inverse(const Eigen::Matrix3d& d) {
    bool invertible = false;
    Eigen::Matrix3d inv;
    d.computeInverseWithCheck(inv, invertible);
    if (!invertible || !inv.allFinite()) {
        inv.setZero();
        for (int k = 0; k < 3; ++k) inv(k, k) = d(k, k) != 0.0 ? 1.0 / d(k, k) : 0.0;
    }
    return inv;
}

}  // namespace

CgResult ConjugateGradient::solve(const BlockSparseMatrix& A, const Eigen::VectorXd& b, const std::vector<bool>& fixed,
                                  Eigen::VectorXd& x, double relative_tolerance, int max_iterations,
                                  Preconditioner preconditioner, int sweep_domains, const ParallelFor* parallel) {
    if (preconditioner == Preconditioner::symmetric_gauss_seidel)
        return solve_eisenstat(A, b, fixed, x, relative_tolerance, max_iterations, sweep_domains, parallel);
    std::vector<Eigen::Matrix3d> diagonal(static_cast<size_t>(A.block_rows()));
    for (int i = 0; i < A.block_rows(); ++i) diagonal[static_cast<size_t>(i)] = A.block(A.diagonal_slot(i));
    return solve([&](const Eigen::VectorXd& p, Eigen::VectorXd& out) { A.multiply(p, out); }, diagonal, b, fixed, x,
                 relative_tolerance, max_iterations);
}

double ConjugateGradient::prepare(const Eigen::VectorXd& b, const std::vector<bool>& fixed, Eigen::VectorXd& x) {
    const int n = static_cast<int>(fixed.size());
    // Fixed vertices as a 0/1 vector: masking is then one vectorised product.
    m_mask.resize(3 * n);
    for (int i = 0; i < n; ++i) m_mask.segment<3>(3 * i).setConstant(fixed[static_cast<size_t>(i)] ? 0.0 : 1.0);
    m_b = b;
    m_b.array() *= m_mask.array();
    const double b_norm = m_b.norm();
    if (b_norm == 0.0) {
        for (int i = 0; i < n; ++i)
            if (!fixed[static_cast<size_t>(i)]) x.segment<3>(3 * i).setZero();
        return 0.0;
    }
    // Fixed entries of x take part in A x, but b already holds their effect:
    // work on the free part only.
    m_x = x;
    m_x.array() *= m_mask.array();
    return b_norm;
}

CgResult ConjugateGradient::solve(const Operator& apply, const std::vector<Eigen::Matrix3d>& diagonal,
                                  const Eigen::VectorXd& b, const std::vector<bool>& fixed, Eigen::VectorXd& x,
                                  double relative_tolerance, int max_iterations) {
    const int n = static_cast<int>(diagonal.size());
    m_inverse_diagonal.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
        m_inverse_diagonal[static_cast<size_t>(i)] =
            fixed[static_cast<size_t>(i)] ? Eigen::Matrix3d::Zero() : block_inverse(diagonal[static_cast<size_t>(i)]);
    }
    auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
        z.resize(r.size());
        for (int i = 0; i < n; ++i) z.segment<3>(3 * i).noalias() = m_inverse_diagonal[static_cast<size_t>(i)] * r.segment<3>(3 * i);
    };

    const auto mask = [&](Eigen::VectorXd& v) { v.array() *= m_mask.array(); };
    CgResult result;
    const double b_norm = prepare(b, fixed, x);
    if (b_norm == 0.0) {
        result.converged = true;
        return result;
    }
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

namespace {

// s -= B x for a column-major 3x3 block B.
inline void subtract_block_product(const double* b, const double* x, double& s0, double& s1, double& s2) {
    s0 -= b[0] * x[0] + b[3] * x[1] + b[6] * x[2];
    s1 -= b[1] * x[0] + b[4] * x[1] + b[7] * x[2];
    s2 -= b[2] * x[0] + b[5] * x[1] + b[8] * x[2];
}

}  // namespace

// Rows [begin, end) of (D + L~)^-1 v, L~ the part of L inside the domain:
// row i's slots [m_lower_first[i], diagonal). Fixed rows have a zero inverse.
void ConjugateGradient::lower_solve(const BlockSparseMatrix& A, const Eigen::VectorXd& v, Eigen::VectorXd& out,
                                    int begin, int end) const {
    const double* vp = v.data();
    double* op = out.data();
    for (int i = begin; i < end; ++i) {
        double s0 = vp[3 * i], s1 = vp[3 * i + 1], s2 = vp[3 * i + 2];
        const int stop = A.diagonal_slot(i);
        for (int k = m_lower_first[static_cast<size_t>(i)]; k < stop; ++k)
            subtract_block_product(A.block(k).data(), op + 3 * A.column(k), s0, s1, s2);
        const double* d = m_inverse_diagonal[static_cast<size_t>(i)].data();
        op[3 * i] = d[0] * s0 + d[3] * s1 + d[6] * s2;
        op[3 * i + 1] = d[1] * s0 + d[4] * s1 + d[7] * s2;
        op[3 * i + 2] = d[2] * s0 + d[5] * s1 + d[8] * s2;
    }
}

// Rows [begin, end) of (D + U~)^-1 v: row i's slots (diagonal, m_upper_end[i]).
void ConjugateGradient::upper_solve(const BlockSparseMatrix& A, const Eigen::VectorXd& v, Eigen::VectorXd& out,
                                    int begin, int end) const {
    const double* vp = v.data();
    double* op = out.data();
    for (int i = end - 1; i >= begin; --i) {
        double s0 = vp[3 * i], s1 = vp[3 * i + 1], s2 = vp[3 * i + 2];
        const int stop = m_upper_end[static_cast<size_t>(i)];
        for (int k = A.diagonal_slot(i) + 1; k < stop; ++k)
            subtract_block_product(A.block(k).data(), op + 3 * A.column(k), s0, s1, s2);
        const double* d = m_inverse_diagonal[static_cast<size_t>(i)].data();
        op[3 * i] = d[0] * s0 + d[3] * s1 + d[6] * s2;
        op[3 * i + 1] = d[1] * s0 + d[4] * s1 + d[7] * s2;
        op[3 * i + 2] = d[2] * s0 + d[5] * s1 + d[8] * s2;
    }
}

// PCG with the SSOR preconditioner M = (D + L~) D^-1 (D + U~), run as plain
// PCG on the transformed system A' y = (D + L~)^-1 b with
// A' = (D + L~)^-1 A (D + U~)^-1, x = (D + U~)^-1 y, and D as A''s
// preconditioner (Eisenstat 1981). The rows are split into a fixed number of
// contiguous domains; L~ and U~ keep only the couplings inside a domain, so
// every domain sweeps on its own (in parallel when a `parallel` runner is
// given; the domains, not the threads, define the arithmetic). Writing
// A = L~ + D + U~ + C + R + E (C: the diagonal's difference from the split's D
// where a block was singular, R: couplings between domains, E: the extras),
// A' p = t + (D + L~)^-1 (p + (C - D) t + R t + E t) with t = (D + U~)^-1 p:
// one backward and one forward sweep, no product with A. The residual
// r = (D + L~) r' is checked exactly whenever its running estimate says the
// tolerance may be met.
CgResult ConjugateGradient::solve_eisenstat(const BlockSparseMatrix& A, const Eigen::VectorXd& b,
                                            const std::vector<bool>& fixed, Eigen::VectorXd& x,
                                            double relative_tolerance, int max_iterations, int domains,
                                            const ParallelFor* parallel) {
    const int n = A.block_rows();
    domains = std::clamp(domains, 1, std::max(1, n));
    const auto domain_begin = [&](int d) { return static_cast<int>(static_cast<long long>(n) * d / domains); };
    const auto for_each_domain = [&](const std::function<void(int)>& task) {
        if (parallel && domains > 1)
            (*parallel)(domains, task);
        else
            for (int d = 0; d < domains; ++d) task(d);
    };
    // Row i's couplings inside its domain: slots [m_lower_first, diagonal)
    // and (diagonal, m_upper_end); columns are sorted, so the couplings to
    // other domains are the slots before and after those.
    m_lower_first.resize(static_cast<size_t>(n));
    m_upper_end.resize(static_cast<size_t>(n));
    for (int d = 0; d < domains; ++d) {
        const int begin = domain_begin(d), end = domain_begin(d + 1);
        for (int i = begin; i < end; ++i) {
            int first = A.row_begin(i);
            while (A.column(first) < begin) ++first;
            int last = A.row_end(i);
            while (A.column(last - 1) >= end) --last;
            m_lower_first[static_cast<size_t>(i)] = first;
            m_upper_end[static_cast<size_t>(i)] = last;
        }
    }
    m_inverse_diagonal.resize(static_cast<size_t>(n));
    m_sweep_diagonal.resize(static_cast<size_t>(n));
    m_diagonal_correction.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
        const size_t si = static_cast<size_t>(i);
        if (fixed[si]) {
            m_inverse_diagonal[si].setZero();
            m_sweep_diagonal[si].setZero();
            m_diagonal_correction[si].setZero();
            continue;
        }
        // The split's D is A's diagonal block when that inverts well (a test
        // relative to its size: light vertices have tiny determinants), else
        // the block's diagonal.
        const Eigen::Matrix3d& a = A.block(A.diagonal_slot(i));
        Eigen::Matrix3d inv = a.inverse();
        const bool good = inv.allFinite() && (a * inv - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9;
        if (good) {
            m_sweep_diagonal[si] = a;
        } else {
            m_sweep_diagonal[si] = Eigen::Matrix3d::Zero();
            inv.setZero();
            for (int k = 0; k < 3; ++k) {
                m_sweep_diagonal[si](k, k) = a(k, k) != 0.0 ? a(k, k) : 1.0;
                inv(k, k) = 1.0 / m_sweep_diagonal[si](k, k);
            }
        }
        m_inverse_diagonal[si] = inv;
        m_diagonal_correction[si] = a - 2.0 * m_sweep_diagonal[si];
    }
    const auto mask = [&](Eigen::VectorXd& v) { v.array() *= m_mask.array(); };
    m_t.resize(3 * n);
    m_u.resize(3 * n);
    // out = (D + L~)^-1 v, all domains.
    const auto lower = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) {
        out.resize(3 * n);
        for_each_domain([&](int d) { lower_solve(A, v, out, domain_begin(d), domain_begin(d + 1)); });
    };
    const auto upper = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) {
        out.resize(3 * n);
        for_each_domain([&](int d) { upper_solve(A, v, out, domain_begin(d), domain_begin(d + 1)); });
    };
    // r = (D + L~) r', the residual of the original system.
    const auto lower_product = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) {
        out.resize(3 * n);
        for_each_domain([&](int d) {
            const int begin = domain_begin(d), end = domain_begin(d + 1);
            for (int i = begin; i < end; ++i) {
                if (fixed[static_cast<size_t>(i)]) {
                    out.segment<3>(3 * i).setZero();
                    continue;
                }
                Eigen::Vector3d s = m_sweep_diagonal[static_cast<size_t>(i)] * v.segment<3>(3 * i);
                for (int k = m_lower_first[static_cast<size_t>(i)]; k < A.diagonal_slot(i); ++k)
                    s.noalias() += A.block(k) * v.segment<3>(3 * A.column(k));
                out.segment<3>(3 * i) = s;
            }
        });
    };
    // q = A' p.
    const auto transformed_product = [&](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
        upper(p, m_t);
        const bool extras = !A.extras().empty();
        if (extras) {
            m_z.setZero(3 * n);
            A.add_extras_product(m_t, m_z);
            mask(m_z);
        }
        q.resize(3 * n);
        for_each_domain([&](int d) {
            const int begin = domain_begin(d), end = domain_begin(d + 1);
            // u = p + (C - D) t + R t (+ E t), then the domain's forward sweep.
            for (int i = begin; i < end; ++i) {
                if (fixed[static_cast<size_t>(i)]) {
                    m_u.segment<3>(3 * i).setZero();
                    continue;
                }
                Eigen::Vector3d s = p.segment<3>(3 * i);
                s.noalias() += m_diagonal_correction[static_cast<size_t>(i)] * m_t.segment<3>(3 * i);
                for (int k = A.row_begin(i); k < m_lower_first[static_cast<size_t>(i)]; ++k)
                    s.noalias() += A.block(k) * m_t.segment<3>(3 * A.column(k));
                for (int k = m_upper_end[static_cast<size_t>(i)]; k < A.row_end(i); ++k)
                    s.noalias() += A.block(k) * m_t.segment<3>(3 * A.column(k));
                if (extras) s += m_z.segment<3>(3 * i);
                m_u.segment<3>(3 * i) = s;
            }
            lower_solve(A, m_u, q, begin, end);
            q.segment(3 * begin, 3 * (end - begin)) += m_t.segment(3 * begin, 3 * (end - begin));
        });
    };

    CgResult result;
    const double b_norm = prepare(b, fixed, x);
    if (b_norm == 0.0) {
        result.converged = true;
        return result;
    }
    A.multiply(m_x, m_q);
    m_r = m_b - m_q;
    mask(m_r);
    double r_norm = m_r.norm();
    const double target = relative_tolerance * b_norm;
    Eigen::VectorXd& r_hat = m_b;  // b is no longer needed
    lower(m_r, r_hat);
    m_step.setZero(3 * n);
    // |r| / |r'|, refreshed at every exact check.
    double residual_scale = r_norm / std::max(r_hat.norm(), 1e-300);
    const auto precondition = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) {
        out.resize(3 * n);
        for (int i = 0; i < n; ++i)
            out.segment<3>(3 * i).noalias() = m_sweep_diagonal[static_cast<size_t>(i)] * v.segment<3>(3 * i);
    };
    precondition(r_hat, m_z);
    m_p = m_z;
    double rz = r_hat.dot(m_z);
    int it = 0;
    while (r_norm > target && it < max_iterations) {
        transformed_product(m_p, m_q);
        const double pq = m_p.dot(m_q);
        if (!(pq > 0.0)) {
            result.negative_curvature = true;
            break;
        }
        const double alpha = rz / pq;
        m_step.noalias() += alpha * m_p;
        r_hat.noalias() -= alpha * m_q;
        ++it;
        const double r_hat_norm = r_hat.norm();
        r_norm = residual_scale * r_hat_norm;
        if (r_norm <= target) {
            lower_product(r_hat, m_r);
            r_norm = m_r.norm();
            if (r_norm <= target) break;
            residual_scale = r_norm / std::max(r_hat_norm, 1e-300);
        }
        precondition(r_hat, m_z);
        const double rz_new = r_hat.dot(m_z);
        m_p = m_z + (rz_new / rz) * m_p;
        rz = rz_new;
    }
    lower_product(r_hat, m_r);  // the reported residual is exact, not the estimate
    r_norm = m_r.norm();
    upper(m_step, m_t);
    for (int i = 0; i < n; ++i)
        if (!fixed[static_cast<size_t>(i)]) x.segment<3>(3 * i) = m_x.segment<3>(3 * i) + m_t.segment<3>(3 * i);
    result.iterations = it;
    result.relative_residual = r_norm / b_norm;
    result.converged = r_norm <= target;
    return result;
}

}  // namespace flowvid::cloth
