#pragma once
// Free flight of a rigid body (thesis section 2.3.2, eq. 2.2): Newton-Euler
// equations with a unit quaternion, integrated with fixed-step RK4, and the
// sensitivities dq(t)/dp by integrating the variational equations alongside
// the state (eq. 2.10-2.11).
//
// Frames: "camera" is the OpenCV camera of the capture (x right, y down,
// z forward, metres). For rigid.toss captures the world is the camera frame.
// The body frame is the mesh frame of body.glb. Orientation q = rotation
// camera_from_body, stored (w, x, y, z) in files.
//
// State (13 numbers): COM position (3), orientation quaternion (4, w first),
// COM velocity (3), angular velocity in *body* axes (3). Rotation follows
// Euler's equations with the full gyroscopic term,
//     I dw/dt = (I w) x w,      dq/dt = 1/2 q (0, w),
// so torque-free tumbling (intermediate-axis instability) comes out right.
//
// Parameters p (14 numbers, the thesis's p = (p_obj, p_env)) are local
// coordinates around a FlightParameters value: COM (m, 3), a rotation vector
// (rad, 3, camera frame, applied on the left: q = exp(d) q_ref), COM
// velocity (m/s, 3), angular velocity (rad/s, 3, camera frame), gravity tilt
// and roll (rad). Gravity's magnitude is fixed (9.81 m/s^2 by default): a
// silhouette fit recovers its direction, the body's known size sets the scale.

#include "flowvid/formats/capture.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace flowvid::rigid {

inline constexpr double kStandardGravity_m_per_s2 = 9.81;
inline constexpr int kStateSize = 13;
inline constexpr int kParameterCount = 14;

using ParameterVector = Eigen::Matrix<double, kParameterCount, 1>;
using StateJacobian = Eigen::Matrix<double, kStateSize, kParameterCount>;
// d pose / d p: rows 0-2 the COM (m), rows 3-5 a small rotation (rad, camera
// frame, on the left) of the orientation.
using PoseJacobian = Eigen::Matrix<double, 6, kParameterCount>;

// The direction of gravity in camera space as two angles (thesis 2.3.2):
//   direction = (sin(roll) cos(tilt), cos(roll) cos(tilt), sin(tilt)).
// roll: in the image plane, from image-down (+y) towards image-right (+x);
//       0 when gravity points straight down the image.
// tilt: out of the image plane, positive towards +z (away from the camera,
//       as when the camera looks down at the scene).
struct GravityAngles {
    double tilt_rad = 0.0;
    double roll_rad = 0.0;

    Eigen::Vector3d direction() const;
    Eigen::Matrix<double, 3, 2> direction_derivative() const;  // d direction / d (tilt, roll)
    static GravityAngles from_vector(const Eigen::Vector3d& gravity);
};

// The known intrinsic parameters: mass properties and shape.
struct RigidBody {
    double mass_kg = 1.0;
    Eigen::Vector3d center_of_mass_m = Eigen::Vector3d::Zero();     // body frame
    Eigen::Matrix3d inertia_kg_m2 = Eigen::Matrix3d::Identity();   // about the COM, body axes (symmetric, positive definite)
    formats::TriangleMesh mesh;                                     // body frame, metres
    // Body-frame rotations about the COM that map the mesh's vertices onto
    // themselves (identity first). Orientations that differ by one of them
    // look identical, so orientation errors are measured up to them.
    std::vector<Eigen::Matrix3d> symmetries{Eigen::Matrix3d::Identity()};

    // From a capture's rigid block (mesh included); finds the symmetries.
    static RigidBody from_capture(const formats::RigidSpec& spec);
};

// Rotations about principal axes through the COM (2-fold about each axis;
// 3-, 4- and 6-fold about an axis of rotational inertia symmetry) that map
// every vertex onto a vertex within `tolerance_m`. Identity first.
std::vector<Eigen::Matrix3d> find_mesh_symmetries(const formats::TriangleMesh& mesh, const Eigen::Vector3d& center_m,
                                                  const Eigen::Matrix3d& inertia, double tolerance_m = 1e-6);

// Angle (rad) between two orientations camera_from_body, minimised over the
// body's symmetries: min_S angle(a S, b).
double orientation_distance_rad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b,
                                const std::vector<Eigen::Matrix3d>& symmetries);

struct RigidState {
    Eigen::Vector3d com_m = Eigen::Vector3d::Zero();
    Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // camera_from_body
    Eigen::Vector3d com_velocity_m_per_s = Eigen::Vector3d::Zero();
    Eigen::Vector3d angular_velocity_body_rad_per_s = Eigen::Vector3d::Zero();

    Eigen::Matrix3d rotation() const { return orientation.normalized().toRotationMatrix(); }
    Eigen::Vector3d angular_velocity_rad_per_s() const { return rotation() * angular_velocity_body_rad_per_s; }
    // A body-frame point in camera coordinates.
    Eigen::Vector3d to_camera(const RigidBody& body, const Eigen::Vector3d& body_point_m) const {
        return com_m + rotation() * (body_point_m - body.center_of_mass_m);
    }
    // The body-frame (mesh) origin in camera coordinates and its velocity.
    Eigen::Vector3d origin_m(const RigidBody& body) const { return to_camera(body, Eigen::Vector3d::Zero()); }
    Eigen::Vector3d origin_velocity_m_per_s(const RigidBody& body) const;
};

// Total kinetic energy of rotation (J) and angular momentum about the COM in
// camera axes (kg m^2/s): both are conserved in free flight.
double rotational_energy_J(const RigidBody& body, const RigidState& state);
Eigen::Vector3d angular_momentum_kg_m2_per_s(const RigidBody& body, const RigidState& state);

// The thesis's p: the state at the reference time (t = 0) and gravity.
struct FlightParameters {
    Eigen::Vector3d com_m = Eigen::Vector3d::Zero();
    Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // camera_from_body
    Eigen::Vector3d com_velocity_m_per_s = Eigen::Vector3d::Zero();
    Eigen::Vector3d angular_velocity_rad_per_s = Eigen::Vector3d::Zero();  // camera frame
    GravityAngles gravity;
    double gravity_magnitude_m_per_s2 = kStandardGravity_m_per_s2;

    Eigen::Vector3d gravity_m_per_s2() const { return gravity_magnitude_m_per_s2 * gravity.direction(); }
    RigidState initial_state() const;
    static FlightParameters from_state(const RigidState& state, const GravityAngles& gravity,
                                       double gravity_magnitude_m_per_s2 = kStandardGravity_m_per_s2);
    // p + delta in the local coordinates described at the top.
    FlightParameters perturbed(const ParameterVector& delta) const;
};

// Terms the free-flight model leaves out, for the gap diagnosis
// (gap/rigid_model.hpp; catalogue effects "air_drag" and "inertia_error").
// All zero (the default) is the plain free flight above, computed by the
// same code path bit for bit.
//   quadratic_drag_per_m:   dv/dt = g - c |v| v  (c = rho Cd A / (2 m), 1/m)
//   angular_damping_per_s:  dw/dt = I^-1 (I w) x w - k w  (body axes)
//   log_inertia_scale_xy:   I -> D I D, D = diag(exp(a/2), exp(b/2), 1): the
//                           moments about body x and y scaled by exp(a),
//                           exp(b) relative to body z (principal moments when
//                           the inertia is diagonal in mesh axes, as in the
//                           captures). A common scale of all three moments
//                           does not change torque-free motion, so only
//                           these two ratios are observable.
struct FlightEffects {
    double quadratic_drag_per_m = 0.0;
    double angular_damping_per_s = 0.0;
    Eigen::Vector2d log_inertia_scale_xy = Eigen::Vector2d::Zero();

    bool neutral() const {
        return quadratic_drag_per_m == 0.0 && angular_damping_per_s == 0.0 && log_inertia_scale_xy.isZero(0.0);
    }
    // The body's inertia with the scale applied (the inertia itself when neutral).
    Eigen::Matrix3d scaled_inertia(const Eigen::Matrix3d& inertia_kg_m2) const;
};

struct SimulationSettings {
    // RK4 steps per interval between consecutive requested times are
    // ceil(|interval| / max_step_s); 1/240 s is 8 steps per frame at 30 fps
    // (relative energy drift ~1e-7 over 40 frames at 13 rad/s).
    double max_step_s = 1.0 / 240.0;
    bool sensitivities = false;  // integrate the variational equations too
    // Optional terms (neutral by default). The variational equations include
    // them, so sensitivities stay exact d state / d p for the 14 flight
    // parameters; derivatives with respect to the effect values themselves
    // are not integrated (refits take those by finite differences).
    FlightEffects effects;
};

struct Trajectory {
    std::vector<double> times_s;                 // as requested (relative to the reference time)
    std::vector<RigidState> states;              // one per time
    std::vector<StateJacobian> sensitivities;    // d state / d p, one per time when requested

    // d pose / d p at sample i (see PoseJacobian).
    PoseJacobian pose_jacobian(std::size_t i) const;
};

// Free flight from the parameters' state at t = 0 to every requested time
// (any order, negative times integrate backwards).
Trajectory simulate(const RigidBody& body, const FlightParameters& parameters, const std::vector<double>& times_s,
                    const SimulationSettings& settings = {});

// The time derivative of a state (eq. 2.2), for tests and other integrators:
// 13 numbers in the state layout above.
Eigen::Matrix<double, kStateSize, 1> state_derivative(const RigidBody& body, const Eigen::Matrix<double, kStateSize, 1>& y,
                                                      const Eigen::Vector3d& gravity_m_per_s2);
// The same with optional terms.
Eigen::Matrix<double, kStateSize, 1> state_derivative(const RigidBody& body, const Eigen::Matrix<double, kStateSize, 1>& y,
                                                      const Eigen::Vector3d& gravity_m_per_s2, const FlightEffects& effects);
Eigen::Matrix<double, kStateSize, 1> pack_state(const RigidState& state);
RigidState unpack_state(const Eigen::Matrix<double, kStateSize, 1>& y);

}  // namespace flowvid::rigid
