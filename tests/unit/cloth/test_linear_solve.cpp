// The filtered conjugate-gradient solver against a dense factorisation, with
// both preconditioners: stiff symmetric positive definite block systems on a
// grid (a cloth's stencil), some vertices fixed, contact-like extra blocks.

#include "flowvid/cloth/linear_solve.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <functional>
#include <ostream>
#include <random>
#include <string>
#include <thread>

namespace fc = flowvid::cloth;

namespace {

struct GridSystem {
    fc::BlockSparseMatrix A;
    Eigen::MatrixXd dense;
    std::vector<bool> fixed;
};

Eigen::Matrix3d random_spd(std::mt19937& rng, double scale) {
    std::normal_distribution<double> g(0.0, 1.0);
    Eigen::Matrix3d r;
    for (int k = 0; k < 9; ++k) r(k) = g(rng);
    return scale * (r * r.transpose() + 0.1 * Eigen::Matrix3d::Identity());
}

// A = mass I + sum over grid edges (and diagonals) of [B -B; -B B], B random
// SPD with stiffness / mass `ratio` (h^2 k / m of an implicit cloth step);
// the first row of vertices is fixed. With `contacts`, a few couplings between
// far vertices go in as extras (outside the pattern).
GridSystem grid_system(int side, double ratio, bool contacts, unsigned seed) {
    std::mt19937 rng(seed);
    const int n = side * side;
    std::vector<std::pair<int, int>> pairs;
    for (int r = 0; r < side; ++r)
        for (int c = 0; c < side; ++c) {
            const int i = r * side + c;
            if (c + 1 < side) pairs.emplace_back(i, i + 1);
            if (r + 1 < side) pairs.emplace_back(i, i + side);
            if (c + 1 < side && r + 1 < side) pairs.emplace_back(i, i + side + 1);
        }
    GridSystem s;
    s.A = fc::BlockSparseMatrix(n, pairs);
    s.A.set_zero();
    for (int i = 0; i < n; ++i) s.A.add(i, i, Eigen::Matrix3d::Identity());
    auto couple = [&](int i, int j) {
        const Eigen::Matrix3d b = random_spd(rng, ratio);
        s.A.add(i, i, b);
        s.A.add(j, j, b);
        s.A.add(i, j, -b);
        s.A.add(j, i, -b);
    };
    for (const auto& [i, j] : pairs) couple(i, j);
    if (contacts)
        for (int k = 0; k < 4; ++k) couple(side + 2 * k, n - 1 - 3 * k);  // not grid neighbours: extras
    s.dense = s.A.to_dense();
    s.fixed.assign(static_cast<size_t>(n), false);
    for (int c = 0; c < side; ++c) s.fixed[static_cast<size_t>(c)] = true;
    return s;
}

// The free part of A x = b solved densely (fixed entries of x kept).
Eigen::VectorXd dense_solution(const GridSystem& s, const Eigen::VectorXd& b, const Eigen::VectorXd& x_fixed) {
    std::vector<int> free;
    for (int i = 0; i < static_cast<int>(s.fixed.size()); ++i)
        if (!s.fixed[static_cast<size_t>(i)])
            for (int a = 0; a < 3; ++a) free.push_back(3 * i + a);
    const int m = static_cast<int>(free.size());
    Eigen::MatrixXd Aff(m, m);
    Eigen::VectorXd bf(m);
    for (int p = 0; p < m; ++p) {
        bf(p) = b(free[static_cast<size_t>(p)]);
        for (int q = 0; q < m; ++q) Aff(p, q) = s.dense(free[static_cast<size_t>(p)], free[static_cast<size_t>(q)]);
    }
    const Eigen::VectorXd xf = Aff.ldlt().solve(bf);
    Eigen::VectorXd x = x_fixed;
    for (int p = 0; p < m; ++p) x(free[static_cast<size_t>(p)]) = xf(p);
    return x;
}

double free_residual(const GridSystem& s, const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
    // b holds the fixed columns' effect already, as the solver expects: the
    // residual is over the free rows with the fixed entries of x left out.
    Eigen::VectorXd xf = x;
    for (size_t i = 0; i < s.fixed.size(); ++i)
        if (s.fixed[i]) xf.segment<3>(3 * static_cast<int>(i)).setZero();
    Eigen::VectorXd r = b - s.dense * xf;
    for (size_t i = 0; i < s.fixed.size(); ++i)
        if (s.fixed[i]) r.segment<3>(3 * static_cast<int>(i)).setZero();
    return r.norm();
}

struct Solved {
    fc::CgResult result;
    Eigen::VectorXd x;
};

Solved solve(const GridSystem& s, const Eigen::VectorXd& b, fc::Preconditioner preconditioner, double tolerance,
             int domains = 1, const fc::ConjugateGradient::ParallelFor* parallel = nullptr) {
    Solved out;
    out.x = Eigen::VectorXd::Constant(b.size(), 0.25);  // a start that is not the answer; fixed entries kept
    fc::ConjugateGradient cg;
    out.result = cg.solve(s.A, b, s.fixed, out.x, tolerance, 2000, preconditioner, domains, parallel);
    return out;
}

Eigen::VectorXd random_vector(int size, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    Eigen::VectorXd v(size);
    for (int k = 0; k < size; ++k) v(k) = g(rng);
    return v;
}

}  // namespace

struct SolverCase {
    fc::Preconditioner preconditioner;
    int domains;
};

void PrintTo(const SolverCase& c, std::ostream* os) {
    *os << (c.preconditioner == fc::Preconditioner::block_jacobi ? "block Jacobi" : "Gauss-Seidel") << ", "
        << c.domains << " domain(s)";
}

class SolverCases : public ::testing::TestWithParam<SolverCase> {};

TEST_P(SolverCases, SolveStiffGridSystemsToTheRequestedResidual) {
    for (const bool contacts : {false, true}) {
        const GridSystem s = grid_system(12, 400.0, contacts, 7);
        ASSERT_EQ(!s.A.extras().empty(), contacts);
        const Eigen::VectorXd b = random_vector(static_cast<int>(s.dense.rows()), 11);
        const double tolerance = 1e-8;
        const Solved solved = solve(s, b, GetParam().preconditioner, tolerance, GetParam().domains);
        EXPECT_TRUE(solved.result.converged);
        EXPECT_FALSE(solved.result.negative_curvature);
        Eigen::VectorXd b_free = b;
        for (size_t i = 0; i < s.fixed.size(); ++i)
            if (s.fixed[i]) b_free.segment<3>(3 * static_cast<int>(i)).setZero();
        // The reported residual is the true one, and within the tolerance.
        const double residual = free_residual(s, b, solved.x);
        EXPECT_LE(residual, tolerance * b_free.norm() * (1.0 + 1e-6));
        EXPECT_NEAR(solved.result.relative_residual, residual / b_free.norm(), 1e-3 * tolerance);
        // Fixed entries are left as they were; free ones match a dense solve.
        const Eigen::VectorXd reference = dense_solution(s, b, Eigen::VectorXd::Constant(b.size(), 0.25));
        EXPECT_LE((solved.x - reference).norm(), 1e-5 * reference.norm());
        for (size_t i = 0; i < s.fixed.size(); ++i) {
            if (s.fixed[i]) {
                EXPECT_EQ(solved.x(3 * static_cast<int>(i)), 0.25);
            }
        }
    }
}

TEST_P(SolverCases, ReportNegativeCurvature) {
    GridSystem s = grid_system(6, 1.0, false, 3);
    for (int i = 0; i < s.A.block_rows(); ++i) s.A.block(s.A.diagonal_slot(i)) -= 30.0 * Eigen::Matrix3d::Identity();
    const Eigen::VectorXd b = random_vector(3 * s.A.block_rows(), 5);
    const Solved solved = solve(s, b, GetParam().preconditioner, 1e-8, GetParam().domains);
    EXPECT_TRUE(solved.result.negative_curvature);
    EXPECT_FALSE(solved.result.converged);
}

INSTANTIATE_TEST_SUITE_P(LinearSolve, SolverCases,
                         ::testing::Values(SolverCase{fc::Preconditioner::block_jacobi, 1},
                                           SolverCase{fc::Preconditioner::symmetric_gauss_seidel, 1},
                                           SolverCase{fc::Preconditioner::symmetric_gauss_seidel, 2},
                                           SolverCase{fc::Preconditioner::symmetric_gauss_seidel, 5}),
                         [](const ::testing::TestParamInfo<SolverCase>& info) {
                             return info.param.preconditioner == fc::Preconditioner::block_jacobi
                                        ? std::string("BlockJacobi")
                                        : "GaussSeidel" + std::to_string(info.param.domains) + "Domains";
                         });

TEST(LinearSolve, GaussSeidelDomainsGiveTheSameBitsOnThreads) {
    // The domains define the arithmetic: sweeping them on threads (here one
    // thread per domain, in reverse start order) changes no bit.
    const GridSystem s = grid_system(16, 400.0, true, 21);
    const Eigen::VectorXd b = random_vector(3 * s.A.block_rows(), 23);
    const fc::ConjugateGradient::ParallelFor threads = [](int count, const std::function<void(int)>& task) {
        std::vector<std::thread> workers;
        for (int k = count - 1; k >= 0; --k) workers.emplace_back([&task, k] { task(k); });
        for (std::thread& t : workers) t.join();
    };
    const Solved serial = solve(s, b, fc::Preconditioner::symmetric_gauss_seidel, 1e-6, 3);
    const Solved parallel = solve(s, b, fc::Preconditioner::symmetric_gauss_seidel, 1e-6, 3, &threads);
    ASSERT_TRUE(serial.result.converged);
    EXPECT_EQ(serial.result.iterations, parallel.result.iterations);
    EXPECT_EQ((serial.x - parallel.x).cwiseAbs().maxCoeff(), 0.0);
}

TEST(LinearSolve, GaussSeidelNeedsFarFewerIterationsOnAFineStiffGrid) {
    // Block Jacobi's iteration count grows with the grid; SSOR's grows slower.
    const GridSystem s = grid_system(24, 400.0, false, 9);
    const Eigen::VectorXd b = random_vector(3 * s.A.block_rows(), 13);
    const Solved jacobi = solve(s, b, fc::Preconditioner::block_jacobi, 1e-3);
    const Solved ssor = solve(s, b, fc::Preconditioner::symmetric_gauss_seidel, 1e-3);
    const Solved ssor2 = solve(s, b, fc::Preconditioner::symmetric_gauss_seidel, 1e-3, 2);
    ASSERT_TRUE(jacobi.result.converged);
    ASSERT_TRUE(ssor.result.converged);
    ASSERT_TRUE(ssor2.result.converged);
    std::printf("iterations to 1e-3 on a 24x24 grid: block Jacobi %d, symmetric Gauss-Seidel %d (2 domains: %d)\n",
                jacobi.result.iterations, ssor.result.iterations, ssor2.result.iterations);
    EXPECT_LT(ssor.result.iterations, 0.6 * jacobi.result.iterations);
    EXPECT_LT(ssor2.result.iterations, 0.6 * jacobi.result.iterations);
}
