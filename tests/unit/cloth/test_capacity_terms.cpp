// The terms the model capacity study added (docs/cloth_model.md):
// softer compression (ClothMaterial::stretch_*_compression_ratio: woven
// fabric shortens far more easily than it stretches), checked against the
// analytic energy of a uniform strain, finite differences of forces and
// Jacobians on configurations with both stretched and compressed
// triangles, the element-wise linearisation and the neutral value; the
// diagonal tension-only fibres (diagonal_tension_N_per_m), checked the same
// way and against the energy of a pure shear; and the hem
// (hem_line_density_kg_per_m), checked against the exact mass of each vertex
// and the swatch's weighed mass.

#include "flowvid/cloth/equilibrium.hpp"
#include "flowvid/cloth/geometry.hpp"
#include "flowvid/cloth/model.hpp"
#include "flowvid/cloth/simulator.hpp"
#include "flowvid/cloth/swatch.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <random>

namespace fc = flowvid::cloth;

namespace {

fc::ClothMaterial soft_compression_material() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = 120.0;
    m.stretch_weft_N_per_m = 80.0;
    m.shear_N_per_m = 40.0;
    m.bend_N_m = 2e-5;
    m.stretch_warp_damping_N_s_per_m = 0.02;
    m.stretch_weft_damping_N_s_per_m = 0.03;
    m.shear_damping_N_s_per_m = 0.01;
    m.stretch_warp_compression_ratio = 0.05;
    m.stretch_weft_compression_ratio = 0.3;
    return m;
}

struct Config {
    Eigen::VectorXd x, v;
};

// The swatch in 3D, rotated, every vertex moved randomly by up to `amplitude`
// (about half the spacing): some triangles stretched, some compressed.
Config random_config(const fc::ClothMesh& mesh, unsigned seed, double amplitude_m) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitZ())).toRotationMatrix();
    Config c;
    const int n = mesh.vertex_count();
    c.x.resize(3 * n);
    c.v.resize(3 * n);
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        c.x.segment<3>(3 * i) = R * (Eigen::Vector3d(uv.x(), uv.y(), 0.0) + amplitude_m * Eigen::Vector3d(u(rng), u(rng), u(rng)));
        c.v.segment<3>(3 * i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    return c;
}

Eigen::VectorXd force_of(fc::ClothModel& model, const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms) {
    Eigen::VectorXd f;
    model.evaluate(x, v, 0.0, terms, f);
    return f;
}

double relative_error(const Eigen::MatrixXd& analytic, const Eigen::MatrixXd& numeric) {
    const double scale = std::max(numeric.norm(), analytic.norm());
    return scale == 0.0 ? 0.0 : (analytic - numeric).norm() / scale;
}

// |w_u| and |w_v| of every triangle at positions x (1 = rest length).
std::vector<Eigen::Vector2d> stretch_ratios(const fc::ClothModel& model, const Eigen::VectorXd& x) {
    std::vector<Eigen::Vector2d> ratios;
    const fc::ClothMesh& mesh = model.mesh();
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector2d& u0 = mesh.material_uv_m[static_cast<size_t>(t[0])];
        const Eigen::Vector2d& u1 = mesh.material_uv_m[static_cast<size_t>(t[1])];
        const Eigen::Vector2d& u2 = mesh.material_uv_m[static_cast<size_t>(t[2])];
        Eigen::Matrix2d D;
        D << u1.x() - u0.x(), u2.x() - u0.x(), u1.y() - u0.y(), u2.y() - u0.y();
        Eigen::Matrix<double, 3, 2> E;
        E.col(0) = x.segment<3>(3 * t[1]) - x.segment<3>(3 * t[0]);
        E.col(1) = x.segment<3>(3 * t[2]) - x.segment<3>(3 * t[0]);
        const Eigen::Matrix<double, 3, 2> F = E * D.inverse();
        ratios.emplace_back(F.col(0).norm(), F.col(1).norm());
    }
    return ratios;
}

// Triangle axes (warp and weft) shorter / longer than at rest.
std::pair<int, int> compressed_and_stretched(const fc::ClothModel& model, const Eigen::VectorXd& x) {
    int compressed = 0, stretched = 0;
    for (const Eigen::Vector2d& r : stretch_ratios(model, x))
        for (int axis = 0; axis < 2; ++axis) (r(axis) < 1.0 ? compressed : stretched) += 1;
    return {compressed, stretched};
}

// Mean over triangles of |w_u|: below 1 where the rows are shortened in plane.
double mean_warp_stretch(const fc::ClothModel& model, const Eigen::VectorXd& x) {
    double sum = 0.0;
    const std::vector<Eigen::Vector2d> ratios = stretch_ratios(model, x);
    for (const Eigen::Vector2d& r : ratios) sum += r(0);
    return sum / static_cast<double>(ratios.size());
}

}  // namespace

TEST(ClothCompression, UniformStrainStoresTheRatiosShareInCompressionOnly) {
    // A flat swatch stretched or compressed uniformly along one axis by a
    // factor (1 + eps): every triangle has C = eps on that axis and 0 on the
    // other, so the energy is exactly k/2 * area * eps^2 (times the ratio when eps < 0).
    const double width = 0.2, height = 0.15;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(width, height, 6, 5);
    const fc::ClothMaterial m = soft_compression_material();
    fc::ClothModel model(mesh, m);
    for (int axis = 0; axis < 2; ++axis)
        for (double eps : {0.04, -0.04, -0.2}) {
            Eigen::VectorXd x(3 * mesh.vertex_count());
            for (int i = 0; i < mesh.vertex_count(); ++i) {
                Eigen::Vector2d uv = mesh.material_uv_m[static_cast<size_t>(i)];
                uv(axis) *= 1.0 + eps;
                x.segment<3>(3 * i) = Eigen::Vector3d(uv.x(), uv.y(), 0.0);
            }
            const double k = axis == 0 ? m.stretch_warp_N_per_m : m.stretch_weft_N_per_m;
            const double ratio = axis == 0 ? m.stretch_warp_compression_ratio : m.stretch_weft_compression_ratio;
            const double expected = 0.5 * (eps < 0.0 ? ratio * k : k) * width * height * eps * eps;
            const double energy = model.potential_energy(x, fc::ForceTerm::stretch);
            EXPECT_NEAR(energy, expected, 1e-12 * expected) << "axis " << axis << ", strain " << eps;
        }
}

TEST(ClothCompression, ForcesAndJacobiansMatchFiniteDifferences) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::ClothMaterial with_fibres = soft_compression_material();
    with_fibres.diagonal_tension_N_per_m = 70.0;  // the diagonal fibres too (they count as shear)
    fc::ClothModel model(mesh, with_fibres);
    for (unsigned seed : {1u, 2u, 3u}) {
        SCOPED_TRACE(seed);
        const Config c = random_config(mesh, seed, 0.008);
        const auto [compressed, stretched] = compressed_and_stretched(model, c.x);
        ASSERT_GT(compressed, 4) << "the check needs compressed triangles";
        ASSERT_GT(stretched, 4) << "and stretched ones";
        ASSERT_GT(model.potential_energy(c.x, fc::ForceTerm::shear),
                  fc::ClothModel(mesh, soft_compression_material()).potential_energy(c.x, fc::ForceTerm::shear))
            << "and pulled diagonals";
        for (unsigned terms : {unsigned(fc::ForceTerm::stretch), unsigned(fc::ForceTerm::shear),
                               unsigned(fc::ForceTerm::elastic | fc::ForceTerm::damping)}) {
            const Eigen::VectorXd f = force_of(model, c.x, c.v, terms);
            fc::BlockSparseMatrix dfdx = model.make_jacobian_matrix(), dfdv = model.make_jacobian_matrix();
            Eigen::VectorXd f2;
            model.evaluate(c.x, c.v, 0.0, terms, f2, &dfdx, &dfdv, fc::JacobianMode::exact);
            EXPECT_LT((f2 - f).norm(), 1e-12 * f.norm()) << "force-only and Jacobian paths disagree";
            const double h = 1e-7;
            Eigen::MatrixXd K_fd(c.x.size(), c.x.size());
            Eigen::VectorXd f_energy(c.x.size());
            for (Eigen::Index k = 0; k < c.x.size(); ++k) {
                Eigen::VectorXd xp = c.x, xm = c.x;
                xp(k) += h;
                xm(k) -= h;
                K_fd.col(k) = (force_of(model, xp, c.v, terms) - force_of(model, xm, c.v, terms)) / (2 * h);
                f_energy(k) = -(model.potential_energy(xp, terms) - model.potential_energy(xm, terms)) / (2 * h);
            }
            const double ex = relative_error(dfdx.to_dense(), K_fd);
            EXPECT_LT(ex, 2e-6) << "df/dx, terms " << terms;
            if (terms == fc::ForceTerm::stretch || terms == fc::ForceTerm::shear) {
                const double ef = relative_error(f, f_energy);
                EXPECT_LT(ef, 2e-6) << "force is not minus the energy gradient";
                std::printf("[ measured ] seed %u, %s: %d compressed and %d stretched axes; force vs energy %.1e, df/dx %.1e\n",
                            seed, terms == fc::ForceTerm::stretch ? "stretch" : "shear + diagonal fibres", compressed,
                            stretched, ef, ex);
            }
            // Definite mode stays symmetric negative semi-definite.
            model.evaluate(c.x, c.v, 0.0, terms, f2, &dfdx, &dfdv, fc::JacobianMode::definite);
            const Eigen::MatrixXd M = dfdx.to_dense();
            EXPECT_LT((M - M.transpose()).norm(), 1e-12 * M.norm());
            const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(-M).eigenvalues();
            EXPECT_GT(eig.minCoeff(), -1e-10 * M.norm());
        }
    }
}

TEST(ClothCompression, ElementwiseLinearizationEqualsTheAssembledJacobians) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    const Config c = random_config(mesh, 5, 0.008);
    fc::ClothMaterial m = soft_compression_material();
    m.diagonal_tension_N_per_m = 70.0;
    fc::ClothModel model(mesh, m);
    fc::BlockSparseMatrix K = model.make_jacobian_matrix(), D = model.make_jacobian_matrix();
    Eigen::VectorXd f1, f2, out;
    const unsigned terms = fc::ForceTerm::elastic | fc::ForceTerm::damping;
    model.evaluate(c.x, c.v, 0.0, terms, f1, &K, &D, fc::JacobianMode::definite);
    std::mt19937 rng(4);
    std::normal_distribution<double> normal;
    Eigen::VectorXd p(c.x.size());
    for (Eigen::Index k = 0; k < p.size(); ++k) p(k) = normal(rng);
    const double sx = 2e-4, sv = 0.03;
    fc::Linearization lin;
    model.linearize(c.x, c.v, 0.0, terms, sx, sv, f2, lin, &p);
    EXPECT_LT((f1 - f2).norm(), 1e-12 * f1.norm());
    EXPECT_LT((lin.dfdx_product - K.to_dense() * p).norm(), 1e-12 * (K.to_dense() * p).norm());
    const Eigen::MatrixXd J = sx * K.to_dense() + sv * D.to_dense();
    model.apply_product(lin, p, out);
    EXPECT_LT((out - J * p).norm(), 1e-12 * (J * p).norm());
}

TEST(ClothCompression, RatioOneIsTheSymmetricModelAndSofterCompressionShortensTheSlackEdge) {
    EXPECT_EQ(fc::ClothMaterial{}.stretch_warp_compression_ratio, 1.0);
    EXPECT_EQ(fc::ClothMaterial{}.stretch_weft_compression_ratio, 1.0);
    // A 0.2 m swatch hung by its top corners 0.12 m apart: the top edge is
    // compressed. The drape is the static equilibrium nearest the same bowed
    // start (a dynamic run is still swinging after seconds, and where it is
    // in its swing depends on the linear solver's tolerance).
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.2, 0.2, 10, 10);
    auto settle = [&](double ratio) {
        fc::ClothMaterial m = soft_compression_material();
        m.stretch_warp_compression_ratio = m.stretch_weft_compression_ratio = ratio;
        m.stretch_warp_damping_N_s_per_m = m.stretch_weft_damping_N_s_per_m = 0.01;
        m.bend_N_m = 1e-6;
        fc::ClothModel model(mesh, m);
        Eigen::VectorXd x0(3 * mesh.vertex_count());
        for (int i = 0; i < mesh.vertex_count(); ++i) {
            const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
            const double u = uv.x() / 0.2;
            x0.segment<3>(3 * i) = Eigen::Vector3d(0.04 + 0.6 * uv.x(), 0.01 * std::sin(M_PI * u), uv.y());
        }
        std::vector<bool> fixed(static_cast<size_t>(mesh.vertex_count()), false);
        fixed[9 * 10] = fixed[10 * 10 - 1] = true;
        const fc::EquilibriumReport r = fc::solve_static_equilibrium(model, fixed, x0);
        EXPECT_TRUE(r.converged) << r.reason;
        return x0;
    };
    // Below the pins the hanging cloth is narrower than its rest width: with
    // symmetric stiffness the rows keep their length and bow out of plane;
    // where compression is cheap they shorten in place instead.
    fc::ClothModel probe(mesh, soft_compression_material());
    const Eigen::VectorXd symmetric = settle(1.0), soft = settle(0.01);
    const double warp_symmetric = mean_warp_stretch(probe, symmetric), warp_soft = mean_warp_stretch(probe, soft);
    const int top_middle = 9 * 10 + 5;
    std::printf("[ measured ] mean warp stretch |w_u| %.4f, top edge sags %.1f mm (symmetric); %.4f, %.1f mm "
                "(compression ratio 0.01)\n",
                warp_symmetric, 1e3 * (0.2 - symmetric(3 * top_middle + 2)), warp_soft, 1e3 * (0.2 - soft(3 * top_middle + 2)));
    EXPECT_NEAR(warp_symmetric, 1.0, 1e-3) << "symmetric stiffness keeps the rows' length";
    EXPECT_LT(warp_soft, warp_symmetric - 5e-4) << "soft compression lets them shorten";
    EXPECT_GT(std::abs(symmetric(3 * top_middle + 2) - soft(3 * top_middle + 2)), 3e-3) << "and the drape changes visibly";
}

TEST(ClothHem, BoundaryVerticesCarryTheHemsLineDensity) {
    // A 0.2 x 0.1 m swatch, 5 x 3 vertices (spacing 0.05 m): each boundary
    // vertex gets the hem of half of each incident boundary edge.
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.2, 0.1, 3, 5);
    fc::ClothMaterial m = soft_compression_material();
    m.hem_line_density_kg_per_m = 0.002;
    const fc::ClothModel model(mesh, m);
    EXPECT_NEAR(model.boundary_length_m(), 0.6, 1e-15);
    EXPECT_NEAR(model.total_mass_kg(), m.areal_density_kg_per_m2 * 0.02 + 0.002 * 0.6, 1e-15);
    const fc::ClothModel plain(mesh, soft_compression_material());
    // Vertex 0 is a corner (edges of 0.05 along u and v), 2 mid-bottom, 7 interior.
    EXPECT_NEAR(model.vertex_masses_kg()(0) - plain.vertex_masses_kg()(0), 0.002 * 0.05, 1e-15);
    EXPECT_NEAR(model.vertex_masses_kg()(2) - plain.vertex_masses_kg()(2), 0.002 * 0.05, 1e-15);
    EXPECT_EQ(model.vertex_masses_kg()(7), plain.vertex_masses_kg()(7));
    // At 0 the masses are the areal density's, bit for bit.
    fc::ClothMaterial zero = soft_compression_material();
    zero.hem_line_density_kg_per_m = 0.0;
    EXPECT_TRUE(fc::ClothModel(mesh, zero).vertex_masses_kg() == plain.vertex_masses_kg());
}

TEST(ClothHem, TheSwatchWeighsItsDeclaredMassWithAHem) {
    // experiment_material takes the hem's share off the areal density, so the
    // swatch still weighs what capture.json says, at any resolution.
    fc::SwatchExperiment e;
    e.width_m = 0.3;
    e.height_m = 0.2;
    e.mass_kg = 0.012;
    fc::ClothMaterial m = soft_compression_material();
    m.hem_line_density_kg_per_m = 0.004;
    const fc::ClothMaterial applied = fc::experiment_material(e, m);
    EXPECT_NEAR(applied.areal_density_kg_per_m2, (0.012 - 0.004 * 1.0) / 0.06, 1e-15);
    for (const int n : {6, 12, 24}) {
        const fc::ClothModel model(fc::make_swatch_mesh(0.3, 0.2, n, n), applied);
        EXPECT_NEAR(model.total_mass_kg(), 0.012, 1e-15) << n;
    }
    m.hem_line_density_kg_per_m = 0.1;  // heavier than the swatch: the cloth keeps 5 %
    EXPECT_NEAR(fc::experiment_material(e, m).areal_density_kg_per_m2, 0.05 * 0.012 / 0.06, 1e-15);
    m.hem_line_density_kg_per_m = 0.0;
    EXPECT_EQ(fc::experiment_material(e, m).areal_density_kg_per_m2, 0.012 / (0.3 * 0.2));
}

TEST(ClothDiagonalFibres, PureShearPullsOneDiagonalOnly) {
    // A flat shear x -> x + gamma y (rest coordinates u, v): w_u = (1, 0, 0),
    // w_v = (gamma, 1, 0). The diagonal (w_u + w_v)/sqrt 2 lengthens, the other
    // shortens and is slack: E = k/2 * area * (|w_u + w_v|/sqrt 2 - 1)^2 exactly,
    // the same energy for -gamma (the other diagonal), none at gamma = 0.
    const double width = 0.2, height = 0.15;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(width, height, 6, 5);
    fc::ClothMaterial m = soft_compression_material();
    m.diagonal_tension_N_per_m = 70.0;
    m.shear_N_per_m = 0.0;
    fc::ClothModel model(mesh, m);
    for (double gamma : {0.0, 0.1, -0.1, 0.3}) {
        Eigen::VectorXd x(3 * mesh.vertex_count());
        for (int i = 0; i < mesh.vertex_count(); ++i) {
            const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
            x.segment<3>(3 * i) = Eigen::Vector3d(uv.x() + gamma * uv.y(), uv.y(), 0.0);
        }
        const double pulled = Eigen::Vector3d(1.0 + std::abs(gamma), 1.0, 0.0).norm() / std::sqrt(2.0) - 1.0;
        const double expected = 0.5 * 70.0 * width * height * pulled * pulled;
        EXPECT_NEAR(model.potential_energy(x, fc::ForceTerm::shear), expected, 1e-12 * std::max(expected, 1e-12)) << gamma;
    }
    EXPECT_EQ(fc::ClothMaterial{}.diagonal_tension_N_per_m, 0.0);
}

TEST(ClothDiagonalFibres, OnAGridEachCellMeasuresItsOwnDiagonalEdge) {
    // On a grid whose cells alternate their diagonals, each fibre family is
    // measured on the cells' real diagonal edges only: E = k * A_cell *
    // max(|e| / |e_rest| - 1, 0)^2 per diagonal edge (the two triangles on it
    // count twice the area of triangles that measure both families, as half
    // the cells carry each family). Computed here from the edges' lengths,
    // with no deformation gradient, on random configurations.
    const double h = 0.02;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(4 * h, 3 * h, 4, 5);  // 4 x 3 square cells
    fc::ClothMaterial m = soft_compression_material();
    m.diagonal_tension_N_per_m = 70.0;
    m.shear_N_per_m = 0.0;
    fc::ClothModel model(mesh, m);
    for (unsigned seed : {1u, 2u}) {
        const Config c = random_config(mesh, seed, 0.006);
        double expected = 0.0;
        int pulled = 0;
        for (int r = 0; r + 1 < 4; ++r)
            for (int col = 0; col + 1 < 5; ++col) {
                // The edge make_swatch_mesh splits the cell along.
                const bool rising = (r + col) % 2 == 0;
                const int a = rising ? r * 5 + col : r * 5 + col + 1;
                const int b = rising ? (r + 1) * 5 + col + 1 : (r + 1) * 5 + col;
                const double stretch = (c.x.segment<3>(3 * a) - c.x.segment<3>(3 * b)).norm() / (std::sqrt(2.0) * h) - 1.0;
                if (stretch > 0.0) ++pulled;
                // 6 of the 12 cells carry each family, so each edge stands
                // for twice its cell's area: 2 * k/2 * h^2 * stretch^2.
                expected += 70.0 * h * h * std::pow(std::max(stretch, 0.0), 2);
            }
        ASSERT_GT(pulled, 2) << "the check needs pulled diagonals";
        EXPECT_NEAR(model.potential_energy(c.x, fc::ForceTerm::shear), expected, 1e-12 * expected) << seed;
    }
}

TEST(ClothDiagonalFibres, ACellFoldsAlongItsOtherDiagonalWithoutPullingAFibre) {
    // Two square cells; the second is split along its falling diagonal. Its
    // corner on the far side of the rising diagonal is turned 60 degrees
    // about that diagonal: a fold along a line no edge follows. The cell's
    // sides keep their lengths and its real (falling) diagonal shortens, so a
    // fabric of tension-only bias fibres folds there freely. A fibre measured
    // across each triangle to a point in its own plane was stretched by
    // 1 - cos 60 = 50 % of its squared rest length instead: the coarse-mesh
    // lock of docs/cloth_model.md. A pure in-plane shear of the same mesh
    // still stores the continuum's energy.
    const double h = 0.05;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(2 * h, h, 2, 3);
    fc::ClothMaterial m = soft_compression_material();
    m.diagonal_tension_N_per_m = 70.0;
    m.shear_N_per_m = 0.0;
    fc::ClothModel model(mesh, m);
    const auto flat = [&](int i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        return Eigen::Vector3d(uv.x(), uv.y(), 0.0);
    };
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) x.segment<3>(3 * i) = flat(i);
    // Vertex 2 = (2h, 0), the far corner; the axis runs from vertex 1 (h, 0) to vertex 5 (2h, h).
    const Eigen::Vector3d axis_from = flat(1), axis = (flat(5) - flat(1)).normalized();
    x.segment<3>(6) = axis_from + Eigen::AngleAxisd(M_PI / 3.0, axis) * (flat(2) - axis_from);
    EXPECT_NEAR((x.segment<3>(6) - x.segment<3>(3)).norm(), h, 1e-15);
    EXPECT_NEAR((x.segment<3>(6) - x.segment<3>(15)).norm(), h, 1e-15);
    EXPECT_LT((x.segment<3>(6) - x.segment<3>(12)).norm(), 0.9 * std::sqrt(2.0) * h);  // the real diagonal shortens
    // (The flat cell's fibres sit at |w_d| = 1 up to rounding.) The in-plane
    // measure would store 0.5 k A (sqrt(1.25) - 1)^2 = 6e-4 J in this cell.
    EXPECT_LT(model.potential_energy(x, fc::ForceTerm::shear), 1e-18);
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        x.segment<3>(3 * i) = Eigen::Vector3d(uv.x() + 0.2 * uv.y(), uv.y(), 0.0);
    }
    const double pulled = Eigen::Vector3d(1.2, 1.0, 0.0).norm() / std::sqrt(2.0) - 1.0;
    const double expected = 0.5 * 70.0 * 2 * h * h * pulled * pulled;
    EXPECT_NEAR(model.potential_energy(x, fc::ForceTerm::shear), expected, 1e-12 * expected);
}
