#include "flowvid/rigid/fit_file.hpp"

#include <algorithm>
#include <cmath>

namespace flowvid::rigid {

namespace {

nlohmann::json array_of(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

}  // namespace

FitResult RigidFitRecord::as_fit_result() const {
    FitResult fit;
    fit.parameters = initial;
    fit.reference_frame = initial_frame;
    fit.fps = fps;
    fit.final_cost_px2 = final_cost_px2;
    fit.frames = frames;
    return fit;
}

RigidFitRecord make_rigid_fit_record(const FitResult& fit, const RigidBody& body, const formats::Capture& capture,
                                     const std::string& capture_argument) {
    RigidFitRecord r;
    r.capture = capture_argument;
    r.capture_json_sha256 = capture.capture_json_sha256;
    r.fps = fit.fps;
    r.initial_frame = capture.frames.first;
    r.first_fitted_frame = fit.frames.empty() ? fit.reference_frame : fit.frames.front().frame;
    r.last_fitted_frame = fit.frames.empty() ? fit.reference_frame : fit.frames.back().frame;
    const RigidState state = fit.state_at_frame(body, r.initial_frame);
    r.initial = FlightParameters::from_state(state, fit.parameters.gravity, fit.parameters.gravity_magnitude_m_per_s2);
    r.optimizer = optimizer_name(fit.optimizer);
    r.status = status_name(fit.report.status);
    r.reason = fit.report.reason;
    r.final_cost_px2 = fit.final_cost_px2;
    r.frames = fit.frames;
    r.seconds = fit.seconds;
    const TrajectoryEstimate& t = fit.trajectory;
    r.details = {
        {"reference_frame", fit.reference_frame},
        {"trajectory_estimate",
         {{"com_cam", array_of(t.com_m)},
          {"com_velocity_cam", array_of(t.com_velocity_m_per_s)},
          {"gravity_tilt_deg", t.gravity.tilt_rad * 180.0 / M_PI},
          {"gravity_roll_deg", t.gravity.roll_rad * 180.0 / M_PI},
          {"centroid_rms_px", t.rms_centroid_px}}},
        {"candidate_orientations", fit.candidate_orientations},
        {"starts_scored", fit.starts_scored},
        {"starts_refined", fit.starts_refined},
        {"widened_search", fit.widened},
        {"final_start_costs_px2", fit.start_costs_px2},
        {"iterations_last_window", fit.report.iterations},
    };
    return r;
}

formats::RigidFit to_rigid_fit_file(const RigidFitRecord& r, const RigidBody& body) {
    const RigidState s = r.initial.initial_state();
    formats::RigidFit file;
    file.conventions = kCameraSpaceConventions;
    file.capture = r.capture;
    file.capture_json_sha256 = r.capture_json_sha256;
    file.fps = r.fps;
    file.initial_frame = r.initial_frame;
    file.first_fitted_frame = r.first_fitted_frame;
    file.last_fitted_frame = r.last_fitted_frame;
    file.gravity_magnitude_m_per_s2 = r.initial.gravity_magnitude_m_per_s2;
    file.initial.position_cam = s.origin_m(body);
    file.initial.com_cam = s.com_m;
    file.initial.orientation_cam = s.orientation;
    file.initial.com_velocity_cam = s.com_velocity_m_per_s;
    file.initial.origin_velocity_cam = s.origin_velocity_m_per_s(body);
    file.initial.angular_velocity_cam = s.angular_velocity_rad_per_s();
    file.initial.angular_velocity_body = s.angular_velocity_body_rad_per_s;
    file.gravity_cam = r.initial.gravity_m_per_s2();
    file.gravity_tilt_deg = r.initial.gravity.tilt_rad * 180.0 / M_PI;
    file.gravity_roll_deg = r.initial.gravity.roll_rad * 180.0 / M_PI;
    file.optimizer = r.optimizer;
    double mean_rms = 0.0, max_rms = 0.0, mean_iou = 0.0, min_iou = 1.0;
    for (const FrameFit& f : r.frames) {
        file.frames.push_back({f.frame, f.edge_rms_px, f.xor_px, f.iou});
        mean_rms += f.edge_rms_px / static_cast<double>(r.frames.size());
        max_rms = std::max(max_rms, f.edge_rms_px);
        mean_iou += f.iou / static_cast<double>(r.frames.size());
        min_iou = std::min(min_iou, f.iou);
    }
    formats::RigidFitError error;
    error.final_cost_px2 = r.final_cost_px2;
    error.mean_edge_rms_px = mean_rms;
    error.max_edge_rms_px = max_rms;
    error.mean_iou = r.frames.empty() ? 0.0 : mean_iou;
    error.min_iou = r.frames.empty() ? 0.0 : min_iou;
    error.status = r.status;
    error.reason = r.reason;
    file.error = error;
    file.symmetries_body = body.symmetries;
    file.timing_s = r.seconds;
    file.details = r.details;
    return file;
}

RigidFitRecord rigid_fit_record_from_file(const formats::RigidFit& file) {
    RigidFitRecord record;
    record.capture = file.capture;
    record.capture_json_sha256 = file.capture_json_sha256;
    record.fps = file.fps;
    record.initial_frame = file.initial_frame;
    record.first_fitted_frame = file.first_fitted_frame;
    record.last_fitted_frame = file.last_fitted_frame;
    record.initial.com_m = file.initial.com_cam;
    record.initial.orientation = file.initial.orientation_cam.normalized();
    record.initial.com_velocity_m_per_s = file.initial.com_velocity_cam;
    record.initial.angular_velocity_rad_per_s = file.initial.angular_velocity_cam;
    record.initial.gravity = GravityAngles::from_vector(file.gravity_cam);
    record.initial.gravity_magnitude_m_per_s2 = file.gravity_magnitude_m_per_s2;
    record.optimizer = file.optimizer;
    if (file.error) {
        record.final_cost_px2 = file.error->final_cost_px2;
        record.status = file.error->status;
        record.reason = file.error->reason;
    }
    for (const formats::RigidFitFrame& f : file.frames) record.frames.push_back({f.frame, f.edge_rms_px, f.xor_px, f.iou});
    record.seconds = file.timing_s.value_or(0.0);
    record.details = file.details;
    return record;
}

nlohmann::json rigid_fit_to_json(const RigidFitRecord& record, const RigidBody& body) {
    return formats::rigid_fit_to_json(to_rigid_fit_file(record, body));
}

void write_rigid_fit(const std::string& path, const RigidFitRecord& record, const RigidBody& body) {
    formats::write_rigid_fit(path, to_rigid_fit_file(record, body));
}

RigidFitRecord read_rigid_fit(const std::string& path, std::vector<Problem>* warnings) {
    return rigid_fit_record_from_file(formats::read_rigid_fit(path, warnings));
}

GuessFile read_guess_file(const std::string& path) {
    const formats::RigidFitGuess file = formats::read_rigid_fit_guess(path);
    GuessFile out;
    out.guess.origin_m = file.position_cam;
    if (file.orientation_cam) out.guess.orientation = file.orientation_cam->normalized();
    out.guess.com_velocity_m_per_s = file.com_velocity_cam;
    out.guess.angular_velocity_rad_per_s = file.angular_velocity_cam;
    out.guess.gravity_m_per_s2 = file.gravity_cam;
    out.initial_frame = file.initial_frame;
    return out;
}

}  // namespace flowvid::rigid
