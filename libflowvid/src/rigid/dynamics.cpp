#include "flowvid/rigid/dynamics.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace flowvid::rigid {

namespace {

using State = Eigen::Matrix<double, kStateSize, 1>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
}

Eigen::Quaterniond rotation_vector_to_quaternion(const Eigen::Vector3d& v) {
    const double angle = v.norm();
    if (angle < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * v.x(), 0.5 * v.y(), 0.5 * v.z()).normalized();
    return Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle));
}

// Inverse inertia, cached per call site by the integrator.
struct Dynamics {
    Eigen::Matrix3d I;
    Eigen::Matrix3d I_inv;
    Eigen::Vector3d g;
    Eigen::Matrix<double, 3, 2> dg_dangles;  // d gravity / d (tilt, roll)
    // Optional terms (FlightEffects); when off, the code below is the plain
    // free flight, untouched, so neutral effects reproduce it bit for bit.
    bool damped = false;
    double drag_per_m = 0.0;
    double damping_per_s = 0.0;

    State derivative(const State& y) const {
        if (damped) return damped_derivative(y);
        State dy;
        const double w = y[3];
        const Eigen::Vector3d u = y.segment<3>(4);
        const Eigen::Vector3d omega = y.segment<3>(10);
        dy.segment<3>(0) = y.segment<3>(7);
        dy[3] = -0.5 * u.dot(omega);
        dy.segment<3>(4) = 0.5 * (w * omega + u.cross(omega));
        dy.segment<3>(7) = g;
        dy.segment<3>(10) = I_inv * (I * omega).cross(omega);
        return dy;
    }

    State damped_derivative(const State& y) const {
        State dy;
        const double w = y[3];
        const Eigen::Vector3d u = y.segment<3>(4);
        const Eigen::Vector3d v = y.segment<3>(7);
        const Eigen::Vector3d omega = y.segment<3>(10);
        dy.segment<3>(0) = v;
        dy[3] = -0.5 * u.dot(omega);
        dy.segment<3>(4) = 0.5 * (w * omega + u.cross(omega));
        dy.segment<3>(7) = g - drag_per_m * v.norm() * v;
        dy.segment<3>(10) = I_inv * (I * omega).cross(omega) - damping_per_s * omega;
        return dy;
    }

    // d/dt S = A(y) S + B with A = dF/dy and B = dF/dp (gravity columns only).
    StateJacobian sensitivity_derivative(const State& y, const StateJacobian& S) const {
        const double w = y[3];
        const Eigen::Vector3d u = y.segment<3>(4);
        const Eigen::Vector3d omega = y.segment<3>(10);
        Eigen::Matrix4d dq_dq;
        dq_dq(0, 0) = 0.0;
        dq_dq.block<1, 3>(0, 1) = -0.5 * omega.transpose();
        dq_dq.block<3, 1>(1, 0) = 0.5 * omega;
        dq_dq.block<3, 3>(1, 1) = -0.5 * skew(omega);
        Eigen::Matrix<double, 4, 3> dq_domega;
        dq_domega.row(0) = -0.5 * u.transpose();
        dq_domega.block<3, 3>(1, 0) = 0.5 * (w * Eigen::Matrix3d::Identity() + skew(u));
        Eigen::Matrix3d domega_domega = I_inv * (skew(I * omega) - skew(omega) * I);
        if (damped) domega_domega.diagonal().array() -= damping_per_s;

        StateJacobian dS;
        dS.block<3, kParameterCount>(0, 0) = S.block<3, kParameterCount>(7, 0);
        dS.block<4, kParameterCount>(3, 0) =
            dq_dq * S.block<4, kParameterCount>(3, 0) + dq_domega * S.block<3, kParameterCount>(10, 0);
        dS.block<3, kParameterCount>(7, 0).setZero();
        const double speed = damped ? y.segment<3>(7).norm() : 0.0;
        if (drag_per_m != 0.0 && speed > 0.0) {
            // d(-c |v| v)/dv = -c (|v| 1 + v v^T / |v|)
            const Eigen::Vector3d v = y.segment<3>(7);
            const Eigen::Matrix3d dv_dv = -drag_per_m * (speed * Eigen::Matrix3d::Identity() + v * v.transpose() / speed);
            dS.block<3, kParameterCount>(7, 0) = dv_dv * S.block<3, kParameterCount>(7, 0);
            dS.block<3, 2>(7, 12) += dg_dangles;
        } else {
            dS.block<3, 2>(7, 12) = dg_dangles;
        }
        dS.block<3, kParameterCount>(10, 0) = domega_domega * S.block<3, kParameterCount>(10, 0);
        return dS;
    }

    void rk4_step(State& y, double h) const {
        const State k1 = derivative(y);
        const State k2 = derivative(y + 0.5 * h * k1);
        const State k3 = derivative(y + 0.5 * h * k2);
        const State k4 = derivative(y + h * k3);
        y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }

    void rk4_step(State& y, StateJacobian& S, double h) const {
        const State k1 = derivative(y);
        const StateJacobian l1 = sensitivity_derivative(y, S);
        const State y2 = y + 0.5 * h * k1;
        const StateJacobian S2 = S + 0.5 * h * l1;
        const State k2 = derivative(y2);
        const StateJacobian l2 = sensitivity_derivative(y2, S2);
        const State y3 = y + 0.5 * h * k2;
        const StateJacobian S3 = S + 0.5 * h * l2;
        const State k3 = derivative(y3);
        const StateJacobian l3 = sensitivity_derivative(y3, S3);
        const State y4 = y + h * k3;
        const StateJacobian S4 = S + h * l3;
        const State k4 = derivative(y4);
        const StateJacobian l4 = sensitivity_derivative(y4, S4);
        y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        S += h / 6.0 * (l1 + 2.0 * l2 + 2.0 * l3 + l4);
    }
};

Dynamics make_dynamics(const RigidBody& body, const FlightParameters& p, const FlightEffects& effects = {}) {
    Dynamics d;
    d.I = 0.5 * (body.inertia_kg_m2 + body.inertia_kg_m2.transpose());
    if (!effects.log_inertia_scale_xy.isZero(0.0)) d.I = effects.scaled_inertia(d.I);
    d.I_inv = d.I.inverse();
    d.g = p.gravity_m_per_s2();
    d.dg_dangles = p.gravity_magnitude_m_per_s2 * p.gravity.direction_derivative();
    d.damped = effects.quadratic_drag_per_m != 0.0 || effects.angular_damping_per_s != 0.0;
    d.drag_per_m = effects.quadratic_drag_per_m;
    d.damping_per_s = effects.angular_damping_per_s;
    return d;
}

}  // namespace

// ---- Effects ------------------------------------------------------------------

Eigen::Matrix3d FlightEffects::scaled_inertia(const Eigen::Matrix3d& inertia) const {
    if (log_inertia_scale_xy.isZero(0.0)) return inertia;
    // D I D keeps the matrix symmetric positive definite and scales the
    // diagonal (the moments about body x and y) by exp(a), exp(b).
    const Eigen::Vector3d d(std::exp(0.5 * log_inertia_scale_xy.x()), std::exp(0.5 * log_inertia_scale_xy.y()), 1.0);
    return d.asDiagonal() * inertia * d.asDiagonal();
}

// ---- Gravity ------------------------------------------------------------------

Eigen::Vector3d GravityAngles::direction() const {
    return {std::sin(roll_rad) * std::cos(tilt_rad), std::cos(roll_rad) * std::cos(tilt_rad), std::sin(tilt_rad)};
}

Eigen::Matrix<double, 3, 2> GravityAngles::direction_derivative() const {
    Eigen::Matrix<double, 3, 2> d;
    d.col(0) << -std::sin(roll_rad) * std::sin(tilt_rad), -std::cos(roll_rad) * std::sin(tilt_rad), std::cos(tilt_rad);
    d.col(1) << std::cos(roll_rad) * std::cos(tilt_rad), -std::sin(roll_rad) * std::cos(tilt_rad), 0.0;
    return d;
}

GravityAngles GravityAngles::from_vector(const Eigen::Vector3d& gravity) {
    const Eigen::Vector3d d = gravity.normalized();
    GravityAngles a;
    a.tilt_rad = std::asin(std::clamp(d.z(), -1.0, 1.0));
    a.roll_rad = std::atan2(d.x(), d.y());
    return a;
}

// ---- Body and symmetries ----------------------------------------------------------

RigidBody RigidBody::from_capture(const formats::RigidSpec& spec) {
    RigidBody body;
    body.mass_kg = spec.mass_kg;
    body.center_of_mass_m = spec.center_of_mass_m;
    body.inertia_kg_m2 = spec.inertia_body_kg_m2;
    body.mesh = spec.body_mesh;
    double size = 0.0;
    for (const Eigen::Vector3d& v : body.mesh.vertices_m) size = std::max(size, (v - body.center_of_mass_m).norm());
    body.symmetries = find_mesh_symmetries(body.mesh, body.center_of_mass_m, body.inertia_kg_m2, 1e-5 * std::max(size, 1e-3));
    return body;
}

std::vector<Eigen::Matrix3d> find_mesh_symmetries(const formats::TriangleMesh& mesh, const Eigen::Vector3d& center,
                                                  const Eigen::Matrix3d& inertia, double tolerance_m) {
    std::vector<Eigen::Matrix3d> found{Eigen::Matrix3d::Identity()};
    if (mesh.vertices_m.empty()) return found;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (inertia + inertia.transpose()));
    const Eigen::Vector3d moments = eigen.eigenvalues();
    const Eigen::Matrix3d axes = eigen.eigenvectors();

    auto maps_onto_itself = [&](const Eigen::Matrix3d& R) {
        for (const Eigen::Vector3d& v : mesh.vertices_m) {
            const Eigen::Vector3d image = center + R * (v - center);
            bool hit = false;
            for (const Eigen::Vector3d& w : mesh.vertices_m)
                if ((w - image).norm() <= tolerance_m) {
                    hit = true;
                    break;
                }
            if (!hit) return false;
        }
        return true;
    };
    auto known = [&](const Eigen::Matrix3d& R) {
        return std::any_of(found.begin(), found.end(), [&](const Eigen::Matrix3d& S) { return (S - R).norm() < 1e-9; });
    };
    const double scale = std::max(moments.cwiseAbs().maxCoeff(), 1e-30);
    for (int a = 0; a < 3; ++a) {
        // Higher orders are possible only about an axis with two equal moments.
        bool symmetric_axis = false;
        for (int b = 0; b < 3; ++b)
            for (int c = b + 1; c < 3; ++c)
                if (b != a && c != a && std::abs(moments[b] - moments[c]) < 1e-6 * scale) symmetric_axis = true;
        for (int order : {2, 3, 4, 6}) {
            if (order > 2 && !symmetric_axis) continue;
            const Eigen::Matrix3d R = Eigen::AngleAxisd(2.0 * M_PI / order, axes.col(a)).toRotationMatrix();
            if (!maps_onto_itself(R)) continue;
            Eigen::Matrix3d power = R;
            for (int k = 1; k < order; ++k, power = power * R)
                if (!known(power)) found.push_back(power);
        }
    }
    // Close the set under composition (e.g. two perpendicular 2-fold axes give the third).
    for (std::size_t i = 0; i < found.size(); ++i)
        for (std::size_t j = 0; j < found.size() && found.size() < 64; ++j) {
            const Eigen::Matrix3d product = found[i] * found[j];
            if (!known(product)) found.push_back(product);
        }
    return found;
}

double orientation_distance_rad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b,
                                const std::vector<Eigen::Matrix3d>& symmetries) {
    const Eigen::Quaterniond qb = b.normalized();
    double best = M_PI;
    for (const Eigen::Matrix3d& S : symmetries) {
        const Eigen::Quaterniond qa = a.normalized() * Eigen::Quaterniond(S);
        best = std::min(best, qa.angularDistance(qb));
    }
    return best;
}

// ---- State ---------------------------------------------------------------------------

Eigen::Vector3d RigidState::origin_velocity_m_per_s(const RigidBody& body) const {
    return com_velocity_m_per_s + angular_velocity_rad_per_s().cross(origin_m(body) - com_m);
}

double rotational_energy_J(const RigidBody& body, const RigidState& state) {
    const Eigen::Vector3d& w = state.angular_velocity_body_rad_per_s;
    return 0.5 * w.dot(body.inertia_kg_m2 * w);
}

Eigen::Vector3d angular_momentum_kg_m2_per_s(const RigidBody& body, const RigidState& state) {
    return state.rotation() * (body.inertia_kg_m2 * state.angular_velocity_body_rad_per_s);
}

Eigen::Matrix<double, kStateSize, 1> pack_state(const RigidState& s) {
    State y;
    y.segment<3>(0) = s.com_m;
    y[3] = s.orientation.w();
    y.segment<3>(4) = s.orientation.vec();
    y.segment<3>(7) = s.com_velocity_m_per_s;
    y.segment<3>(10) = s.angular_velocity_body_rad_per_s;
    return y;
}

RigidState unpack_state(const Eigen::Matrix<double, kStateSize, 1>& y) {
    RigidState s;
    s.com_m = y.segment<3>(0);
    s.orientation = Eigen::Quaterniond(y[3], y[4], y[5], y[6]);
    s.com_velocity_m_per_s = y.segment<3>(7);
    s.angular_velocity_body_rad_per_s = y.segment<3>(10);
    return s;
}

Eigen::Matrix<double, kStateSize, 1> state_derivative(const RigidBody& body, const Eigen::Matrix<double, kStateSize, 1>& y,
                                                      const Eigen::Vector3d& gravity) {
    Dynamics d = make_dynamics(body, FlightParameters{});
    d.g = gravity;
    return d.derivative(y);
}

Eigen::Matrix<double, kStateSize, 1> state_derivative(const RigidBody& body, const Eigen::Matrix<double, kStateSize, 1>& y,
                                                      const Eigen::Vector3d& gravity, const FlightEffects& effects) {
    Dynamics d = make_dynamics(body, FlightParameters{}, effects);
    d.g = gravity;
    return d.derivative(y);
}

// ---- Parameters ----------------------------------------------------------------------

RigidState FlightParameters::initial_state() const {
    RigidState s;
    s.com_m = com_m;
    s.orientation = orientation.normalized();
    s.com_velocity_m_per_s = com_velocity_m_per_s;
    s.angular_velocity_body_rad_per_s = s.rotation().transpose() * angular_velocity_rad_per_s;
    return s;
}

FlightParameters FlightParameters::from_state(const RigidState& state, const GravityAngles& gravity, double magnitude) {
    FlightParameters p;
    p.com_m = state.com_m;
    p.orientation = state.orientation.normalized();
    p.com_velocity_m_per_s = state.com_velocity_m_per_s;
    p.angular_velocity_rad_per_s = state.angular_velocity_rad_per_s();
    p.gravity = gravity;
    p.gravity_magnitude_m_per_s2 = magnitude;
    return p;
}

FlightParameters FlightParameters::perturbed(const ParameterVector& d) const {
    FlightParameters p = *this;
    p.com_m += d.segment<3>(0);
    p.orientation = (rotation_vector_to_quaternion(d.segment<3>(3)) * orientation).normalized();
    p.com_velocity_m_per_s += d.segment<3>(6);
    p.angular_velocity_rad_per_s += d.segment<3>(9);
    p.gravity.tilt_rad += d[12];
    p.gravity.roll_rad += d[13];
    return p;
}

// ---- Integration ---------------------------------------------------------------------

PoseJacobian Trajectory::pose_jacobian(std::size_t i) const {
    PoseJacobian J;
    const StateJacobian& S = sensitivities.at(i);
    const Eigen::Quaterniond q = states.at(i).orientation;
    const double norm = q.norm();
    const double w = q.w() / norm;
    const Eigen::Vector3d u = q.vec() / norm;
    // A change dq of the (unit) quaternion is the left rotation 2 vec(dq q*).
    Eigen::Matrix<double, 3, 4> G;
    G.col(0) = -2.0 * u;
    G.block<3, 3>(0, 1) = 2.0 * (w * Eigen::Matrix3d::Identity() + skew(u));
    J.block<3, kParameterCount>(0, 0) = S.block<3, kParameterCount>(0, 0);
    J.block<3, kParameterCount>(3, 0) = G * S.block<4, kParameterCount>(3, 0) / norm;
    return J;
}

Trajectory simulate(const RigidBody& body, const FlightParameters& parameters, const std::vector<double>& times,
                    const SimulationSettings& settings) {
    const Dynamics dynamics = make_dynamics(body, parameters, settings.effects);
    const RigidState start = parameters.initial_state();
    const State y0 = pack_state(start);

    StateJacobian S0 = StateJacobian::Zero();
    if (settings.sensitivities) {
        const Eigen::Quaterniond& q = start.orientation;
        const Eigen::Matrix3d R = start.rotation();
        S0.block<3, 3>(0, 0).setIdentity();
        // q = exp(d) q_ref: dq/dd = 1/2 (0, d) * q_ref.
        S0.block<1, 3>(3, 3) = -0.5 * q.vec().transpose();
        S0.block<3, 3>(4, 3) = 0.5 * (q.w() * Eigen::Matrix3d::Identity() - skew(q.vec()));
        S0.block<3, 3>(7, 6).setIdentity();
        // w_body = R^T w_camera, and R = exp(d) R_ref.
        S0.block<3, 3>(10, 9) = R.transpose();
        S0.block<3, 3>(10, 3) = R.transpose() * skew(parameters.angular_velocity_rad_per_s);
    }

    Trajectory out;
    out.times_s = times;
    out.states.resize(times.size());
    if (settings.sensitivities) out.sensitivities.resize(times.size());
    const double max_step = settings.max_step_s > 0.0 ? settings.max_step_s : 1.0 / 240.0;

    // Forwards through the non-negative times in increasing order, then
    // backwards through the negative ones in decreasing order.
    std::vector<std::size_t> order(times.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return times[a] < times[b]; });
    std::vector<std::size_t> forward, backward;
    for (std::size_t i : order) (times[i] >= 0.0 ? forward : backward).push_back(i);
    std::reverse(backward.begin(), backward.end());

    for (const std::vector<std::size_t>* run : {&forward, &backward}) {
        State y = y0;
        StateJacobian S = S0;
        double t = 0.0;
        for (std::size_t i : *run) {
            const double interval = times[i] - t;
            const int steps = static_cast<int>(std::ceil(std::abs(interval) / max_step - 1e-9));
            if (steps > 0) {
                const double h = interval / steps;
                for (int k = 0; k < steps; ++k) {
                    if (settings.sensitivities) dynamics.rk4_step(y, S, h);
                    else dynamics.rk4_step(y, h);
                }
            }
            t = times[i];
            out.states[i] = unpack_state(y);
            if (settings.sensitivities) out.sensitivities[i] = S;
        }
    }
    return out;
}

}  // namespace flowvid::rigid
