// The thesis's nonlinear drag: a flat horizontal swatch falling freely
// reaches the terminal velocity the drag parameters predict,
// m g = A kN v^2 / (1 + kf v^2)  =>  v = sqrt(rho g / (kN - rho g kf)).

#include "flowvid/cloth/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace fc = flowvid::cloth;

namespace {

double fall_speed(const fc::ClothMaterial& m, fc::Integrator integrator, double seconds) {
    const fc::ClothMesh mesh = fc::make_swatch_mesh(0.3, 0.3, 8, 8);
    fc::ClothModel model(mesh, m);
    Eigen::VectorXd x(3 * mesh.vertex_count());
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        const Eigen::Vector2d& uv = mesh.material_uv_m[static_cast<size_t>(i)];
        x.segment<3>(3 * i) = Eigen::Vector3d(uv.x(), uv.y(), 10.0);
    }
    fc::SimulationSettings s;
    s.integrator = integrator;
    fc::ClothSimulator sim(model, {}, s);
    sim.set_state(x, Eigen::VectorXd::Zero(x.size()), 0.0);
    for (int k = 1; k <= static_cast<int>(seconds * 30); ++k) {
        const fc::SimulationReport r = sim.advance_to(k / 30.0);
        EXPECT_TRUE(r.ok()) << r.reason;
        if (!r.ok()) return 0.0;
    }
    // Every vertex falls at the same speed (mass and drag are both lumped by area).
    const Eigen::VectorXd& v = sim.velocities();
    double min_vz = 1e300, max_vz = -1e300, max_lateral = 0.0;
    for (int i = 0; i < mesh.vertex_count(); ++i) {
        min_vz = std::min(min_vz, v(3 * i + 2));
        max_vz = std::max(max_vz, v(3 * i + 2));
        max_lateral = std::max(max_lateral, v.segment<2>(3 * i).norm());
    }
    // A flat plate falling against quadratic drag is unstable (it starts to
    // flutter from rounding-level tilts), so only a small sideways drift and
    // spread of vertical speeds are allowed.
    EXPECT_LT(max_lateral, 0.01 * std::abs(min_vz));
    EXPECT_LT(max_vz - min_vz, 1e-4 * std::abs(min_vz));
    return -min_vz;
}

}  // namespace

TEST(ClothDrag, FallingSwatchReachesTheAnalyticTerminalVelocity) {
    struct Case {
        double kN, kf, kL;
    };
    // The last case is the linear-drag comparison model: m g = A kL v.
    for (const Case c : {Case{1.0, 0.0, 0.0}, Case{1.0, 0.1, 0.0}, Case{0.4, 0.05, 0.0}, Case{0.0, 0.0, 2.0}}) {
        fc::ClothMaterial m;
        m.areal_density_kg_per_m2 = 0.15;
        m.drag_normal_kg_per_m3 = c.kN;
        m.drag_degradation_s2_per_m2 = c.kf;
        m.drag_linear_normal_kg_per_m2_s = c.kL;
        m.drag_tangential_kg_per_m2_s = 0.3;  // no tangential motion: must not matter
        m.stretch_warp_damping_N_s_per_m = 0.02;
        const double rho_g = 0.15 * 9.81;
        const double expected = c.kL > 0.0 ? rho_g / c.kL : std::sqrt(rho_g / (c.kN - rho_g * c.kf));
        for (fc::Integrator integrator : {fc::Integrator::rk4_adaptive, fc::Integrator::implicit_euler}) {
            // Ten time constants v/g of the approach.
            const double seconds = std::ceil(10.0 * expected / 9.81 * 30.0) / 30.0;
            const double v = fall_speed(m, integrator, seconds);
            const double error = std::abs(v - expected) / expected;
            std::printf("[ measured ] kN %.2f kf %.2f kL %.1f %s: terminal %.6f m/s, analytic %.6f m/s, error %.2e\n", c.kN, c.kf, c.kL,
                        fc::integrator_name(integrator), v, expected, error);
            EXPECT_LT(error, 0.01);
        }
    }
}
