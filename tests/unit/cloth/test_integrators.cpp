// Time integration: energy conservation and numerical damping, pins,
// determinism, blow-up and cancel reports.

#include "flowvid/cloth/equilibrium.hpp"
#include "flowvid/cloth/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace fc = flowvid::cloth;

namespace {

// A 0.2 m square swatch held at two adjacent corners, released flat and
// horizontal: it swings down like a pendulum and back.
struct Swing {
    fc::ClothMesh mesh = fc::make_swatch_mesh(0.2, 0.2, 10, 10);
    std::vector<fc::PinnedVertex> pins;
    Eigen::VectorXd x0;
    Swing() {
        x0.resize(3 * mesh.vertex_count());
        for (int i = 0; i < mesh.vertex_count(); ++i) {
            const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
            x0.segment<3>(3 * i) = Eigen::Vector3d(uv.x(), uv.y(), 1.0);
        }
        for (int corner : {90, 99})  // uv (0, 1) and (1, 1)
            pins.push_back({corner, fc::PinPath::fixed(x0.segment<3>(3 * corner))});
    }
};

fc::ClothMaterial undamped() {
    fc::ClothMaterial m;
    m.areal_density_kg_per_m2 = 0.15;
    m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = 150.0;
    m.shear_N_per_m = 90.0;
    m.bend_N_m = 1e-5;
    return m;  // no damping, no drag
}

struct EnergyTrace {
    double initial = 0.0;
    double max_deviation = 0.0;
    double final_energy = 0.0;
    fc::SimulationStatistics stats;
    bool ok = false;
};

EnergyTrace swing_energy(fc::Integrator integrator, double seconds, int substeps = 5, double tolerance_m = 1e-6) {
    Swing swing;
    fc::ClothModel model(swing.mesh, undamped());
    fc::SimulationSettings settings;
    settings.integrator = integrator;
    settings.position_tolerance_m = tolerance_m;
    settings.velocity_tolerance_m_per_s = 100.0 * tolerance_m;
    settings.implicit_substeps_per_frame = substeps;
    settings.cg_relative_tolerance = 1e-8;
    fc::ClothSimulator sim(model, swing.pins, settings);
    sim.set_state(swing.x0, Eigen::VectorXd::Zero(swing.x0.size()), 0.0);
    EnergyTrace trace;
    trace.initial = sim.total_energy();
    const int frames = static_cast<int>(std::lround(seconds * 30));
    for (int k = 1; k <= frames; ++k) {
        const fc::SimulationReport r = sim.advance_to(k / 30.0);
        if (!r.ok()) return trace;
        const double e = sim.total_energy();
        trace.max_deviation = std::max(trace.max_deviation, std::abs(e - trace.initial));
        trace.final_energy = e;
    }
    trace.stats = sim.statistics();
    trace.ok = true;
    return trace;
}

// The energy scale of the swing: weight times the drop of the centre of mass
// from flat to hanging (half the swatch height).
double swing_scale() { return 0.15 * 0.04 * 9.81 * 0.1; }

}  // namespace

TEST(ClothIntegrators, ExplicitConservesEnergyOfAnUndampedSwing) {
    // Tolerances 1e-7 m and 1e-5 m/s: the steps follow accuracy, not stability.
    const EnergyTrace t = swing_energy(fc::Integrator::rk4_adaptive, 2.0, 5, 1e-7);
    ASSERT_TRUE(t.ok);
    const double drift = t.max_deviation / swing_scale();
    std::printf("[ measured ] rk4_adaptive (1e-7 m): max |E(t) - E(0)| over 2 s = %.3g of m g h (%lld steps, %lld "
                "rejected)\n",
                drift, t.stats.steps, t.stats.rejected_steps);
    EXPECT_LT(drift, 5e-3);  // stated tolerance: 0.5% of the swing's energy m g h
    // Runge-Kutta 4 dissipates (never gains) energy: the final energy is below the start.
    EXPECT_LE(t.final_energy, t.initial + 1e-6 * swing_scale());
}

TEST(ClothIntegrators, ImplicitDampsTheSwingAndTheDampingIsMeasured) {
    // Numerical damping, documented in docs/cloth_model.md: the fraction of
    // the swing energy (relative to the drop m g h) lost in 2 s.
    const EnergyTrace be = swing_energy(fc::Integrator::implicit_euler, 2.0);
    const EnergyTrace bdf = swing_energy(fc::Integrator::bdf2, 2.0);
    // The explicit default at its default tolerances, where steps sit at the
    // stability limit and the stiffest (stretch) modes are damped.
    const EnergyTrace rk4 = swing_energy(fc::Integrator::rk4_adaptive, 2.0, 5, 1e-4);
    ASSERT_TRUE(be.ok && bdf.ok && rk4.ok);
    const double loss_be = (be.initial - be.final_energy) / swing_scale();
    const double loss_bdf = (bdf.initial - bdf.final_energy) / swing_scale();
    const double loss_rk4 = (rk4.initial - rk4.final_energy) / swing_scale();
    std::printf("[ measured ] energy lost in 2 s, fraction of m g h: implicit Euler (5 substeps/frame) %.3f, "
                "BDF2 %.3f, rk4_adaptive at 1e-4 m %.3f\n",
                loss_be, loss_bdf, loss_rk4);
    EXPECT_GT(loss_be, 0.5);        // backward Euler damps most of the swing away...
    EXPECT_LT(loss_bdf, loss_be);   // ...BDF2 less...
    EXPECT_LT(loss_rk4, 0.5 * loss_bdf);  // ...the explicit integrator much less
    EXPECT_GT(loss_rk4, -0.01);
    // Implicit integration never adds energy to an undamped system.
    EXPECT_LT(be.max_deviation, be.initial - be.final_energy + 1e-12 + 0.5 * swing_scale());
}

TEST(ClothIntegrators, PinPathsAreSmoothAndConsistent) {
    std::vector<Eigen::Vector3d> p = {{0, 0, 1}, {0.01, 0, 1}, {0.03, 0.01, 1}, {0.06, 0.0, 1.02}, {0.07, 0, 1}};
    const fc::PinPath path(p, 30.0);
    for (size_t k = 0; k < p.size(); ++k) EXPECT_EQ((path.position(k / 30.0) - p[k]).norm(), 0.0);
    // Velocity is the derivative of the position, and continuous at samples.
    for (double t = 0.001; t < 4.0 / 30; t += 0.0037) {
        const Eigen::Vector3d fd = (path.position(t + 1e-7) - path.position(t - 1e-7)) / 2e-7;
        EXPECT_LT((fd - path.velocity(t)).norm(), 1e-6) << t;
    }
    for (int k = 1; k < 4; ++k)
        EXPECT_LT((path.velocity(k / 30.0 - 1e-9) - path.velocity(k / 30.0 + 1e-9)).norm(), 1e-5);
    // At rest at both ends (the capture starts in equilibrium).
    EXPECT_EQ(path.velocity(0.0).norm(), 0.0);
    EXPECT_EQ(path.velocity(10.0).norm(), 0.0);
    EXPECT_EQ((path.position(10.0) - p.back()).norm(), 0.0);
}

TEST(ClothIntegrators, RunsAreBitIdenticalWhateverTheThreadCount) {
    for (fc::Integrator integrator : {fc::Integrator::rk4_adaptive, fc::Integrator::implicit_euler}) {
        std::vector<Eigen::VectorXd> reference;
        for (int threads : {1, 1, 2}) {
            Swing swing;
            fc::ClothMaterial m = undamped();
            m.stretch_warp_damping_N_s_per_m = 0.01;
            m.drag_normal_kg_per_m3 = 0.5;
            m.drag_tangential_kg_per_m2_s = 0.1;
            fc::ClothModel model(swing.mesh, m);
            fc::SimulationSettings s;
            s.integrator = integrator;
            s.threads = threads;
            const fc::SimulationResult r = fc::simulate(model, swing.pins, swing.x0, Eigen::VectorXd::Zero(swing.x0.size()),
                                                        0.0, 30.0, 10, s);
            ASSERT_TRUE(r.report.ok()) << r.report.reason;
            ASSERT_EQ(r.frames.size(), 10u);
            if (reference.empty()) {
                reference = r.frames;
                continue;
            }
            for (size_t f = 0; f < reference.size(); ++f)
                EXPECT_TRUE(r.frames[f] == reference[f]) << fc::integrator_name(integrator) << " threads " << threads
                                                         << " frame " << f;
        }
    }
}

TEST(ClothIntegrators, AbsurdParametersEndInABlowUpReportNamingTheFrame) {
    for (fc::Integrator integrator : {fc::Integrator::rk4_adaptive, fc::Integrator::implicit_euler}) {
        Swing swing;
        fc::ClothMaterial m = undamped();
        m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = -500.0;  // the fabric pushes itself apart
        fc::ClothModel model(swing.mesh, m);
        fc::SimulationSettings s;
        s.integrator = integrator;
        const fc::SimulationResult r =
            fc::simulate(model, swing.pins, swing.x0, Eigen::VectorXd::Zero(swing.x0.size()), 0.0, 30.0, 60, s);
        EXPECT_EQ(r.report.status, fc::SimulationReport::Status::blew_up) << fc::integrator_name(integrator);
        EXPECT_GT(r.report.frame, 1);
        EXPECT_LT(r.report.frame, 60);
        EXPECT_FALSE(r.report.reason.empty());
        EXPECT_EQ(static_cast<int>(r.frames.size()), r.report.frame - 1);  // every returned frame is good
        for (const Eigen::VectorXd& f : r.frames) EXPECT_TRUE(f.allFinite());
        std::printf("[ measured ] %s: %s at frame %d: %s\n", fc::integrator_name(integrator),
                    fc::status_name(r.report.status), r.report.frame, r.report.reason.c_str());
    }
}

TEST(ClothIntegrators, NonFiniteWindIsReportedNotPropagated) {
    Swing swing;
    fc::Environment env;
    env.wind_field = [](const Eigen::Vector3d&, double t) {
        return t > 0.1 ? Eigen::Vector3d(std::nan(""), 0, 0) : Eigen::Vector3d::Zero();
    };
    fc::ClothMaterial m = undamped();
    m.drag_normal_kg_per_m3 = 1.0;
    fc::ClothModel model(swing.mesh, m, env);
    const fc::SimulationResult r =
        fc::simulate(model, swing.pins, swing.x0, Eigen::VectorXd::Zero(swing.x0.size()), 0.0, 30.0, 10, {});
    EXPECT_EQ(r.report.status, fc::SimulationReport::Status::blew_up);
    EXPECT_EQ(r.report.frame, 5);  // frame 5 is computed over t in (0.1, 0.133] s
    EXPECT_NE(r.report.reason.find("non-finite"), std::string::npos) << r.report.reason;
}

TEST(ClothIntegrators, StepUnderflowIsReported) {
    Swing swing;
    fc::ClothMaterial m = undamped();
    m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = 1e9;  // far too stiff for the minimum step below
    fc::ClothModel model(swing.mesh, m);
    fc::SimulationSettings s;
    s.min_step_s = 1e-4;
    const fc::SimulationResult r = fc::simulate(model, swing.pins, swing.x0, Eigen::VectorXd::Zero(swing.x0.size()), 0.0,
                                                30.0, 5, s);
    EXPECT_EQ(r.report.status, fc::SimulationReport::Status::step_underflow);
    EXPECT_EQ(r.report.frame, 2);
    EXPECT_NE(r.report.reason.find("minimum"), std::string::npos);
}

TEST(ClothIntegrators, ProgressCanCancel) {
    Swing swing;
    fc::ClothModel model(swing.mesh, undamped());
    int calls = 0;
    const fc::SimulationResult r =
        fc::simulate(model, swing.pins, swing.x0, Eigen::VectorXd::Zero(swing.x0.size()), 0.0, 30.0, 20, {},
                     [&](const flowvid::ProgressReport& p) {
                         ++calls;
                         EXPECT_EQ(p.stage, "simulate");
                         EXPECT_EQ(p.message, "frame " + std::to_string(calls + 1) + "/20");
                         return p.fraction < 3.0 / 20.0;
                     });
    EXPECT_EQ(r.report.status, fc::SimulationReport::Status::cancelled);
    EXPECT_EQ(r.report.frame, 3);
    EXPECT_EQ(r.frames.size(), 3u);
    EXPECT_EQ(calls, 2);
}
