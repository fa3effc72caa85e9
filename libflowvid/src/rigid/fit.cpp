#include "flowvid/rigid/fit.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/metrics/silhouette.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <Eigen/Cholesky>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numeric>
#include <thread>

namespace flowvid::rigid {

namespace {

using Scratch = SilhouetteModel::Scratch;

std::string format(const char* pattern, double a, double b = 0.0, double c = 0.0, double d = 0.0) {
    char buffer[256];
    std::snprintf(buffer, sizeof buffer, pattern, a, b, c, d);
    return buffer;
}

double rotation_distance(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b, const std::vector<Eigen::Matrix3d>& symmetries) {
    return orientation_distance_rad(Eigen::Quaterniond(a), Eigen::Quaterniond(b), symmetries);
}

// Indices sorted by value, ties by index: the same order on any machine and thread count.
std::vector<std::size_t> sorted_by(const std::vector<double>& values) {
    std::vector<std::size_t> order(values.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        const double va = std::isfinite(values[a]) ? values[a] : std::numeric_limits<double>::max();
        const double vb = std::isfinite(values[b]) ? values[b] : std::numeric_limits<double>::max();
        return va < vb;
    });
    return order;
}

struct Candidate {
    Pose pose;
    double cost_px2 = 0.0;
};

// Step 2: the best distinct orientations for one frame at an estimated COM.
std::vector<Candidate> orientation_candidates(const SilhouetteModel& model, const FrameObservation& frame,
                                              const Eigen::Vector3d& com_guess, const std::vector<Eigen::Quaterniond>& grid,
                                              int keep, int threads, std::vector<Scratch>& scratches) {
    const Eigen::Matrix3d K_inv = model.camera().K.inverse();
    std::vector<double> score(grid.size(), std::numeric_limits<double>::infinity());
    std::vector<Pose> placed(grid.size());
    parallel_for(grid.size(), threads, [&](std::size_t i, int t) {
        Scratch& s = scratches[static_cast<std::size_t>(t)];
        Pose pose{grid[i].toRotationMatrix(), com_guess};
        const SilhouetteModel::Moments m = model.moments(pose, s);
        if (m.area_px < 1.0 || frame.area_px < 1.0) return;
        // Re-scale and re-centre the rendered silhouette onto the observed one.
        const double z = com_guess.z();
        const double z_new = z * std::sqrt(m.area_px / frame.area_px);
        const Eigen::Vector2d offset = model.project(com_guess) - m.centroid_px;
        const Eigen::Vector2d target = frame.centroid_px + offset * (z / z_new);
        const Eigen::Vector3d ray = K_inv * Eigen::Vector3d(target.x(), target.y(), 1.0);
        pose.com_m = ray * (z_new / ray.z());
        placed[i] = pose;
        score[i] = static_cast<double>(model.overlap(pose, frame, s).xor_px) / frame.area_px;
    });
    const std::vector<Eigen::Matrix3d>& symmetries = model.body().symmetries;
    std::vector<std::size_t> chosen;
    const double suppression_rad = 20.0 * M_PI / 180.0;
    for (std::size_t i : sorted_by(score)) {
        if (!std::isfinite(score[i]) || static_cast<int>(chosen.size()) >= keep) break;
        bool near = false;
        for (std::size_t j : chosen)
            near = near || rotation_distance(placed[i].rotation, placed[j].rotation, symmetries) < suppression_rad;
        if (!near) chosen.push_back(i);
    }
    std::vector<Candidate> refined(chosen.size());
    parallel_for(chosen.size(), threads, [&](std::size_t k, int t) {
        const PoseFit fit = fit_pose(model, frame, placed[chosen[k]], scratches[static_cast<std::size_t>(t)], 20);
        refined[k] = {fit.pose, fit.cost_px2};
    });
    std::vector<double> costs;
    for (const Candidate& c : refined) costs.push_back(c.cost_px2);
    std::vector<Candidate> out;
    for (std::size_t i : sorted_by(costs)) {
        bool duplicate = false;
        for (const Candidate& c : out)
            duplicate = duplicate || (rotation_distance(c.pose.rotation, refined[i].pose.rotation, symmetries) < 0.07 &&
                                      (c.pose.com_m - refined[i].pose.com_m).norm() < 0.01);
        if (!duplicate && std::isfinite(refined[i].cost_px2)) out.push_back(refined[i]);
    }
    return out;
}

// Small dense least squares with a numerical Jacobian (the 8-parameter trajectory fit).
template <typename Residuals>
Eigen::VectorXd small_least_squares(const Residuals& residuals, Eigen::VectorXd x, int iterations) {
    Eigen::VectorXd r = residuals(x);
    double cost = r.squaredNorm();
    double lambda = 1e-3;
    for (int it = 0; it < iterations; ++it) {
        Eigen::MatrixXd J(r.size(), x.size());
        for (int k = 0; k < x.size(); ++k) {
            const double h = 1e-6 * std::max(1.0, std::abs(x[k]));
            Eigen::VectorXd xp = x, xm = x;
            xp[k] += h;
            xm[k] -= h;
            J.col(k) = (residuals(xp) - residuals(xm)) / (2.0 * h);
        }
        const Eigen::MatrixXd H = J.transpose() * J;
        const Eigen::VectorXd g = J.transpose() * r;
        bool accepted = false;
        while (lambda < 1e10) {
            Eigen::MatrixXd A = H;
            for (int k = 0; k < x.size(); ++k) A(k, k) += lambda * std::max(H(k, k), 1e-12) + 1e-12;
            const Eigen::VectorXd step = A.ldlt().solve(-g);
            const Eigen::VectorXd candidate = x + step;
            const Eigen::VectorXd rc = residuals(candidate);
            if (rc.allFinite() && rc.squaredNorm() < cost) {
                const double decrease = (cost - rc.squaredNorm()) / std::max(cost, 1e-300);
                x = candidate;
                r = rc;
                cost = rc.squaredNorm();
                lambda = std::max(lambda * 0.3, 1e-9);
                accepted = true;
                if (decrease < 1e-10) return x;
                break;
            }
            lambda *= 5.0;
        }
        if (!accepted) break;
    }
    return x;
}

}  // namespace

const char* optimizer_name(OptimizerKind kind) {
    return kind == OptimizerKind::levenberg_marquardt ? "levenberg_marquardt" : "hybrid_gradient";
}

std::vector<Eigen::Quaterniond> uniform_rotations(int count) {
    // Super-Fibonacci spirals: phi = sqrt(2), psi the root of psi^4 = psi + 4.
    const double phi = std::sqrt(2.0);
    const double psi = 1.533751168755204288118041;
    std::vector<Eigen::Quaterniond> out;
    out.reserve(static_cast<std::size_t>(std::max(count, 0)));
    for (int i = 0; i < count; ++i) {
        const double s = i + 0.5;
        const double r = std::sqrt(s / count), R = std::sqrt(1.0 - s / count);
        const double alpha = 2.0 * M_PI * s / phi, beta = 2.0 * M_PI * s / psi;
        out.emplace_back(r * std::sin(alpha), r * std::cos(alpha), R * std::sin(beta), R * std::cos(beta));
    }
    return out;
}

// COM positions at `times_s` (ascending, >= 0) from X0 and v0 at time 0 under
// gravity and quadratic drag dv/dt = g - k |v| v: a parabola without drag,
// else RK4 with steps of at most 1/240 s (the fit's own step).
std::vector<Eigen::Vector3d> com_path(const Eigen::Vector3d& X0, const Eigen::Vector3d& v0, const Eigen::Vector3d& g,
                                      double drag_per_m, const std::vector<double>& times_s) {
    std::vector<Eigen::Vector3d> out;
    out.reserve(times_s.size());
    if (drag_per_m == 0.0) {
        for (double t : times_s) out.push_back(X0 + v0 * t + 0.5 * g * t * t);
        return out;
    }
    auto acceleration = [&](const Eigen::Vector3d& v) { return Eigen::Vector3d(g - drag_per_m * v.norm() * v); };
    Eigen::Vector3d X = X0, v = v0;
    double now = 0.0;
    for (double t : times_s) {
        const int steps = static_cast<int>(std::ceil(std::max(t - now, 0.0) * 240.0));
        const double h = steps > 0 ? (t - now) / steps : 0.0;
        for (int i = 0; i < steps; ++i) {
            const Eigen::Vector3d k1v = acceleration(v), k1x = v;
            const Eigen::Vector3d k2v = acceleration(v + 0.5 * h * k1v), k2x = v + 0.5 * h * k1v;
            const Eigen::Vector3d k3v = acceleration(v + 0.5 * h * k2v), k3x = v + 0.5 * h * k2v;
            const Eigen::Vector3d k4v = acceleration(v + h * k3v), k4x = v + h * k3v;
            X += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        now = std::max(now, t);
        out.push_back(X);
    }
    return out;
}

TrajectoryEstimate estimate_trajectory(const SilhouetteModel& model, const std::vector<FrameObservation>& frames,
                                       double gravity_magnitude, double quadratic_drag_per_m) {
    TrajectoryEstimate estimate;
    const formats::CameraModel& camera = model.camera();
    const double f = 0.5 * (camera.K(0, 0) + camera.K(1, 1));
    const Eigen::Matrix3d K_inv = camera.K.inverse();
    std::vector<const FrameObservation*> valid;
    for (const FrameObservation& o : frames)
        if (o.area_px >= 10.0) valid.push_back(&o);
    estimate.frames_used = static_cast<int>(valid.size());

    // Mean projected area of the body over orientations, at a reference depth.
    double radius = 0.0;
    for (const Eigen::Vector3d& v : model.body().mesh.vertices_m) radius = std::max(radius, (v - model.body().center_of_mass_m).norm());
    radius = std::max(radius, 1e-3);
    const double z_ref = f * 2.0 * radius / 100.0;
    Scratch scratch;
    double mean_area = 0.0;
    const std::vector<Eigen::Quaterniond> rotations = uniform_rotations(64);
    const Eigen::Vector3d centre = z_ref * (K_inv * Eigen::Vector3d(0.5 * (camera.width - 1), 0.5 * (camera.height - 1), 1.0));
    for (const Eigen::Quaterniond& q : rotations) mean_area += model.moments(Pose{q.toRotationMatrix(), centre}, scratch).area_px;
    mean_area /= static_cast<double>(rotations.size());

    if (valid.empty() || mean_area <= 0.0) {
        estimate.com_m = Eigen::Vector3d(0.0, 0.0, 10.0 * radius);
        estimate.gravity = GravityAngles{};
        return estimate;
    }
    std::vector<double> z_area;
    for (const FrameObservation* o : valid) z_area.push_back(z_ref * std::sqrt(mean_area / o->area_px));
    std::vector<double> sorted = z_area;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double z_median = sorted[sorted.size() / 2];

    // Quadratic fit of the centroid track: position, velocity, acceleration in pixels.
    Eigen::Vector2d a = valid.front()->centroid_px, b = Eigen::Vector2d::Zero(), accel = Eigen::Vector2d::Zero();
    if (valid.size() >= 3) {
        Eigen::MatrixXd A(valid.size(), 3);
        Eigen::MatrixXd rhs(valid.size(), 2);
        for (std::size_t i = 0; i < valid.size(); ++i) {
            const double t = valid[i]->time_s;
            A.row(static_cast<Eigen::Index>(i)) << 1.0, t, 0.5 * t * t;
            rhs.row(static_cast<Eigen::Index>(i)) = valid[i]->centroid_px.transpose();
        }
        const Eigen::MatrixXd coefficients = A.colPivHouseholderQr().solve(rhs);
        a = coefficients.row(0).transpose();
        b = coefficients.row(1).transpose();
        accel = coefficients.row(2).transpose();
    }
    // Depth from the image curvature of the parabola (gravity across the view), unless implausible.
    double z0 = z_median;
    const double z_curvature = accel.norm() > 0.0 ? f * gravity_magnitude / accel.norm() : 0.0;
    if (valid.size() >= 6 && z_curvature > 0.3 * z_median && z_curvature < 3.0 * z_median) z0 = z_curvature;

    Eigen::VectorXd x(8);
    const Eigen::Vector3d X0 = z0 * (K_inv * Eigen::Vector3d(a.x(), a.y(), 1.0));
    x << X0, b.x() * z0 / f, b.y() * z0 / f, 0.0, 0.0, accel.norm() > 0.0 ? std::atan2(accel.x(), accel.y()) : 0.0;
    const double sigma_px = 2.0, sigma_log_depth = 0.3;
    std::vector<double> times_s;
    for (const FrameObservation* o : valid) times_s.push_back(o->time_s);
    // The parabola first; with drag, refined from there (the pixel-space
    // start below is a parabola's and lands the drag model in a poor valley).
    double drag_per_m = 0.0;
    auto residuals = [&](const Eigen::VectorXd& p) {
        Eigen::VectorXd r(3 * valid.size());
        const GravityAngles angles{p[6], p[7]};
        const std::vector<Eigen::Vector3d> path =
            com_path(p.segment<3>(0), p.segment<3>(3), gravity_magnitude * angles.direction(), drag_per_m, times_s);
        for (std::size_t i = 0; i < valid.size(); ++i) {
            const Eigen::Vector3d& X = path[i];
            const Eigen::Vector2d u = model.project(X);
            r.segment<2>(static_cast<Eigen::Index>(3 * i)) = (u - valid[i]->centroid_px) / sigma_px;
            r[static_cast<Eigen::Index>(3 * i + 2)] = X.z() > 0.0 ? std::log(X.z() / z_area[i]) / sigma_log_depth : 1e3;
        }
        return r;
    };
    if (valid.size() >= 3) {
        x = small_least_squares(residuals, x, 60);
        drag_per_m = quadratic_drag_per_m;
        if (drag_per_m != 0.0) x = small_least_squares(residuals, x, 60);
    }
    estimate.com_m = x.segment<3>(0);
    estimate.com_velocity_m_per_s = x.segment<3>(3);
    estimate.gravity = GravityAngles{x[6], x[7]};
    if (valid.size() < 3) estimate.com_velocity_m_per_s.setZero();
    double sum = 0.0;
    const std::vector<Eigen::Vector3d> path = com_path(estimate.com_m, estimate.com_velocity_m_per_s,
                                                       gravity_magnitude * estimate.gravity.direction(), quadratic_drag_per_m, times_s);
    for (std::size_t i = 0; i < valid.size(); ++i) sum += (model.project(path[i]) - valid[i]->centroid_px).squaredNorm();
    estimate.rms_centroid_px = std::sqrt(sum / static_cast<double>(valid.size()));
    return estimate;
}

RigidState FitResult::state_at_frame(const RigidBody& body, int frame, const SimulationSettings& simulation) const {
    SimulationSettings s = simulation;
    s.sensitivities = false;
    return simulate(body, parameters, {(frame - reference_frame) / fps}, s).states.front();
}

namespace {

// One search and refinement with the settings' candidate and start counts.
FitResult fit_rigid_once(const RigidBody& body, const formats::CameraModel& camera, double fps,
                         const std::vector<FrameObservation>& frames, const FitSettings& settings) {
    const auto started = std::chrono::steady_clock::now();
    FitResult result;
    result.fps = fps;
    result.optimizer = settings.optimizer;
    result.reference_frame = frames.empty() ? 0 : frames.front().frame;
    auto log = [&](const std::string& text) {
        if (settings.log)
            settings.log(format("[%.2f s] ", std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()) + text);
    };
    std::atomic<bool> cancelled{false};
    auto progress = [&](const char* stage, double fraction) {
        if (settings.progress && !settings.progress({stage, fraction, {}})) cancelled = true;
        return !cancelled;
    };
    auto finish = [&]() {
        result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return result;
    };
    if (frames.size() < 3) {
        result.report.status = OptimizerReport::Status::failed;
        result.report.reason = "at least 3 frames are needed, got " + std::to_string(frames.size());
        return finish();
    }
    const int threads = resolve_thread_count(settings.threads);
    std::vector<Scratch> scratches(static_cast<std::size_t>(threads));
    SilhouetteModel model(body, camera);
    model.set_corner_radius(settings.corner_radius_px);
    const std::size_t n = frames.size();
    const std::vector<Eigen::Matrix3d>& symmetries = body.symmetries;

    // 1. Trajectory of the COM and gravity from the centroid track.
    progress("trajectory", 0.0);
    result.trajectory = estimate_trajectory(model, frames, settings.gravity_magnitude_m_per_s2,
                                            settings.simulation.effects.quadratic_drag_per_m);
    TrajectoryEstimate& trajectory = result.trajectory;
    log(format("trajectory: COM depth %.3f m, gravity tilt %.2f deg roll %.2f deg, centroid rms %.2f px",
               trajectory.com_m.z(), trajectory.gravity.tilt_rad * 180.0 / M_PI, trajectory.gravity.roll_rad * 180.0 / M_PI,
               trajectory.rms_centroid_px));

    // The user's guess, moved to time 0 when given at another time.
    std::optional<InitialGuess> guess = settings.guess;
    if (guess && guess->gravity_m_per_s2 && guess->gravity_m_per_s2->norm() > 0.0)
        trajectory.gravity = GravityAngles::from_vector(*guess->gravity_m_per_s2);
    if (guess && guess->time_s != 0.0) {
        if (!guess->complete()) {
            result.report.status = OptimizerReport::Status::failed;
            result.report.reason = "a guess for another frame than the first fitted one must give position, orientation and both velocities";
            return finish();
        }
        RigidState s;
        s.orientation = guess->orientation->normalized();
        s.com_m = *guess->origin_m + s.rotation() * body.center_of_mass_m;
        s.com_velocity_m_per_s = *guess->com_velocity_m_per_s;
        s.angular_velocity_body_rad_per_s = s.rotation().transpose() * *guess->angular_velocity_rad_per_s;
        const RigidState moved =
            simulate(body, FlightParameters::from_state(s, trajectory.gravity, settings.gravity_magnitude_m_per_s2), {-guess->time_s},
                     settings.simulation)
                .states.front();
        InitialGuess at_zero;
        at_zero.orientation = moved.orientation;
        at_zero.origin_m = moved.origin_m(body);
        at_zero.com_velocity_m_per_s = moved.com_velocity_m_per_s;
        at_zero.angular_velocity_rad_per_s = moved.angular_velocity_rad_per_s();
        at_zero.gravity_m_per_s2 = guess->gravity_m_per_s2;
        guess = at_zero;
    }
    if (guess && guess->com_velocity_m_per_s) trajectory.com_velocity_m_per_s = *guess->com_velocity_m_per_s;
    if (guess && guess->origin_m && guess->orientation)
        trajectory.com_m = *guess->origin_m + guess->orientation->normalized().toRotationMatrix() * body.center_of_mass_m;
    else if (guess && guess->origin_m)
        log("guess: a position without an orientation does not locate the centre of mass; estimating it from the images");
    auto com_at = [&](double t) {
        return com_path(trajectory.com_m, trajectory.com_velocity_m_per_s,
                        settings.gravity_magnitude_m_per_s2 * trajectory.gravity.direction(),
                        settings.simulation.effects.quadratic_drag_per_m, {t})
            .front();
    };
    auto base_parameters = [&]() {
        FlightParameters p;
        p.com_m = trajectory.com_m;
        p.com_velocity_m_per_s = trajectory.com_velocity_m_per_s;
        p.gravity = trajectory.gravity;
        p.gravity_magnitude_m_per_s2 = settings.gravity_magnitude_m_per_s2;
        return p;
    };
    if (!progress("candidates", 0.05)) {
        result.report.status = OptimizerReport::Status::cancelled;
        return finish();
    }

    // 2-3. Starts: orientation candidates in the first two frames, paired.
    std::vector<FlightParameters> starts;
    const bool fixed_orientation = guess && guess->orientation;
    const bool fixed_spin = guess && guess->angular_velocity_rad_per_s;
    if (fixed_orientation && fixed_spin) {
        FlightParameters p = base_parameters();
        p.orientation = guess->orientation->normalized();
        p.angular_velocity_rad_per_s = *guess->angular_velocity_rad_per_s;
        starts.push_back(p);
        result.starts_scored = 1;
    } else {
        const std::vector<Eigen::Quaterniond> grid = uniform_rotations(std::max(settings.orientation_samples, 8));
        std::vector<Candidate> first;
        if (fixed_orientation) {
            first.push_back({Pose{guess->orientation->normalized().toRotationMatrix(), com_at(frames[0].time_s)}, 0.0});
        } else {
            first = orientation_candidates(model, frames[0], com_at(frames[0].time_s), grid, settings.candidates_per_frame,
                                           threads, scratches);
        }
        std::vector<FlightParameters> paired;
        if (fixed_spin) {
            for (const Candidate& c : first) {
                FlightParameters p = base_parameters();
                p.com_m = c.pose.com_m;
                p.orientation = Eigen::Quaterniond(c.pose.rotation);
                p.angular_velocity_rad_per_s = *guess->angular_velocity_rad_per_s;
                paired.push_back(p);
            }
        } else {
            const std::vector<Candidate> second = orientation_candidates(
                model, frames[1], com_at(frames[1].time_s), grid, settings.candidates_per_frame, threads, scratches);
            const double dt = frames[1].time_s - frames[0].time_s;
            for (const Candidate& c0 : first)
                for (const Candidate& c1 : second)
                    for (const Eigen::Matrix3d& S : symmetries) {
                        const Eigen::AngleAxisd turn(c1.pose.rotation * S * c0.pose.rotation.transpose());
                        const Eigen::Vector3d omega = turn.axis() * turn.angle() / dt;
                        if (!(omega.norm() < 80.0)) continue;
                        FlightParameters p = base_parameters();
                        p.com_m = c0.pose.com_m;
                        p.orientation = Eigen::Quaterniond(c0.pose.rotation);
                        p.angular_velocity_rad_per_s = omega;
                        paired.push_back(p);
                    }
            result.candidate_orientations = static_cast<int>(first.size() + second.size());
        }
        // Score every pair on the first frames and keep the best distinct ones.
        const FlightProblem opening(model, frames, 0, std::min<std::size_t>(n, 4), settings.simulation);
        std::vector<double> scores(paired.size());
        parallel_for(paired.size(), threads, [&](std::size_t i, int t) {
            scores[i] = opening.cost(paired[i], scratches[static_cast<std::size_t>(t)]);
        });
        result.starts_scored = static_cast<int>(paired.size());
        for (std::size_t i : sorted_by(scores)) {
            if (static_cast<int>(starts.size()) >= std::max(settings.starts, 1)) break;
            bool duplicate = false;
            for (const FlightParameters& s : starts) {
                const double angle = orientation_distance_rad(s.orientation, paired[i].orientation, symmetries);
                const double spin = (s.angular_velocity_rad_per_s - paired[i].angular_velocity_rad_per_s).norm();
                duplicate = duplicate || (angle < 0.15 && spin < 0.15 * s.angular_velocity_rad_per_s.norm() + 0.5);
            }
            if (!duplicate) starts.push_back(paired[i]);
        }
        log(format("starts: %.0f orientation candidates, %.0f pairs scored, %.0f kept", result.candidate_orientations,
                   result.starts_scored, static_cast<double>(starts.size())));
    }
    if (starts.empty()) {
        result.report.status = OptimizerReport::Status::failed;
        result.report.reason = "no orientation matches the first frames (is the object visible in them?)";
        return finish();
    }
    if (!progress("refine", 0.25)) {
        result.report.status = OptimizerReport::Status::cancelled;
        return finish();
    }

    // 4. Growing windows; the weaker starts are dropped between windows.
    std::vector<std::size_t> windows;
    for (std::size_t w = 6; w < n; w *= 2) windows.push_back(w);
    windows.push_back(n);
    const std::vector<int> keep = {settings.starts, 4, 2};
    struct Track {
        FlightParameters parameters;
        double cost = 0.0;
        OptimizerReport report;
    };
    std::vector<Track> alive;
    for (const FlightParameters& s : starts) alive.push_back({s, 0.0, {}});
    const Progress cancel = [&](const ProgressReport&) { return !cancelled.load(); };
    for (std::size_t stage = 0; stage < windows.size(); ++stage) {
        const int limit = keep[std::min(stage, keep.size() - 1)];
        if (stage > 0 && static_cast<int>(alive.size()) > limit) alive.resize(static_cast<std::size_t>(limit));
        const FlightProblem problem(model, frames, 0, windows[stage], settings.simulation);
        const ParameterMask mask = (stage == 0 && windows.size() > 1) ? kWithoutGravity : kAllParameters;
        std::atomic<int> done{0};
        parallel_for(alive.size(), threads, [&](std::size_t i, int t) {
            Scratch& s = scratches[static_cast<std::size_t>(t)];
            OptimizerResult r;
            if (settings.optimizer == OptimizerKind::levenberg_marquardt) {
                LmSettings lm;
                lm.max_iterations = settings.max_iterations;
                lm.free = mask;
                lm.progress = cancel;
                lm.relative_tolerance = stage + 1 == windows.size() ? 1e-6 : 1e-4;
                r = levenberg_marquardt(problem, alive[i].parameters, lm, s);
            } else {
                HybridSettings hybrid;
                hybrid.max_iterations = 5 * settings.max_iterations;
                hybrid.free = mask;
                hybrid.metric = settings.hybrid_metric;
                hybrid.progress = cancel;
                if (settings.hybrid_metric == HybridMetric::xor_pixels) {
                    // The XOR count moves in whole pixels: step about a pixel.
                    hybrid.position_step_m = 0.005;
                    hybrid.rotation_step_rad = 0.03;
                    hybrid.gravity_step_rad = 0.005;
                }
                r = hybrid_gradient(problem, alive[i].parameters, hybrid, s);
            }
            alive[i].parameters = r.parameters;
            alive[i].report = r.report;
            alive[i].cost = r.report.final_cost;
            ++done;
        });
        std::vector<double> costs;
        for (const Track& t : alive) costs.push_back(t.cost);
        std::vector<Track> ordered;
        for (std::size_t i : sorted_by(costs)) ordered.push_back(alive[i]);
        alive = std::move(ordered);
        log(format("window of %.0f frames: best E %.4g px^2 (%.3g per frame) over %.0f starts", static_cast<double>(windows[stage]),
                   alive.front().cost, alive.front().cost / static_cast<double>(windows[stage]), static_cast<double>(alive.size())));
        if (stage == 0) result.starts_refined = static_cast<int>(alive.size());
        if (!progress("refine", 0.25 + 0.75 * static_cast<double>(stage + 1) / static_cast<double>(windows.size()))) break;
    }

    const Track& best = alive.front();
    result.parameters = best.parameters;
    result.report = best.report;
    if (cancelled) {
        result.report.status = OptimizerReport::Status::cancelled;
        result.report.reason = "cancelled";
    }
    for (const Track& t : alive) result.start_costs_px2.push_back(t.cost);

    // Per-frame quality of the winner.
    const FlightProblem all(model, frames, 0, n, settings.simulation);
    const std::vector<Pose> poses = all.poses(result.parameters);
    Scratch& s = scratches.front();
    result.final_cost_px2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const FrameCost c = model.edge_cost(poses[i], frames[i], s);
        const SilhouetteOverlap o = model.overlap(poses[i], frames[i], s);
        result.final_cost_px2 += c.cost_px2;
        result.frames.push_back({frames[i].frame, std::sqrt(c.cost_px2), o.xor_px, o.iou()});
    }
    progress("done", 1.0);
    return finish();
}

}  // namespace

FitResult fit_rigid(const RigidBody& body, const formats::CameraModel& camera, double fps,
                    const std::vector<FrameObservation>& frames, const FitSettings& settings) {
    FitResult first = fit_rigid_once(body, camera, fps, frames, settings);
    const bool searched = !(settings.guess && settings.guess->orientation && settings.guess->angular_velocity_rad_per_s);
    const double per_frame_px2 = first.final_cost_px2 / static_cast<double>(std::max<std::size_t>(frames.size(), 1));
    const bool wider = settings.wide_candidates_per_frame > settings.candidates_per_frame;
    if (!searched || !wider || first.report.status == OptimizerReport::Status::failed ||
        first.report.status == OptimizerReport::Status::cancelled || !(per_frame_px2 > settings.wide_search_above_px2))
        return first;
    if (settings.log)
        settings.log(format("E %.3g px^2 per frame after the search: searching again with %.0f orientations per frame", per_frame_px2,
                            settings.wide_candidates_per_frame));
    FitSettings wide = settings;
    wide.candidates_per_frame = settings.wide_candidates_per_frame;
    wide.starts = 2 * settings.starts;
    FitResult second = fit_rigid_once(body, camera, fps, frames, wide);
    const double seconds = first.seconds + second.seconds;
    FitResult& better = second.report.status != OptimizerReport::Status::failed && second.final_cost_px2 < first.final_cost_px2 ? second : first;
    better.seconds = seconds;
    better.widened = &better == &second;
    return better;
}

std::vector<metrics::Silhouette> predict_silhouettes(const RigidBody& body, const formats::CameraModel& camera,
                                                     const FitResult& fit, const std::vector<int>& frames,
                                                     const SimulationSettings& simulation) {
    const SilhouetteModel model(body, camera);
    std::vector<double> times;
    for (int f : frames) times.push_back((f - fit.reference_frame) / fit.fps);
    SimulationSettings s = simulation;
    s.sensitivities = false;
    const Trajectory t = simulate(body, fit.parameters, times, s);
    Scratch scratch;
    std::vector<metrics::Silhouette> out;
    for (const RigidState& state : t.states) out.push_back(model.render(Pose::of(state), scratch));
    return out;
}

// ---- Loading masks ------------------------------------------------------------------

namespace {

// Object = the largest connected region differing from the background by more than 10 %.
metrics::Silhouette segment_against_background(const formats::Image& frame, const formats::Image& background) {
    cv::Mat different(frame.height, frame.width, CV_8UC1, cv::Scalar(0));
    for (int y = 0; y < frame.height; ++y)
        for (int x = 0; x < frame.width; ++x) {
            float d = 0.0f;
            for (int c = 0; c < frame.channels; ++c) d = std::max(d, std::abs(frame.at(x, y, c) - background.at(x, y, c)));
            different.at<std::uint8_t>(y, x) = d > 0.1f ? 255 : 0;
        }
    cv::morphologyEx(different, different, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
    cv::Mat labels, stats, centroids;
    const int count = cv::connectedComponentsWithStats(different, labels, stats, centroids, 8, CV_32S);
    int best = 0, best_area = 0;
    for (int i = 1; i < count; ++i)
        if (stats.at<int>(i, cv::CC_STAT_AREA) > best_area) {
            best_area = stats.at<int>(i, cv::CC_STAT_AREA);
            best = i;
        }
    metrics::Silhouette s(frame.width, frame.height);
    if (best == 0) return s;
    for (int y = 0; y < frame.height; ++y)
        for (int x = 0; x < frame.width; ++x) s.set(x, y, labels.at<int>(y, x) == best);
    return s;
}

}  // namespace

std::vector<FrameObservation> load_observations(const formats::Capture& capture, int first, int last, int reference_frame,
                                                int threads) {
    if (capture.masks.empty() && capture.background.empty())
        throw ValidationError({Problem{Problem::Severity::error, capture.json_path, "/masks",
                                       "fitting a rigid body needs silhouettes: the capture has neither masks nor a background image",
                                       "add \"masks\": \"masks/%06d.png\" (255 = object) or a \"background\" image"}});
    const double fps = capture.fps > 0.0 ? capture.fps : 30.0;
    std::vector<int> numbers;
    for (int f = first; f <= last; ++f) numbers.push_back(f);
    std::vector<FrameObservation> out(numbers.size());
    if (!capture.masks.empty()) {
        std::vector<std::unique_ptr<formats::FrameSource>> sources(
            static_cast<std::size_t>(resolve_thread_count(threads)));
        parallel_for(numbers.size(), static_cast<int>(sources.size()), [&](std::size_t i, int t) {
            auto& source = sources[static_cast<std::size_t>(t)];
            if (!source) source = std::make_unique<formats::FrameSource>(capture);
            metrics::Silhouette mask = metrics::silhouette_from_image(source->mask(numbers[i]), 0.5f);
            out[i] = make_frame_observation(std::move(mask), numbers[i], (numbers[i] - reference_frame) / fps);
        });
    } else {
        // Video frames decode sequentially: one source, in order.
        formats::FrameSource source(capture);
        const formats::Image background = source.background();
        for (std::size_t i = 0; i < numbers.size(); ++i)
            out[i] = make_frame_observation(segment_against_background(source.frame(numbers[i]), background), numbers[i],
                                            (numbers[i] - reference_frame) / fps);
    }
    return out;
}

}  // namespace flowvid::rigid
