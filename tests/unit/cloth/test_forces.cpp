// Finite-difference checks of every cloth force against its energy, and of
// every analytic Jacobian (df/dx, df/dv) against differences of the force, on
// random deformed configurations with fixed seeds.

#include "flowvid/cloth/geometry.hpp"
#include "flowvid/cloth/model.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cstdio>
#include <random>

namespace fc = flowvid::cloth;

namespace {

fc::ClothMaterial test_material() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = 120.0;
    m.stretch_weft_N_per_m = 80.0;
    m.shear_N_per_m = 40.0;
    m.bend_N_m = 2e-5;
    m.stretch_warp_damping_N_s_per_m = 0.02;
    m.stretch_weft_damping_N_s_per_m = 0.03;
    m.shear_damping_N_s_per_m = 0.01;
    m.bend_damping_N_m_s = 1e-6;
    m.drag_normal_kg_per_m3 = 0.8;
    m.drag_degradation_s2_per_m2 = 0.5;
    m.drag_tangential_kg_per_m2_s = 0.2;
    m.drag_linear_normal_kg_per_m2_s = 0.3;  // the linear-drag comparison model's term
    return m;
}

// A 5 x 4 swatch, lifted to 3D, rotated and randomly deformed (the folds are
// large: up to ~40% of the spacing), with random velocities.
struct Config {
    Eigen::VectorXd x, v;
};

Config random_config(const fc::ClothMesh& mesh, unsigned seed, double amplitude_m = 0.012) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitZ())).toRotationMatrix();
    Config c;
    const int n = mesh.vertex_count();
    c.x.resize(3 * n);
    c.v.resize(3 * n);
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        Eigen::Vector3d p(uv.x(), uv.y(), 0.0);
        p += amplitude_m * Eigen::Vector3d(u(rng), u(rng), u(rng));
        c.x.segment<3>(3 * i) = R * p + Eigen::Vector3d(0.1, -0.2, 1.0);
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
    if (scale == 0.0) return 0.0;
    return (analytic - numeric).norm() / scale;
}

// Central differences of the force with respect to x (or v).
Eigen::MatrixXd numeric_jacobian(fc::ClothModel& model, const Config& c, unsigned terms, bool wrt_velocity, double h) {
    const Eigen::Index n = c.x.size();
    Eigen::MatrixXd J(n, n);
    for (Eigen::Index k = 0; k < n; ++k) {
        Config plus = c, minus = c;
        (wrt_velocity ? plus.v : plus.x)(k) += h;
        (wrt_velocity ? minus.v : minus.x)(k) -= h;
        J.col(k) = (force_of(model, plus.x, plus.v, terms) - force_of(model, minus.x, minus.v, terms)) / (2 * h);
    }
    return J;
}

Eigen::VectorXd numeric_force_from_energy(fc::ClothModel& model, const Eigen::VectorXd& x, unsigned terms, double h) {
    Eigen::VectorXd f(x.size());
    for (Eigen::Index k = 0; k < x.size(); ++k) {
        Eigen::VectorXd xp = x, xm = x;
        xp(k) += h;
        xm(k) -= h;
        f(k) = -(model.potential_energy(xp, terms) - model.potential_energy(xm, terms)) / (2 * h);
    }
    return f;
}

struct TermCase {
    const char* name;
    unsigned terms;
    bool conservative;
    bool velocity_dependent;
};

void check_terms(fc::ClothModel& model, const Config& c, const TermCase& t, double tolerance = 2e-6) {
    SCOPED_TRACE(t.name);
    const Eigen::VectorXd f = force_of(model, c.x, c.v, t.terms);
    ASSERT_TRUE(f.allFinite());
    ASSERT_GT(f.norm(), 0.0) << "the term exerts no force in this configuration; the check would be empty";
    double ef = 0.0;
    if (t.conservative) {
        const Eigen::VectorXd fe = numeric_force_from_energy(model, c.x, t.terms, 1e-7);
        ef = relative_error(f, fe);
        EXPECT_LT(ef, tolerance) << "force is not minus the energy gradient";
    }
    fc::BlockSparseMatrix dfdx = model.make_jacobian_matrix(), dfdv = model.make_jacobian_matrix();
    Eigen::VectorXd f2;
    model.evaluate(c.x, c.v, 0.0, t.terms, f2, &dfdx, &dfdv, fc::JacobianMode::exact);
    EXPECT_LT((f2 - f).norm(), 1e-12 * f.norm()) << "force-only and Jacobian paths disagree";
    const Eigen::MatrixXd Kx = dfdx.to_dense();
    const Eigen::MatrixXd Kx_fd = numeric_jacobian(model, c, t.terms, false, 1e-7);
    const double ex = relative_error(Kx, Kx_fd);
    EXPECT_LT(ex, tolerance) << "df/dx";
    const Eigen::MatrixXd Kv = dfdv.to_dense();
    const Eigen::MatrixXd Kv_fd = numeric_jacobian(model, c, t.terms, true, 1e-7);
    const double ev = relative_error(Kv, Kv_fd);
    std::printf("[ measured ] %-16s relative error: force vs energy %.1e, df/dx %.1e, df/dv %.1e\n", t.name, ef, ex, ev);
    if (t.velocity_dependent) {
        EXPECT_GT(Kv_fd.norm(), 0.0);
        EXPECT_LT(ev, tolerance) << "df/dv";
    } else {
        EXPECT_EQ(Kv_fd.norm(), 0.0);
        EXPECT_EQ(Kv.norm(), 0.0);
    }
    // Definite mode: symmetric, and -df/dx, -df/dv positive semi-definite.
    model.evaluate(c.x, c.v, 0.0, t.terms, f2, &dfdx, &dfdv, fc::JacobianMode::definite);
    for (const Eigen::MatrixXd& M : {dfdx.to_dense(), dfdv.to_dense()}) {
        const double scale = std::max(M.norm(), 1e-300);
        EXPECT_LT((M - M.transpose()).norm() / scale, 1e-12);
        const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(-0.5 * (M + M.transpose())).eigenvalues();
        EXPECT_GT(eig.minCoeff(), -1e-10 * scale) << "definite Jacobian has a negative direction";
    }
}

}  // namespace

TEST(ClothForces, MembraneBendingDampingDragGravity) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::Environment env;
    env.wind_m_per_s = Eigen::Vector3d(0.3, -0.2, 0.1);
    fc::ClothModel model(mesh, test_material(), env);
    const TermCase cases[] = {
        {"stretch", fc::ForceTerm::stretch, true, false},
        {"shear", fc::ForceTerm::shear, true, false},
        {"bending", fc::ForceTerm::bending, true, false},
        {"stretch_damping", fc::ForceTerm::stretch_damping, false, true},
        {"shear_damping", fc::ForceTerm::shear_damping, false, true},
        {"bending_damping", fc::ForceTerm::bending_damping, false, true},
        {"drag", fc::ForceTerm::drag, false, true},
        {"gravity", fc::ForceTerm::gravity, true, false},
        {"all", fc::ForceTerm::elastic | fc::ForceTerm::damping | fc::ForceTerm::drag | fc::ForceTerm::gravity, false, true},
    };
    for (unsigned seed : {1u, 2u, 3u}) {
        SCOPED_TRACE(seed);
        const Config c = random_config(mesh, seed);
        for (const TermCase& t : cases) check_terms(model, c, t);
    }
}

TEST(ClothForces, WindPushesAsOnAFlatPlate) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::Environment env;
    env.wind_m_per_s = Eigen::Vector3d(0.6, -1.1, 0.4);
    env.wind_pressure_kg_per_m3 = 0.72;
    // The Jacobians with the drag law and the plate push together.
    {
        fc::ClothModel model(mesh, test_material(), env);
        for (unsigned seed : {4u, 5u}) {
            SCOPED_TRACE(seed);
            check_terms(model, random_config(mesh, seed), {"drag+plate", fc::ForceTerm::drag, false, true});
        }
    }
    // The push alone (no drag law) on a flat swatch at rest: its area times
    // c (w.n)^2 along the normal, the force of wind on a plate.
    fc::ClothMaterial still = test_material();
    still.drag_normal_kg_per_m3 = 0.0;
    still.drag_tangential_kg_per_m2_s = 0.0;
    still.drag_linear_normal_kg_per_m2_s = 0.0;
    fc::ClothModel model(mesh, still, env);
    const Eigen::Vector3d normal = Eigen::Vector3d(0.2, -1.0, 0.3).normalized();
    const Eigen::Vector3d across = normal.cross(Eigen::Vector3d::UnitZ()).normalized(), up = normal.cross(across);
    Eigen::VectorXd x(3 * mesh.vertex_count()), v = Eigen::VectorXd::Zero(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        x.segment<3>(3 * i) = uv.x() * across + uv.y() * up;
    }
    const Eigen::VectorXd f = force_of(model, x, v, fc::ForceTerm::drag);
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (int i = 0; i < mesh.vertex_count(); ++i) total += f.segment<3>(3 * i);
    const double w_n = env.wind_m_per_s.dot(across.cross(up));
    const Eigen::Vector3d expected = 0.08 * 0.06 * 0.72 * w_n * std::abs(w_n) * across.cross(up);
    std::printf("[ measured ] plate push %.6g N, expected %.6g N\n", total.norm(), expected.norm());
    EXPECT_LT((total - expected).norm(), 1e-12 * expected.norm());
    // No push without the coefficient: the drag law alone (here none).
    fc::Environment plain = env;
    plain.wind_pressure_kg_per_m3 = 0.0;
    fc::ClothModel without(mesh, still, plain);
    EXPECT_EQ(force_of(without, x, v, fc::ForceTerm::drag).norm(), 0.0);
}

TEST(ClothForces, DragWithoutDegradationAndAtLowSpeed) {
    // kf = 0 and near-zero normal speed exercise the |v_N| kink of the drag law.
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.05, 0.05, 3, 3);
    fc::ClothMaterial m = test_material();
    m.drag_degradation_s2_per_m2 = 0.0;
    fc::ClothModel model(mesh, m);
    Config c = random_config(mesh, 7, 0.004);
    c.v *= 0.05;
    check_terms(model, c, {"drag", fc::ForceTerm::drag, false, true});
}

TEST(ClothForces, DihedralAngleIsRobustNearFlatAndFolded) {
    // Exact angles, including almost folded onto itself (atan2 keeps it accurate).
    const Eigen::Vector3d x0(0, 0, 0), x1(1, 0, 0), x2(0.4, 1, 0);
    for (double angle : {0.0, 1e-7, 0.3, -1.2, 2.5, 3.1415}) {
        const Eigen::Vector3d x3(0.6, -std::cos(angle), -std::sin(angle));
        // Wing B rotated by `angle` about the edge away from the flat position.
        const double theta = fc::dihedral_angle(x0, x1, x2, x3);
        EXPECT_NEAR(std::abs(theta), std::abs(angle), 1e-12) << angle;
    }
    // Hessian against differences of the gradient at a generic hinge.
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        Eigen::Vector3d p[4];
        for (auto& q : p) q = Eigen::Vector3d(u(rng), u(rng), u(rng));
        double theta;
        fc::Vector12d g;
        fc::Matrix12d H;
        ASSERT_TRUE(fc::dihedral_angle_hessian(p[0], p[1], p[2], p[3], theta, g, H));
        fc::Matrix12d H_fd;
        fc::Vector12d g_fd;
        for (int k = 0; k < 12; ++k) {
            Eigen::Vector3d a[4], b[4];
            for (int j = 0; j < 4; ++j) a[j] = b[j] = p[j];
            a[k / 3](k % 3) += 1e-6;
            b[k / 3](k % 3) -= 1e-6;
            double ta, tb;
            fc::Vector12d ga, gb;
            fc::dihedral_angle_gradient(a[0], a[1], a[2], a[3], ta, ga);
            fc::dihedral_angle_gradient(b[0], b[1], b[2], b[3], tb, gb);
            H_fd.col(k) = (ga - gb) / 2e-6;
            g_fd(k) = std::remainder(ta - tb, 2 * M_PI) / 2e-6;
        }
        EXPECT_LT((g - g_fd).norm() / g.norm(), 1e-7);
        EXPECT_LT((H - H_fd).norm() / H.norm(), 1e-6);
    }
}

TEST(ClothForces, BodyContactsAndFriction) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    const Config base = random_config(mesh, 5, 0.003);
    // Put bodies right under the cloth so that several vertices are in the layer.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int i = 0; i < mesh.vertex_count(); ++i) centroid += base.x.segment<3>(3 * i);
    centroid /= mesh.vertex_count();
    // Cloth normal, roughly: the rotation applied to z.
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitZ())).toRotationMatrix();
    const Eigen::Vector3d normal = R * Eigen::Vector3d::UnitZ();
    fc::MeshCollider box;  // a slightly tilted square under the middle of the cloth
    {
        const Eigen::Vector3d o = centroid - 0.0025 * normal;
        const Eigen::Vector3d t1 = R * Eigen::Vector3d::UnitX(), t2 = R * Eigen::Vector3d::UnitY();
        box.vertices_m = {o - 0.025 * t1 - 0.02 * t2, o + 0.025 * t1 - 0.02 * t2 + 0.001 * normal,
                          o + 0.025 * t1 + 0.02 * t2, o - 0.025 * t1 + 0.02 * t2 - 0.001 * normal};
        box.triangles = {{0, 1, 2}, {0, 2, 3}};  // counter-clockwise seen from the cloth
    }
    struct Body {
        const char* name;
        fc::Collider collider;
    };
    const Body bodies[] = {
        {"plane", fc::PlaneCollider{centroid - 0.002 * normal, normal}},
        {"sphere", fc::SphereCollider{centroid - 0.031 * normal, 0.03}},
        {"capsule", fc::CapsuleCollider{centroid - 0.022 * normal - 0.03 * (R * Eigen::Vector3d::UnitX()),
                                        centroid - 0.022 * normal + 0.01 * (R * Eigen::Vector3d::UnitX()), 0.02}},
        {"mesh", box},
    };
    for (const Body& body : bodies) {
        SCOPED_TRACE(body.name);
        fc::Environment env;
        env.colliders = {body.collider};
        env.contact.thickness_m = 0.004;
        env.contact.stiffness_per_m_s2 = 1e8;
        env.contact.friction_coefficient = 0.4;
        env.contact.friction_smoothing_m_per_s = 0.05;
        fc::ClothModel model(mesh, test_material(), env);
        check_terms(model, base, {"contact", fc::ForceTerm::body_contact, true, false});
        check_terms(model, base, {"friction", fc::ForceTerm::friction, false, true}, 5e-6);
    }
}

TEST(ClothForces, SelfContact) {
    // Two 4 x 4 patches, the second 2 mm above the first and shifted, far
    // apart in material space: each vertex of one sees triangles of the other.
    const fc::ClothMesh patch = fc::make_swatch_mesh(0.03, 0.03, 4, 4);
    fc::ClothMesh mesh = patch;
    for (const auto& uv : patch.material_uv_m) mesh.material_uv_m.push_back(uv + Eigen::Vector2d(1.0, 0.0));
    for (const auto& t : patch.triangles)
        mesh.triangles.push_back({t[0] + patch.vertex_count(), t[1] + patch.vertex_count(), t[2] + patch.vertex_count()});
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Config c;
    c.x.resize(3 * mesh.vertex_count());
    c.v = Eigen::VectorXd::Zero(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const bool upper = i >= patch.vertex_count();
        const Eigen::Vector2d uv = patch.material_uv_m[static_cast<size_t>(i % patch.vertex_count())];
        c.x.segment<3>(3 * i) = Eigen::Vector3d(uv.x() + (upper ? 0.0043 : 0.0), uv.y() + (upper ? 0.0031 : 0.0),
                                                upper ? 0.0021 : 0.0) +
                                0.0004 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    fc::Environment env;
    env.self_contact.enabled = true;
    env.self_contact.thickness_m = 0.003;
    env.self_contact.stiffness_per_m_s2 = 1e8;
    fc::ClothModel model(mesh, test_material(), env);
    check_terms(model, c, {"self_contact", fc::ForceTerm::self_contact, true, false}, 5e-6);
    EXPECT_GT(model.contact_statistics().self_candidates, 20);
}

TEST(ClothForces, FeatureDistanceHessian) {
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int size = 1; size <= 3; ++size) {
        for (int trial = 0; trial < 10; ++trial) {
            Eigen::Vector3d y[3], p(u(rng), u(rng), u(rng) + 2.0);
            for (auto& q : y) q = Eigen::Vector3d(u(rng), u(rng), u(rng));
            fc::FeatureDistance fd;
            ASSERT_TRUE(fc::feature_distance(p, y, size, true, fd));
            const int n = 3 * (size + 1);
            Eigen::MatrixXd H_fd(n, n);
            for (int k = 0; k < n; ++k) {
                Eigen::Vector3d pa = p, pb = p, ya[3] = {y[0], y[1], y[2]}, yb[3] = {y[0], y[1], y[2]};
                (k < 3 ? pa : ya[k / 3 - 1])(k % 3) += 1e-6;
                (k < 3 ? pb : yb[k / 3 - 1])(k % 3) -= 1e-6;
                fc::FeatureDistance a, b;
                fc::feature_distance(pa, ya, size, false, a);
                fc::feature_distance(pb, yb, size, false, b);
                H_fd.col(k) = (a.gradient - b.gradient) / 2e-6;
            }
            EXPECT_LT((Eigen::MatrixXd(fd.hessian) - H_fd).norm() / H_fd.norm(), 1e-6) << "feature size " << size;
        }
    }
}

TEST(ClothForces, ElementwiseLinearizationEqualsTheAssembledDefiniteJacobians) {
    // The implicit integrator never assembles: its element-wise products must
    // be those of the assembled definite matrices (all terms, contacts too).
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    const Config c = random_config(mesh, 9, 0.003);
    fc::Environment env;
    env.wind_m_per_s = Eigen::Vector3d(0.1, 0.2, -0.3);
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int i = 0; i < mesh.vertex_count(); ++i) centroid += c.x.segment<3>(3 * i) / mesh.vertex_count();
    env.colliders = {fc::SphereCollider{centroid - Eigen::Vector3d(0, 0, 0.031), 0.03}};
    env.contact.friction_coefficient = 0.3;
    env.self_contact.enabled = true;
    fc::ClothModel model(mesh, test_material(), env);
    fc::BlockSparseMatrix K = model.make_jacobian_matrix(), D = model.make_jacobian_matrix();
    Eigen::VectorXd f1, f2, out;
    model.evaluate(c.x, c.v, 0.0, fc::ForceTerm::all, f1, &K, &D, fc::JacobianMode::definite);
    const double sx = 2e-4, sv = 0.03;
    std::mt19937 rng(4);
    std::normal_distribution<double> normal;
    Eigen::VectorXd p(c.x.size());
    for (Eigen::Index k = 0; k < p.size(); ++k) p(k) = normal(rng);
    fc::Linearization lin;
    model.linearize(c.x, c.v, 0.0, fc::ForceTerm::all, sx, sv, f2, lin, &p);
    EXPECT_LT((f1 - f2).norm(), 1e-12 * f1.norm());
    const Eigen::MatrixXd J = sx * K.to_dense() + sv * D.to_dense();
    EXPECT_LT((lin.dfdx_product - K.to_dense() * p).norm(), 1e-12 * (K.to_dense() * p).norm());
    model.apply_product(lin, p, out);
    EXPECT_LT((out - J * p).norm(), 1e-12 * (J * p).norm());
    fc::BlockSparseMatrix assembled = model.make_jacobian_matrix();
    model.assemble_product(lin, assembled);
    EXPECT_LT((assembled.to_dense() - J).norm(), 1e-12 * J.norm());
    // The same with two worker threads: bit-identical forces and matrix.
    model.set_threads(2);
    Eigen::VectorXd f3;
    fc::Linearization lin2;
    model.linearize(c.x, c.v, 0.0, fc::ForceTerm::all, sx, sv, f3, lin2, &p);
    EXPECT_TRUE(lin2.dfdx_product == lin.dfdx_product);
    fc::BlockSparseMatrix assembled2 = model.make_jacobian_matrix();
    model.assemble_product(lin2, assembled2);
    EXPECT_TRUE(f3 == f2);
    EXPECT_TRUE(assembled2.to_dense() == assembled.to_dense());
}

TEST(ClothForces, BendingNormalisationMatchesTheContinuumAtEveryResolution) {
    // A swatch wrapped on a cylinder of radius R along u, then along v: the
    // bending energy must be k/2 * area / R^2 whatever the resolution. The
    // outermost strip of hinges is missing on a finite grid, hence the exact
    // factor (n - 2) / (n - 1) for hinges across the bend.
    for (int n : {12, 24, 48}) {
        const fc::ClothMesh mesh = fc::make_swatch_mesh(0.3, 0.2, n, n);
        fc::ClothMaterial m;
        m.bend_N_m = 2e-5;
        fc::ClothModel model(mesh, m);
        const double R = 0.1;
        for (int axis = 0; axis < 2; ++axis) {
            Eigen::VectorXd x(3 * mesh.vertex_count());
            for (int i = 0; i < mesh.vertex_count(); ++i) {
                const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
                const double s = uv(axis), t = uv(1 - axis);
                x.segment<3>(3 * i) = Eigen::Vector3d(R * std::sin(s / R), t, R * (1.0 - std::cos(s / R)));
            }
            const double energy = model.potential_energy(x, fc::ForceTerm::bending) * (n - 1.0) / (n - 2.0);
            const double continuum = 0.5 * m.bend_N_m * model.total_rest_area_m2() / (R * R);
            std::printf("[ measured ] bending energy on a cylinder, %dx%d, along %s: %.5f of the continuum\n", n, n,
                        axis == 0 ? "u" : "v", energy / continuum);
            EXPECT_NEAR(energy / continuum, 1.0, 0.01);
        }
        // Membrane: 10% stretch along u, 5% along v and a 0.1 shear strain
        // (x = F X) cost (k/2) A C^2 summed over the three conditions, exactly.
        m.stretch_warp_N_per_m = 120.0;
        m.stretch_weft_N_per_m = 80.0;
        m.shear_N_per_m = 40.0;
        model.set_material(m);
        Eigen::Matrix<double, 3, 2> F;
        F << 1.1, 0.0, 0.0, 1.05, 0.0, 0.0;
        const Eigen::Vector3d wv = (F.col(1) + 0.1 / 1.1 * F.col(0)).normalized() * 1.05;
        F.col(1) = wv;
        Eigen::VectorXd x(3 * mesh.vertex_count());
        for (int i = 0; i < mesh.vertex_count(); ++i) x.segment<3>(3 * i) = F * mesh.material_uv_m[static_cast<size_t>(i)];
        const double cu = F.col(0).norm() - 1.0, cv = F.col(1).norm() - 1.0, cs = F.col(0).dot(F.col(1));
        const double expected =
            0.5 * model.total_rest_area_m2() * (120.0 * cu * cu + 80.0 * cv * cv + 40.0 * cs * cs);
        EXPECT_NEAR(model.potential_energy(x, fc::ForceTerm::stretch | fc::ForceTerm::shear), expected, 1e-12 * expected);
    }
}
