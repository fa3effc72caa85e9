// Free flight: conservation, the intermediate-axis instability, agreement
// with the captures' ground truth, and the variational equations against
// finite differences.

#include "flowvid/rigid/dynamics.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

using namespace flowvid;
using namespace flowvid::rigid;

namespace {

// The T-shaped body of the rigid.toss captures (inertia about the COM, mesh axes).
RigidBody t_body() {
    RigidBody body;
    body.mass_kg = 0.972;
    body.center_of_mass_m = {0.0, 0.0, 0.203333333};
    body.inertia_kg_m2 = Eigen::Vector3d(0.0079272, 0.0118152, 0.0044712).asDiagonal();
    return body;
}

Eigen::Vector3d vec3(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }
Eigen::Quaterniond quat(const nlohmann::json& j) {
    return Eigen::Quaterniond(j[0].get<double>(), j[1].get<double>(), j[2].get<double>(), j[3].get<double>());
}

std::vector<double> frame_times(int count, double fps = 30.0) {
    std::vector<double> t;
    for (int i = 0; i < count; ++i) t.push_back(i / fps);
    return t;
}

FlightParameters spinning(const Eigen::Vector3d& omega_body) {
    FlightParameters p;
    p.com_m = {0.1, -0.2, 4.0};
    p.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, -1).normalized()));
    p.com_velocity_m_per_s = {0.5, -4.0, 0.2};
    p.angular_velocity_rad_per_s = p.orientation.toRotationMatrix() * omega_body;
    p.gravity = GravityAngles{0.06, 0.1};
    return p;
}

}  // namespace

TEST(RigidDynamics, IntermediateAxisTumblesAndConservesMomentumAndEnergy) {
    const RigidBody body = t_body();
    // Body x is the intermediate axis of the T (moments 0.0079 between 0.0045 and 0.0118).
    const FlightParameters p = spinning({11.0, 0.12, 0.1});
    SimulationSettings fine;
    fine.max_step_s = 1.0 / 6000.0;  // 200 steps per frame, like the capture's integrator
    const Trajectory t = simulate(body, p, frame_times(91), fine);
    const RigidState& s0 = t.states.front();
    const Eigen::Vector3d L0 = angular_momentum_kg_m2_per_s(body, s0);
    const double E0 = rotational_energy_J(body, s0);
    double min_wx = 1e9, max_L_drift = 0.0, max_E_drift = 0.0, max_unit_drift = 0.0;
    for (const RigidState& s : t.states) {
        min_wx = std::min(min_wx, s.angular_velocity_body_rad_per_s.x());
        max_L_drift = std::max(max_L_drift, (angular_momentum_kg_m2_per_s(body, s) - L0).norm() / L0.norm());
        max_E_drift = std::max(max_E_drift, std::abs(rotational_energy_J(body, s) - E0) / E0);
        max_unit_drift = std::max(max_unit_drift, std::abs(s.orientation.norm() - 1.0));
    }
    // The spin about the intermediate axis reverses (Dzhanibekov) within 3 s...
    EXPECT_LT(min_wx, -10.0);
    // ... while angular momentum and energy stay put.
    EXPECT_LT(max_L_drift, 1e-10);
    EXPECT_LT(max_E_drift, 1e-10);
    EXPECT_LT(max_unit_drift, 1e-10);

    // The default step (8 per frame) keeps the drift small over a 40-frame toss.
    const Trajectory coarse = simulate(body, p, frame_times(41));
    const RigidState& last = coarse.states.back();
    EXPECT_LT((angular_momentum_kg_m2_per_s(body, last) - L0).norm() / L0.norm(), 1e-6);
    EXPECT_LT(std::abs(rotational_energy_J(body, last) - E0) / E0, 1e-6);
}

TEST(RigidDynamics, MajorAxisSpinIsStable) {
    const RigidBody body = t_body();
    const Trajectory t = simulate(body, spinning({0.35, 13.0, -0.3}), frame_times(91));
    for (const RigidState& s : t.states) EXPECT_GT(s.angular_velocity_body_rad_per_s.y(), 12.9);
}

TEST(RigidDynamics, ReproducesTheCapturesGroundTruth) {
    const RigidBody body = t_body();
    for (const char* name : {"rigid-toss-major", "rigid-toss-tumble"}) {
        // Evaluation only: the truth is read to check the simulator's conventions.
        const nlohmann::json truth =
            nlohmann::json::parse(flowvid::testing::read_text(flowvid::testing::shared_path(std::string("captures/") + name + "/truth/truth.json")));
        FlightParameters p;
        p.com_m = vec3(truth["initial"]["com_cam"]);
        p.orientation = quat(truth["initial"]["orientation_cam_wxyz"]);
        p.com_velocity_m_per_s = vec3(truth["initial"]["com_velocity_cam"]);
        p.angular_velocity_rad_per_s = vec3(truth["initial"]["angular_velocity_cam"]);
        const Eigen::Vector3d g = vec3(truth["gravity_cam"]);
        p.gravity = GravityAngles::from_vector(g);
        p.gravity_magnitude_m_per_s2 = g.norm();
        const nlohmann::json& frames = truth["frames"];
        const Trajectory t = simulate(body, p, frame_times(static_cast<int>(frames.size())));
        double max_angle = 0.0, max_position = 0.0;
        for (std::size_t i = 0; i < frames.size(); ++i) {
            max_angle = std::max(max_angle, t.states[i].orientation.angularDistance(quat(frames[i]["q_camera_from_body_wxyz"])));
            max_position = std::max(max_position, (t.states[i].origin_m(body) - vec3(frames[i]["body_origin_cam"])).norm());
        }
        EXPECT_LT(max_angle, 1e-5) << name;       // rad
        EXPECT_LT(max_position, 1e-6) << name;    // m
        // Body-frame angular velocity from the truth's camera-frame value.
        const Eigen::Vector3d w_body = t.states[0].angular_velocity_body_rad_per_s;
        EXPECT_LT((w_body - vec3(truth["initial"]["angular_velocity_body"])).norm(), 1e-6) << name;
        EXPECT_LT((t.states[0].origin_velocity_m_per_s(body) - vec3(truth["initial"]["origin_velocity_cam"])).norm(), 1e-6) << name;
    }
}

TEST(RigidDynamics, SensitivitiesMatchFiniteDifferences) {
    const RigidBody body = t_body();
    const FlightParameters p = spinning({4.0, 9.0, -3.0});
    const std::vector<double> times = {0.0, 0.4, 1.2, -0.3};
    SimulationSettings settings;
    settings.sensitivities = true;
    const Trajectory t = simulate(body, p, times, settings);
    ASSERT_EQ(t.sensitivities.size(), times.size());
    const double h = 1e-6;
    for (int k = 0; k < kParameterCount; ++k) {
        ParameterVector d = ParameterVector::Zero();
        d[k] = h;
        const Trajectory plus = simulate(body, p.perturbed(d), times);
        const Trajectory minus = simulate(body, p.perturbed(-d), times);
        for (std::size_t i = 0; i < times.size(); ++i) {
            // Compare in pose coordinates (quaternion sign and normalisation drop out).
            Eigen::Matrix<double, 6, 1> fd;
            fd.head<3>() = (plus.states[i].com_m - minus.states[i].com_m) / (2 * h);
            const Eigen::AngleAxisd rotation(plus.states[i].rotation() * minus.states[i].rotation().transpose());
            fd.tail<3>() = rotation.angle() * rotation.axis() / (2 * h);
            const Eigen::Matrix<double, 6, 1> analytic = t.pose_jacobian(i).col(k);
            EXPECT_LT((analytic - fd).norm(), 1e-5 * std::max(1.0, fd.norm())) << "parameter " << k << " time " << times[i];
            // Velocities too, from the raw state sensitivities.
            const Eigen::Vector3d dv = (plus.states[i].com_velocity_m_per_s - minus.states[i].com_velocity_m_per_s) / (2 * h);
            EXPECT_LT((t.sensitivities[i].block<3, 1>(7, k) - dv).norm(), 1e-5 * std::max(1.0, dv.norm()));
            const Eigen::Vector3d dw =
                (plus.states[i].angular_velocity_body_rad_per_s - minus.states[i].angular_velocity_body_rad_per_s) / (2 * h);
            EXPECT_LT((t.sensitivities[i].block<3, 1>(10, k) - dw).norm(), 1e-5 * std::max(1.0, dw.norm()));
        }
    }
}

TEST(RigidDynamics, BackwardIntegrationReturnsToTheStart) {
    const RigidBody body = t_body();
    const FlightParameters p = spinning({11.0, 0.12, 0.1});
    const Trajectory forward = simulate(body, p, {0.8});
    const FlightParameters later = FlightParameters::from_state(forward.states[0], p.gravity);
    const Trajectory back = simulate(body, later, {-0.8});
    const RigidState& s = back.states[0];
    EXPECT_LT((s.com_m - p.com_m).norm(), 1e-9);
    EXPECT_LT(s.orientation.angularDistance(p.orientation), 1e-6);
    EXPECT_LT((s.angular_velocity_rad_per_s() - p.angular_velocity_rad_per_s).norm(), 1e-5);
}

TEST(RigidDynamics, GravityAnglesRoundTripAndDerivative) {
    for (const GravityAngles a : {GravityAngles{0.0, 0.0}, GravityAngles{0.0592, 0.0}, GravityAngles{-0.3, 0.7},
                                  GravityAngles{0.2, -2.5}}) {
        const GravityAngles b = GravityAngles::from_vector(9.81 * a.direction());
        EXPECT_NEAR(a.tilt_rad, b.tilt_rad, 1e-12);
        EXPECT_NEAR(a.roll_rad, b.roll_rad, 1e-12);
        const double h = 1e-7;
        const Eigen::Vector3d dt = (GravityAngles{a.tilt_rad + h, a.roll_rad}.direction() -
                                    GravityAngles{a.tilt_rad - h, a.roll_rad}.direction()) / (2 * h);
        const Eigen::Vector3d dr = (GravityAngles{a.tilt_rad, a.roll_rad + h}.direction() -
                                    GravityAngles{a.tilt_rad, a.roll_rad - h}.direction()) / (2 * h);
        EXPECT_LT((a.direction_derivative().col(0) - dt).norm(), 1e-7);
        EXPECT_LT((a.direction_derivative().col(1) - dr).norm(), 1e-7);
    }
    // Gravity straight down the image is roll 0, tilt 0.
    EXPECT_LT((GravityAngles{}.direction() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
}

TEST(RigidDynamics, FindsTheTShapesTwoFoldSymmetry) {
    const formats::Capture capture = formats::read_capture(flowvid::testing::shared_path("captures/rigid-toss-major"));
    const RigidBody body = RigidBody::from_capture(*capture.rigid);
    ASSERT_EQ(body.symmetries.size(), 2u);
    // 180 degrees about the stem (body z).
    EXPECT_LT((body.symmetries[1] - Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()).norm(), 1e-9);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
    const Eigen::Quaterniond flipped = q * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
    EXPECT_LT(orientation_distance_rad(q, flipped, body.symmetries), 1e-9);
    EXPECT_GT(orientation_distance_rad(q, flipped, {Eigen::Matrix3d::Identity()}), 3.0);
}
