// Shear read on a grid's cells (cell_shear.cpp): forces and Jacobians against
// finite differences, the element-wise linearisation against the assembled
// matrices, a pure shear's energy against the continuum's, a cell folded
// along either diagonal storing none, and a share of it blending the two
// readings. The cells' fibres are experimental and switched on here for
// every test (FLOWVID_EXPERIMENTAL_CELL_FIBRES).

#include "flowvid/cloth/model.hpp"
#include "flowvid/cloth/swatch.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace fc = flowvid::cloth;

namespace {

const bool kEnabled = [] {
    setenv("FLOWVID_EXPERIMENTAL_CELL_FIBRES", "1", 1);
    return true;
}();

fc::ClothMaterial shear_material() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = 120.0;
    m.stretch_weft_N_per_m = 80.0;
    m.shear_N_per_m = 40.0;
    m.bend_N_m = 2e-5;
    m.shear_damping_N_s_per_m = 0.01;
    m.diagonal_tension_N_per_m = 70.0;
    m.shear_cell_fraction = 1.0;
    return m;
}

Eigen::VectorXd random_x(const fc::ClothMesh& mesh, unsigned seed, double amplitude_m) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitZ())).toRotationMatrix();
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        x.segment<3>(3 * i) = R * (Eigen::Vector3d(uv.x(), uv.y(), 0.0) + amplitude_m * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    }
    return x;
}

Eigen::VectorXd force_of(fc::ClothModel& model, const Eigen::VectorXd& x, unsigned terms) {
    Eigen::VectorXd f;
    model.evaluate(x, Eigen::VectorXd::Zero(x.size()), 0.0, terms, f);
    return f;
}

double relative_error(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    const double scale = std::max(a.norm(), b.norm());
    return scale == 0.0 ? 0.0 : (a - b).norm() / scale;
}

}  // namespace

TEST(ClothCellShear, EveryTriangleOfAGridBelongsToOneCell) {
    ASSERT_TRUE(kEnabled);
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::ClothModel model(mesh, shear_material());
    EXPECT_EQ(model.cells().size(), 3u * 4u);
}

TEST(ClothCellShear, ForcesAndJacobiansMatchFiniteDifferences) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::ClothModel model(mesh, shear_material());
    for (unsigned seed : {1u, 2u, 3u}) {
        SCOPED_TRACE(seed);
        const Eigen::VectorXd x = random_x(mesh, seed, 0.008);
        const unsigned terms = fc::ForceTerm::shear;
        const Eigen::VectorXd f = force_of(model, x, terms);
        fc::BlockSparseMatrix dfdx = model.make_jacobian_matrix();
        Eigen::VectorXd f2;
        model.evaluate(x, Eigen::VectorXd::Zero(x.size()), 0.0, terms, f2, &dfdx, nullptr, fc::JacobianMode::exact);
        EXPECT_LT((f2 - f).norm(), 1e-12 * f.norm());
        const double h = 1e-7;
        Eigen::MatrixXd K_fd(x.size(), x.size());
        Eigen::VectorXd f_energy(x.size());
        for (Eigen::Index k = 0; k < x.size(); ++k) {
            Eigen::VectorXd xp = x, xm = x;
            xp(k) += h;
            xm(k) -= h;
            K_fd.col(k) = (force_of(model, xp, terms) - force_of(model, xm, terms)) / (2 * h);
            f_energy(k) = -(model.potential_energy(xp, terms) - model.potential_energy(xm, terms)) / (2 * h);
        }
        const double ef = relative_error(f, f_energy), ex = relative_error(dfdx.to_dense(), K_fd);
        std::printf("[ measured ] seed %u: force vs energy %.1e, df/dx %.1e\n", seed, ef, ex);
        EXPECT_LT(ef, 2e-6);
        EXPECT_LT(ex, 2e-6);
        model.evaluate(x, Eigen::VectorXd::Zero(x.size()), 0.0, terms, f2, &dfdx, nullptr, fc::JacobianMode::definite);
        const Eigen::MatrixXd M = dfdx.to_dense();
        EXPECT_LT((M - M.transpose()).norm(), 1e-12 * M.norm());
        EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(-M).eigenvalues().minCoeff(), -1e-10 * M.norm());
    }
}

TEST(ClothCellShear, ElementwiseLinearizationEqualsTheAssembledJacobians) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    const Eigen::VectorXd x = random_x(mesh, 5, 0.008);
    std::mt19937 rng(4);
    std::normal_distribution<double> normal;
    Eigen::VectorXd v(x.size()), p(x.size());
    for (Eigen::Index k = 0; k < x.size(); ++k) v(k) = normal(rng), p(k) = normal(rng);
    fc::ClothModel model(mesh, shear_material());
    fc::BlockSparseMatrix K = model.make_jacobian_matrix(), D = model.make_jacobian_matrix();
    Eigen::VectorXd f1, f2, out;
    const unsigned terms = fc::ForceTerm::elastic | fc::ForceTerm::damping;
    model.evaluate(x, v, 0.0, terms, f1, &K, &D, fc::JacobianMode::definite);
    const double sx = 2e-4, sv = 0.03;
    fc::Linearization lin;
    model.linearize(x, v, 0.0, terms, sx, sv, f2, lin, &p);
    EXPECT_LT((f1 - f2).norm(), 1e-12 * f1.norm());
    EXPECT_LT((lin.dfdx_product - K.to_dense() * p).norm(), 1e-12 * (K.to_dense() * p).norm());
    const Eigen::MatrixXd J = sx * K.to_dense() + sv * D.to_dense();
    model.apply_product(lin, p, out);
    EXPECT_LT((out - J * p).norm(), 1e-12 * (J * p).norm());
    fc::BlockSparseMatrix assembled = model.make_jacobian_matrix();
    model.assemble_product(lin, assembled);
    EXPECT_LT((assembled.to_dense() - J).norm(), 1e-12 * J.norm());
}

TEST(ClothCellShear, APureShearStoresTheContinuumsEnergyAndAFoldAlongEitherDiagonalNone) {
    const double h = 0.05;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(2 * h, h, 2, 3);
    fc::ClothMaterial m = shear_material();
    fc::ClothModel model(mesh, m);
    ASSERT_EQ(model.cells().size(), 2u);
    const auto flat = [&](int i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        return Eigen::Vector3d(uv.x(), uv.y(), 0.0);
    };
    Eigen::VectorXd x(3 * mesh.vertex_count());
    const double gamma = 0.2;
    for (int i = 0; i < mesh.vertex_count(); ++i) x.segment<3>(3 * i) = flat(i) + Eigen::Vector3d(gamma * flat(i).y(), 0, 0);
    // w_u = (1, 0, 0), w_v = (gamma, 1, 0): C = gamma everywhere.
    // Each square cell's rising diagonal is pulled to sqrt((1 + gamma)^2 + 1) / sqrt 2.
    const double pulled = std::sqrt((1 + gamma) * (1 + gamma) + 1.0) / std::sqrt(2.0) - 1.0;
    const double expected = 0.5 * m.shear_N_per_m * 2 * h * h * gamma * gamma + 0.5 * m.diagonal_tension_N_per_m * 2 * h * h * pulled * pulled;
    EXPECT_NEAR(model.potential_energy(x, fc::ForceTerm::shear), expected, 1e-12 * expected);
    // Each cell of the 2 x 1 grid folded 60 degrees along each of its diagonals in turn.
    for (const fc::ClothModel::CellData& cell : model.cells())
        for (const bool along_edge : {true, false}) {
            for (int i = 0; i < mesh.vertex_count(); ++i) x.segment<3>(3 * i) = flat(i);
            // Fold line: the diagonal edge v0-v1 or the wings' v2-v3; one corner off it turns.
            const int a = along_edge ? cell.v[0] : cell.v[2], b = along_edge ? cell.v[1] : cell.v[3];
            // The corner that turns must be this cell's alone (the other cell keeps its shape).
            const auto shared = [&](int vertex) {
                for (const fc::ClothModel::CellData& other : model.cells())
                    if (&other != &cell && std::find(other.v.begin(), other.v.end(), vertex) != other.v.end()) return true;
                return false;
            };
            const int first = along_edge ? cell.v[2] : cell.v[0], second = along_edge ? cell.v[3] : cell.v[1];
            ASSERT_NE(shared(first), shared(second));
            const int moved = shared(first) ? second : first;
            const Eigen::Vector3d from = flat(a), axis = (flat(b) - flat(a)).normalized();
            x.segment<3>(3 * moved) = from + Eigen::AngleAxisd(M_PI / 3.0, axis) * (flat(moved) - from);
            const double stored = model.potential_energy(x, fc::ForceTerm::shear);
            std::printf("[ measured ] a cell folded 60 degrees along its %s diagonal stores %.1e J of shear\n",
                        along_edge ? "split" : "unsplit", stored);
            EXPECT_LT(stored, 1e-18);
        }
}

TEST(ClothCellShear, AShareOfTheShearOnTheCellsBlendsTheTwoReadings) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::ClothMaterial m = shear_material();
    m.diagonal_tension_N_per_m = 0.0;  // the shear alone
    const Eigen::VectorXd x = random_x(mesh, 7, 0.008);
    const unsigned terms = fc::ForceTerm::shear;
    const auto energy_and_force = [&](double share) {
        m.shear_cell_fraction = share;
        fc::ClothModel model(mesh, m);
        return std::make_pair(model.potential_energy(x, terms), force_of(model, x, terms));
    };
    const auto [e0, f0] = energy_and_force(0.0);
    const auto [e1, f1] = energy_and_force(1.0);
    const auto [e_quarter, f_quarter] = energy_and_force(0.25);
    std::printf("[ measured ] shear energy across triangles %.4e J, on cells %.4e J\n", e0, e1);
    EXPECT_GT(std::abs(e1 - e0), 1e-3 * e0);  // the readings differ on this shape
    EXPECT_NEAR(e_quarter, 0.75 * e0 + 0.25 * e1, 1e-12 * e0);
    EXPECT_LT((f_quarter - (0.75 * f0 + 0.25 * f1)).norm(), 1e-12 * f0.norm());
    // A share changed on a built model (as a fit does) rebuilds what it needs:
    // the same forces and linearisation as a model built with it.
    m.shear_cell_fraction = 0.0;
    fc::ClothModel changed(mesh, m);
    for (const double share : {1.0, 0.25, 0.0, 0.25}) {
        SCOPED_TRACE(share);
        m.shear_cell_fraction = share;
        changed.set_material(m);
        fc::ClothModel fresh(mesh, m);
        EXPECT_EQ(changed.cells().size(), fresh.cells().size());
        EXPECT_LT((force_of(changed, x, terms) - force_of(fresh, x, terms)).norm(), 1e-14 * f0.norm());
        fc::BlockSparseMatrix a = changed.make_jacobian_matrix(), b = fresh.make_jacobian_matrix();
        Eigen::VectorXd fa, fb;
        changed.evaluate(x, Eigen::VectorXd::Zero(x.size()), 0.0, terms, fa, &a, nullptr, fc::JacobianMode::exact);
        fresh.evaluate(x, Eigen::VectorXd::Zero(x.size()), 0.0, terms, fb, &b, nullptr, fc::JacobianMode::exact);
        EXPECT_LT((a.to_dense() - b.to_dense()).norm(), 1e-14 * b.to_dense().norm());
    }
}

TEST(ClothCellShear, AShareOutsideZeroToOneIsRefusedNamingTheKey) {
    fc::ClothMaterial m = shear_material();
    for (const double share : {-0.1, 1.5}) {
        m.shear_cell_fraction = share;
        const std::vector<flowvid::Problem> problems = fc::check_material(m);
        ASSERT_EQ(problems.size(), 1u) << share;
        EXPECT_EQ(problems[0].field, "/parameters/shear_cell_fraction/value");
        EXPECT_NE(problems[0].fix.find("0 (shear read across each triangle)"), std::string::npos);
    }
    m.shear_cell_fraction = 1.0;
    EXPECT_TRUE(fc::check_material(m).empty());
}
