// The two optional cloth-model terms of the gap diagnosis: the weave's bias
// angle (anisotropy effect) and bending memory (hysteresis effect). Their
// neutral values must reproduce the base model bit for bit; away from neutral
// they are checked against analytic energies, finite differences and the
// exponential memory law.

#include "flowvid/cloth/equilibrium.hpp"
#include "flowvid/cloth/geometry.hpp"
#include "flowvid/cloth/simulator.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <random>

namespace fc = flowvid::cloth;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Every term that the two effects touch is on (damping and drag too), so the
// neutral check covers the force-only, linearised and assembled paths.
fc::ClothMaterial wave_material() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = 150.0;
    m.stretch_weft_N_per_m = 100.0;
    m.shear_N_per_m = 60.0;
    m.bend_N_m = 2e-5;
    m.stretch_warp_damping_N_s_per_m = 0.01;
    m.stretch_weft_damping_N_s_per_m = 0.01;
    m.shear_damping_N_s_per_m = 0.005;
    m.bend_damping_N_m_s = 1e-7;
    m.drag_normal_kg_per_m3 = 0.8;
    m.drag_degradation_s2_per_m2 = 0.5;
    m.drag_tangential_kg_per_m2_s = 0.1;
    return m;
}

fc::ClothMesh wave_mesh() { return fc::make_swatch_mesh(0.2, 0.2, 8, 8); }

// A 0.2 m swatch hung by its top corners, bowed out of plane, the corners
// waving sideways at 2 Hz: 10 frames at 30 fps.
std::vector<Eigen::VectorXd> wave_run(fc::ClothModel& model, fc::Integrator integrator,
                                      double position_tolerance_m = 1e-4) {
    const int rows = 8, cols = 8;
    const fc::ClothMesh& mesh = model.mesh();
    Eigen::VectorXd x0(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        const double bow = 0.01 * std::sin(kPi * uv.x() / 0.2) * (1.0 - uv.y() / 0.2);
        x0.segment<3>(3 * i) = Eigen::Vector3d(uv.x(), bow, 0.8 + uv.y());
    }
    std::vector<fc::PinnedVertex> pins;
    for (int corner : {(rows - 1) * cols, rows * cols - 1}) {
        std::vector<Eigen::Vector3d> path;
        for (int k = 0; k < 12; ++k)
            path.push_back(x0.segment<3>(3 * corner) + Eigen::Vector3d(0.0, 0.03 * std::sin(2 * kPi * 2.0 * k / 30.0), 0.0));
        pins.push_back({corner, fc::PinPath(path, 30.0)});
    }
    fc::SimulationSettings settings;
    settings.integrator = integrator;
    settings.position_tolerance_m = position_tolerance_m;
    settings.velocity_tolerance_m_per_s = 100.0 * position_tolerance_m;
    const fc::SimulationResult result =
        fc::simulate(model, pins, x0, Eigen::VectorXd::Zero(x0.size()), 0.0, 30.0, 10, settings);
    EXPECT_TRUE(result.report.ok()) << result.report.reason;
    EXPECT_EQ(result.frames.size(), 10u);
    return result.frames;
}

bool bit_identical(const std::vector<Eigen::VectorXd>& a, const std::vector<Eigen::VectorXd>& b) {
    if (a.size() != b.size()) return false;
    for (size_t k = 0; k < a.size(); ++k)
        if (!(a[k].size() == b[k].size() && a[k] == b[k])) return false;
    return true;
}

double max_difference(const std::vector<Eigen::VectorXd>& a, const std::vector<Eigen::VectorXd>& b) {
    double worst = 0.0;
    for (size_t k = 0; k < std::min(a.size(), b.size()); ++k) worst = std::max(worst, (a[k] - b[k]).cwiseAbs().maxCoeff());
    return worst;
}

// Random deformed configuration (large folds), fixed seed.
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
        c.x.segment<3>(3 * i) = R * (Eigen::Vector3d(uv.x(), uv.y(), 0.0) + amplitude_m * Eigen::Vector3d(u(rng), u(rng), u(rng)));
        c.v.segment<3>(3 * i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    return c;
}

double relative_error(const Eigen::MatrixXd& analytic, const Eigen::MatrixXd& numeric) {
    const double scale = std::max(numeric.norm(), analytic.norm());
    return scale == 0.0 ? 0.0 : (analytic - numeric).norm() / scale;
}

Eigen::VectorXd force_of(fc::ClothModel& model, const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms) {
    Eigen::VectorXd f;
    model.evaluate(x, v, 0.0, terms, f);
    return f;
}

std::vector<double> hinge_angles(const fc::ClothModel& model, const Eigen::VectorXd& x) {
    std::vector<double> angles;
    for (const fc::BendingStencil& s : model.bending_stencils()) {
        const auto& q = s.vertices;
        angles.push_back(fc::dihedral_angle(x.segment<3>(3 * q[0]), x.segment<3>(3 * q[1]), x.segment<3>(3 * q[2]),
                                            x.segment<3>(3 * q[3])));
    }
    return angles;
}

}  // namespace

TEST(ClothEffects, NeutralValuesReproduceTheBaseModelBitForBit) {
    // The defaults are the neutral values, and a neutral run allocates no memory state.
    EXPECT_EQ(fc::ClothMaterial{}.bias_angle_rad, 0.0);
    EXPECT_EQ(fc::ClothMaterial{}.bend_memory_rate_per_s, 0.0);
    for (fc::Integrator integrator : {fc::Integrator::implicit_euler, fc::Integrator::bdf2, fc::Integrator::rk4_adaptive}) {
        SCOPED_TRACE(fc::integrator_name(integrator));
        fc::ClothModel base_model(wave_mesh(), wave_material());
        const std::vector<Eigen::VectorXd> base = wave_run(base_model, integrator);
        ASSERT_EQ(base.size(), 10u);
        EXPECT_GT((base.back() - base.front()).cwiseAbs().maxCoeff(), 1e-3) << "the run must move for the check to mean anything";
        EXPECT_FALSE(base_model.has_rest_fold());

        // The fields written out at their neutral values.
        fc::ClothMaterial neutral = wave_material();
        neutral.bias_angle_rad = 0.0;
        neutral.bend_memory_rate_per_s = 0.0;
        fc::ClothModel explicit_zero(wave_mesh(), neutral);
        EXPECT_TRUE(bit_identical(wave_run(explicit_zero, integrator), base));

        // A model built at a bias, then set back to 0: the frames are recomputed exactly.
        fc::ClothMaterial biased = neutral;
        biased.bias_angle_rad = 0.4;
        fc::ClothModel rebiased(wave_mesh(), biased);
        rebiased.set_material(neutral);
        EXPECT_TRUE(bit_identical(wave_run(rebiased, integrator), base));

        // Rest folds left over from an earlier run are cleared when a run starts.
        fc::ClothModel leftover(wave_mesh(), neutral);
        leftover.set_rest_fold_angles_rad(Eigen::VectorXd::Constant(static_cast<Eigen::Index>(leftover.bending_stencils().size()), 0.3));
        EXPECT_TRUE(bit_identical(wave_run(leftover, integrator), base));
        EXPECT_FALSE(leftover.has_rest_fold());

        // Away from neutral, each term does move the cloth (the check can fail).
        fc::ClothModel tilted(wave_mesh(), biased);
        fc::ClothMaterial memory = neutral;
        memory.bend_memory_rate_per_s = 10.0;
        fc::ClothModel remembering(wave_mesh(), memory);
        const double moved_by_bias = max_difference(wave_run(tilted, integrator), base);
        const double moved_by_memory = max_difference(wave_run(remembering, integrator), base);
        std::printf("[ measured ] %s: bias 0.4 rad moves a vertex by %.3g m, memory 10/s by %.3g m within 10 frames\n",
                    fc::integrator_name(integrator), moved_by_bias, moved_by_memory);
        EXPECT_GT(moved_by_bias, 1e-5);
        EXPECT_GT(moved_by_memory, 1e-7);
        EXPECT_TRUE(remembering.has_rest_fold());
    }
}

TEST(ClothEffects, BiasAngleTurnsTheWarpAwayFromU) {
    // A uniform stretch by 1.1 along the in-plane direction phi, x = F X:
    // every triangle has the same deformation gradient, so the energy is
    // A/2 (ku (|F a| - 1)^2 + kv (|F b| - 1)^2 + ks ((F a).(F b))^2) with the
    // warp a = (cos b, sin b) and the weft b = (-sin b, cos b), exactly.
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.1, 0.08, 6, 7);
    fc::ClothMaterial m;
    m.stretch_warp_N_per_m = 200.0;
    m.stretch_weft_N_per_m = 50.0;
    m.shear_N_per_m = 30.0;
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (double bias : {0.0, 0.3, kPi / 2}) {
        m.bias_angle_rad = bias;
        fc::ClothModel model(mesh, m);
        for (double phi : {0.0, 0.5, 1.2}) {
            const Eigen::Vector2d d(std::cos(phi), std::sin(phi));
            const Eigen::Matrix2d F = Eigen::Matrix2d::Identity() + 0.1 * d * d.transpose();
            Eigen::VectorXd x(3 * mesh.vertex_count());
            for (int i = 0; i < mesh.vertex_count(); ++i) {
                const Eigen::Vector2d p = F * mesh.material_uv_m[static_cast<size_t>(i)];
                x.segment<3>(3 * i) = R * Eigen::Vector3d(p.x(), p.y(), 0.0);
            }
            const Eigen::Vector2d warp(std::cos(bias), std::sin(bias)), weft(-std::sin(bias), std::cos(bias));
            const double cu = (F * warp).norm() - 1.0, cv = (F * weft).norm() - 1.0, cs = (F * warp).dot(F * weft);
            const double expected = 0.5 * model.total_rest_area_m2() *
                                    (m.stretch_warp_N_per_m * cu * cu + m.stretch_weft_N_per_m * cv * cv +
                                     m.shear_N_per_m * cs * cs);
            const double energy = model.potential_energy(x, fc::ForceTerm::stretch | fc::ForceTerm::shear);
            std::printf("[ measured ] bias %.3f rad, stretch along %.1f rad: energy %.6e J, analytic %.6e J\n", bias, phi,
                        energy, expected);
            EXPECT_NEAR(energy, expected, 1e-12 * expected) << "bias " << bias << " phi " << phi;
        }
    }
    // At bias pi/2 the warp lies along v: the stretch along u costs the weft's stiffness.
    m.bias_angle_rad = kPi / 2;
    fc::ClothModel quarter(mesh, m);
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i)
        x.segment<3>(3 * i) = Eigen::Vector3d(1.1 * mesh.material_uv_m[static_cast<size_t>(i)].x(),
                                              mesh.material_uv_m[static_cast<size_t>(i)].y(), 0.0);
    EXPECT_NEAR(quarter.potential_energy(x, fc::ForceTerm::stretch),
                0.5 * quarter.total_rest_area_m2() * m.stretch_weft_N_per_m * 0.01, 1e-12);

    // set_material with a new bias gives the forces of a model built with it.
    const Config c = random_config(mesh, 3);
    m.bias_angle_rad = 0.3;
    fc::ClothModel built(mesh, m);
    m.bias_angle_rad = -0.2;
    fc::ClothModel changed(mesh, m);
    m.bias_angle_rad = 0.3;
    changed.set_material(m);
    const unsigned membrane = fc::ForceTerm::stretch | fc::ForceTerm::shear | fc::ForceTerm::stretch_damping;
    EXPECT_TRUE(force_of(built, c.x, c.v, membrane) == force_of(changed, c.x, c.v, membrane));
}

TEST(ClothEffects, BiasAtQuarterTurnIsTheSwappedFabric) {
    // Warp and weft exchanged (stiffness and damping) at bias 0 is the same
    // fabric as the original turned by pi/2: the same motion, to rounding
    // (cos(pi/2) is 6e-17, not 0). The adaptive explicit steps run at a tight
    // tolerance: a last-bit difference can flip an accept/reject decision,
    // which moves the result by the order of the tolerance.
    fc::ClothMaterial turned = wave_material();
    turned.stretch_warp_N_per_m = 200.0;
    turned.stretch_weft_N_per_m = 60.0;
    turned.stretch_warp_damping_N_s_per_m = 0.02;
    turned.stretch_weft_damping_N_s_per_m = 0.005;
    turned.bias_angle_rad = kPi / 2;
    fc::ClothMaterial swapped = turned;
    std::swap(swapped.stretch_warp_N_per_m, swapped.stretch_weft_N_per_m);
    std::swap(swapped.stretch_warp_damping_N_s_per_m, swapped.stretch_weft_damping_N_s_per_m);
    swapped.bias_angle_rad = 0.0;
    fc::ClothMaterial unturned = turned;
    unturned.bias_angle_rad = 0.0;
    for (fc::Integrator integrator : {fc::Integrator::implicit_euler, fc::Integrator::rk4_adaptive}) {
        SCOPED_TRACE(fc::integrator_name(integrator));
        fc::ClothModel a(wave_mesh(), turned), b(wave_mesh(), swapped), c(wave_mesh(), unturned);
        const double tolerance_m = 1e-7;
        const std::vector<Eigen::VectorXd> ra = wave_run(a, integrator, tolerance_m),
                                           rb = wave_run(b, integrator, tolerance_m),
                                           rc = wave_run(c, integrator, tolerance_m);
        double extent = 0.0;
        for (const Eigen::VectorXd& f : rb) extent = std::max(extent, f.cwiseAbs().maxCoeff());
        const double swap_difference = max_difference(ra, rb) / extent;
        const double bias_effect = max_difference(ra, rc) / extent;
        std::printf("[ measured ] %s: turned vs swapped %.2e relative, turned vs unturned %.2e\n",
                    fc::integrator_name(integrator), swap_difference, bias_effect);
        EXPECT_LT(swap_difference, 1e-9);
        EXPECT_GT(bias_effect, 1e-5);  // the comparison is not between two identical runs
    }
}

TEST(ClothEffects, BendingWithARestFoldMatchesFiniteDifferences) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.08, 0.06, 4, 5);
    fc::ClothMaterial m;
    m.bend_N_m = 2e-5;
    m.bend_damping_N_m_s = 1e-6;
    fc::ClothModel model(mesh, m);
    const Eigen::Index edges = static_cast<Eigen::Index>(model.bending_stencils().size());
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-0.6, 0.6);
    for (unsigned seed : {1u, 2u}) {
        SCOPED_TRACE(seed);
        const Config c = random_config(mesh, seed);
        Eigen::VectorXd rest(edges);
        for (Eigen::Index e = 0; e < edges; ++e) rest(e) = u(rng);
        model.reset_rest_fold_angles();
        const Eigen::VectorXd f_flat = force_of(model, c.x, c.v, fc::ForceTerm::bending);
        fc::BlockSparseMatrix K_flat = model.make_jacobian_matrix();
        Eigen::VectorXd scratch;
        model.evaluate(c.x, c.v, 0.0, fc::ForceTerm::bending, scratch, &K_flat, nullptr, fc::JacobianMode::definite);
        model.set_rest_fold_angles_rad(rest);
        EXPECT_TRUE(model.rest_fold_angles_rad() == rest);

        const unsigned terms = fc::ForceTerm::bending;
        const Eigen::VectorXd f = force_of(model, c.x, c.v, terms);
        EXPECT_GT((f - f_flat).norm(), 0.1 * f_flat.norm()) << "the rest fold must change the force";
        // Force = -dE/dx.
        Eigen::VectorXd f_fd(c.x.size());
        const double h = 1e-7;
        for (Eigen::Index k = 0; k < c.x.size(); ++k) {
            Eigen::VectorXd xp = c.x, xm = c.x;
            xp(k) += h;
            xm(k) -= h;
            f_fd(k) = -(model.potential_energy(xp, terms) - model.potential_energy(xm, terms)) / (2 * h);
        }
        // df/dx (exact) against differences of the force, with bending damping
        // too (its theta_dot term is unchanged by the rest fold).
        const unsigned both = fc::ForceTerm::bending | fc::ForceTerm::bending_damping;
        fc::BlockSparseMatrix K = model.make_jacobian_matrix(), D = model.make_jacobian_matrix();
        Eigen::VectorXd f_both;
        model.evaluate(c.x, c.v, 0.0, both, f_both, &K, &D, fc::JacobianMode::exact);
        EXPECT_LT((f_both - force_of(model, c.x, c.v, both)).norm(), 1e-12 * f_both.norm());
        Eigen::MatrixXd K_fd(c.x.size(), c.x.size());
        for (Eigen::Index k = 0; k < c.x.size(); ++k) {
            Eigen::VectorXd xp = c.x, xm = c.x;
            xp(k) += h;
            xm(k) -= h;
            K_fd.col(k) = (force_of(model, xp, c.v, both) - force_of(model, xm, c.v, both)) / (2 * h);
        }
        const double ef = relative_error(f, f_fd), ek = relative_error(K.to_dense(), K_fd);
        std::printf("[ measured ] bending with rest folds: force vs energy %.1e, df/dx %.1e\n", ef, ek);
        EXPECT_LT(ef, 2e-6);
        EXPECT_LT(ek, 2e-6);
        // The definite (Gauss-Newton) Jacobian does not depend on the rest fold;
        // the linearised path gives the same forces.
        fc::BlockSparseMatrix K_def = model.make_jacobian_matrix();
        model.evaluate(c.x, c.v, 0.0, terms, scratch, &K_def, nullptr, fc::JacobianMode::definite);
        EXPECT_TRUE(K_def.to_dense() == K_flat.to_dense());
        fc::Linearization lin;
        Eigen::VectorXd f_lin;
        model.linearize(c.x, c.v, 0.0, both, 1e-4, 1e-2, f_lin, lin);
        EXPECT_LT((f_lin - f_both).norm(), 1e-12 * f_both.norm());
    }
    // Rest folds equal to the current folds: no bending energy, no force.
    const Config c = random_config(mesh, 5);
    const std::vector<double> current = hinge_angles(model, c.x);
    model.set_rest_fold_angles_rad(Eigen::Map<const Eigen::VectorXd>(current.data(), edges));
    EXPECT_LT(model.potential_energy(c.x, fc::ForceTerm::bending), 1e-25);
    EXPECT_LT(force_of(model, c.x, c.v, fc::ForceTerm::bending).norm(), 1e-15);
    // Wrong sizes and non-finite angles are programming errors.
    EXPECT_THROW(model.set_rest_fold_angles_rad(Eigen::VectorXd::Zero(edges + 1)), std::invalid_argument);
    EXPECT_THROW(model.set_rest_fold_angles_rad(Eigen::VectorXd::Constant(edges, NAN)), std::invalid_argument);
}

TEST(ClothEffects, RestFoldFollowsTheExponentialLawForAHeldFold) {
    // One hinge (two triangles), folded and held: theta0(t) = theta (1 - e^{-r t}).
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.1, 0.1, 2, 2);
    fc::ClothMaterial m;
    m.bend_N_m = 1e-5;
    m.bend_memory_rate_per_s = 3.0;
    fc::ClothModel model(mesh, m);
    ASSERT_EQ(model.bending_stencils().size(), 1u);
    const auto& q = model.bending_stencils()[0].vertices;
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i)
        x.segment<3>(3 * i) = Eigen::Vector3d(mesh.material_uv_m[static_cast<size_t>(i)].x(),
                                              mesh.material_uv_m[static_cast<size_t>(i)].y(), 1.0);
    // Turn the wing vertex of B about the hinge edge by 0.9 rad.
    const Eigen::Vector3d a = x.segment<3>(3 * q[0]), axis = (x.segment<3>(3 * q[1]) - a).normalized();
    x.segment<3>(3 * q[3]) = a + Eigen::AngleAxisd(0.9, axis) * (x.segment<3>(3 * q[3]) - a);
    const double theta = hinge_angles(model, x)[0];
    EXPECT_NEAR(std::abs(theta), 0.9, 1e-12);

    // Direct calls with uneven steps.
    double t = 0.0;
    double worst = 0.0;
    for (int k = 0; k < 400; ++k) {
        const double dt = 1e-3 * (1 + k % 7);
        model.update_rest_fold_angles(x, dt);
        t += dt;
        const double expected = theta * (1.0 - std::exp(-3.0 * t));
        worst = std::max(worst, std::abs(model.rest_fold_angles_rad()(0) - expected) / std::abs(theta));
    }
    std::printf("[ measured ] held fold, 400 uneven steps to t = %.3f s: max relative error of theta0 %.1e\n", t, worst);
    EXPECT_LT(worst, 1e-13);
    EXPECT_GT(std::abs(model.rest_fold_angles_rad()(0)), 0.9 * std::abs(theta));  // near the fold after 6 time constants

    // Through the simulator (every vertex pinned, so the fold is held): one
    // update per accepted step, whatever the integrator's steps.
    std::vector<fc::PinnedVertex> pins;
    for (int i = 0; i < mesh.vertex_count(); ++i) pins.push_back({i, fc::PinPath::fixed(x.segment<3>(3 * i))});
    for (fc::Integrator integrator : {fc::Integrator::implicit_euler, fc::Integrator::bdf2, fc::Integrator::rk4_adaptive}) {
        SCOPED_TRACE(fc::integrator_name(integrator));
        fc::SimulationSettings settings;
        settings.integrator = integrator;
        fc::ClothSimulator sim(model, pins, settings);
        sim.set_state(x, Eigen::VectorXd::Zero(x.size()), 0.0);
        EXPECT_FALSE(model.has_rest_fold());  // a new run starts flat
        for (int k = 1; k <= 12; ++k) {
            ASSERT_TRUE(sim.advance_to(k / 30.0).ok());
            const double expected = theta * (1.0 - std::exp(-3.0 * sim.time_s()));
            EXPECT_NEAR(model.rest_fold_angles_rad()(0), expected, 1e-13 * std::abs(theta)) << "frame " << k;
        }
        EXPECT_GT(sim.statistics().steps, 12);
    }
    // Rate 0: nothing happens, nothing is allocated.
    m.bend_memory_rate_per_s = 0.0;
    model.set_material(m);
    model.reset_rest_fold_angles();
    model.update_rest_fold_angles(x, 0.1);
    EXPECT_FALSE(model.has_rest_fold());
    EXPECT_EQ(model.rest_fold_angles_rad().size(), 1);
    EXPECT_EQ(model.rest_fold_angles_rad()(0), 0.0);
}

TEST(ClothEffects, BendingMemoryKeepsAFoldThatRelaxesWithoutIt) {
    // A 0.1 m swatch (5 x 5, coarse so that rk4's damping-limited steps stay
    // affordable) clamped along its u = 0 edge (two columns), no gravity,
    // released with a 60 degree crease along u = 0.05 m. Bending damping
    // cb = kb * tau with tau = 1 s makes the relaxation overdamped, where the
    // hinge law is cb dtheta/dt = -kb (theta - theta0), so
    //   without memory the fold decays as exp(-t / tau);
    //   with memory, d(theta - theta0)/dt = -(1/tau + r)(theta - theta0), and
    //   the fold stops at r tau / (1 + r tau) of its start.
    const int n = 5;
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.1, 0.1, n, n);
    const double crease_u = 0.05, fold = kPi / 3;
    Eigen::VectorXd x0(3 * mesh.vertex_count());
    std::vector<fc::PinnedVertex> pins;
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        const double s = std::max(uv.x() - crease_u, 0.0);
        x0.segment<3>(3 * i) =
            Eigen::Vector3d(std::min(uv.x(), crease_u) + s * std::cos(fold), uv.y(), s * std::sin(fold));
        if (i % n <= 1) pins.push_back({i, fc::PinPath::fixed(x0.segment<3>(3 * i))});
    }
    const double tau_s = 1.0, rate_per_s = 10.0, seconds = 1.0;
    fc::ClothMaterial m;
    m.bend_N_m = 2e-5;
    m.bend_damping_N_m_s = tau_s * m.bend_N_m;
    m.stretch_warp_damping_N_s_per_m = m.stretch_weft_damping_N_s_per_m = 0.01;
    fc::Environment still;
    still.gravity_m_per_s2.setZero();
    // The fold: mean angle of the hinges on the crease line.
    auto crease_angle = [&](const fc::ClothModel& model, const Eigen::VectorXd& x) {
        const std::vector<double> angles = hinge_angles(model, x);
        double sum = 0.0;
        int count = 0;
        for (size_t e = 0; e < angles.size(); ++e) {
            const auto& v = model.bending_stencils()[e].vertices;
            if (std::abs(mesh.material_uv_m[static_cast<size_t>(v[0])].x() - crease_u) < 1e-9 &&
                std::abs(mesh.material_uv_m[static_cast<size_t>(v[1])].x() - crease_u) < 1e-9) {
                sum += angles[e];
                ++count;
            }
        }
        EXPECT_EQ(count, n - 1);
        return sum / count;
    };
    const double expected[2] = {std::exp(-seconds / tau_s), rate_per_s * tau_s / (1.0 + rate_per_s * tau_s)};
    for (fc::Integrator integrator : {fc::Integrator::implicit_euler, fc::Integrator::rk4_adaptive}) {
        SCOPED_TRACE(fc::integrator_name(integrator));
        fc::SimulationSettings settings;
        settings.integrator = integrator;
        double kept[2] = {0.0, 0.0};
        for (int with_memory = 0; with_memory < 2; ++with_memory) {
            m.bend_memory_rate_per_s = with_memory ? rate_per_s : 0.0;
            fc::ClothModel model(mesh, m, still);
            const double start = crease_angle(model, x0);
            EXPECT_NEAR(std::abs(start), fold, 1e-9);
            const int frames = static_cast<int>(std::lround(30 * seconds)) + 1;
            const fc::SimulationResult r =
                fc::simulate(model, pins, x0, Eigen::VectorXd::Zero(x0.size()), 0.0, 30.0, frames, settings);
            ASSERT_TRUE(r.report.ok()) << r.report.reason;
            kept[with_memory] = crease_angle(model, r.frames.back()) / start;
            EXPECT_EQ(model.has_rest_fold(), with_memory == 1);
        }
        std::printf("[ measured ] %s: fold kept after %.0f s: %.4f without memory (overdamped law %.4f), %.4f with "
                    "%.0f/s (law %.4f)\n",
                    fc::integrator_name(integrator), seconds, kept[0], expected[0], kept[1], rate_per_s, expected[1]);
        EXPECT_NEAR(kept[0], expected[0], 0.01);
        EXPECT_NEAR(kept[1], expected[1], 0.01);
        EXPECT_GT(kept[1], kept[0] + 0.4);
    }
}

TEST(ClothEffects, NonFiniteOptionalTermsNameTheField) {
    fc::ClothMaterial m;
    m.bias_angle_rad = NAN;
    m.bend_memory_rate_per_s = INFINITY;
    const std::string messages = flowvid::testing::validation_messages(
        [&] { fc::ClothModel model(fc::make_swatch_mesh(0.1, 0.1, 3, 3), m); });
    EXPECT_NE(messages.find("<material>"), std::string::npos) << messages;
    EXPECT_NE(messages.find("bias_angle_rad"), std::string::npos) << messages;
    EXPECT_NE(messages.find("bend_memory_rate_per_s"), std::string::npos) << messages;
    fc::ClothModel model(fc::make_swatch_mesh(0.1, 0.1, 3, 3), fc::ClothMaterial{});
    m.bend_memory_rate_per_s = 0.0;
    const std::string one = flowvid::testing::validation_messages([&] { model.set_material(m); });
    EXPECT_NE(one.find("<material>: bias_angle_rad"), std::string::npos) << one;
    EXPECT_EQ(one.find("bend_memory_rate_per_s"), std::string::npos) << one;
    // Neither is a preset key: a preset round trip leaves them neutral.
    m.bias_angle_rad = 0.5;
    m.bend_memory_rate_per_s = 4.0;
    const fc::ClothMaterial back = fc::material_from_fabric(fc::fabric_from_material(m));
    EXPECT_EQ(back.bias_angle_rad, 0.0);
    EXPECT_EQ(back.bend_memory_rate_per_s, 0.0);
}
