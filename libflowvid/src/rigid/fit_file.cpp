#include "flowvid/rigid/fit_file.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <algorithm>
#include <cmath>

namespace flowvid::rigid {

namespace {

using formats::JsonView;
using formats::NumberRange;
using formats::Strictness;

nlohmann::json array_of(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }
nlohmann::json array_of(const Eigen::Quaterniond& q) { return nlohmann::json::array({q.w(), q.x(), q.y(), q.z()}); }

std::optional<Eigen::Vector3d> vector3(const JsonView& view, const std::string& key, bool required) {
    const std::optional<std::vector<double>> v = view.numbers(key, 3, NumberRange{}, required);
    if (!v) return std::nullopt;
    return Eigen::Vector3d((*v)[0], (*v)[1], (*v)[2]);
}

std::optional<Eigen::Quaterniond> quaternion(const JsonView& view, const std::string& key, bool required) {
    const std::optional<std::vector<double>> v = view.numbers(key, 4, NumberRange{}, required);
    if (!v) return std::nullopt;
    const Eigen::Quaterniond q((*v)[0], (*v)[1], (*v)[2], (*v)[3]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
        view.diagnostics().error(formats::json_pointer_child(view.pointer(), key),
                                 "not a unit quaternion (norm " + std::to_string(q.norm()) + ")",
                                 "write the orientation as a unit quaternion (w, x, y, z)");
        return std::nullopt;
    }
    return q.normalized();
}

std::optional<RigidFitRecord> parse_rigid_fit(const nlohmann::json& document, Diagnostics& diagnostics, Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!document.is_object()) {
        diagnostics.error("", "a rigid fit file is a JSON object", "write the file with `flowvid fit rigid`");
        return std::nullopt;
    }
    if (!formats::check_format_header(root, kRigidFitFormatName, kRigidFitVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "conventions", "capture", "capture_json_sha256", "fps", "initial_frame",
                           "fit_frames", "gravity_magnitude_m_per_s2", "initial", "gravity_cam", "gravity_angles_deg",
                           "optimizer", "error", "frames", "details", "timing_s", "symmetries_body"});
    RigidFitRecord record;
    record.capture = root.string("capture").value_or("");
    record.capture_json_sha256 = root.string("capture_json_sha256", false).value_or("");
    record.fps = root.number("fps", NumberRange::positive("frames/s")).value_or(30.0);
    record.initial_frame = static_cast<int>(root.integer("initial_frame", 0, 100000000).value_or(1));
    if (const std::optional<JsonView> range = root.array("fit_frames")) {
        if (range->size() != 2) {
            diagnostics.error("/fit_frames", "expected [first, last]", "write the fitted frame range as two integers");
        } else {
            const std::optional<double> a = range->element(0).as_number(NumberRange::non_negative(""));
            const std::optional<double> b = range->element(1).as_number(NumberRange::non_negative(""));
            if (a && b) {
                record.first_fitted_frame = static_cast<int>(*a);
                record.last_fitted_frame = static_cast<int>(*b);
                if (record.last_fitted_frame < record.first_fitted_frame)
                    diagnostics.error("/fit_frames", "the last frame comes before the first", "write [first, last]");
            }
        }
    }
    const double magnitude =
        root.number("gravity_magnitude_m_per_s2", NumberRange::positive("m/s^2"), false).value_or(kStandardGravity_m_per_s2);
    if (const std::optional<JsonView> initial = root.object("initial")) {
        initial->check_known_keys({"position_cam", "com_cam", "orientation_cam_wxyz", "com_velocity_cam", "origin_velocity_cam",
                                   "angular_velocity_cam", "angular_velocity_body"});
        vector3(*initial, "position_cam", true);
        const std::optional<Eigen::Vector3d> com = vector3(*initial, "com_cam", true);
        const std::optional<Eigen::Quaterniond> q = quaternion(*initial, "orientation_cam_wxyz", true);
        const std::optional<Eigen::Vector3d> v = vector3(*initial, "com_velocity_cam", true);
        const std::optional<Eigen::Vector3d> w = vector3(*initial, "angular_velocity_cam", true);
        if (com) record.initial.com_m = *com;
        if (q) record.initial.orientation = *q;
        if (v) record.initial.com_velocity_m_per_s = *v;
        if (w) record.initial.angular_velocity_rad_per_s = *w;
    }
    if (const std::optional<Eigen::Vector3d> g = vector3(root, "gravity_cam", true)) {
        if (!(g->norm() > 0.0))
            diagnostics.error("/gravity_cam", "gravity is the zero vector", "write gravity in camera space, m/s^2");
        else
            record.initial.gravity = GravityAngles::from_vector(*g);
    }
    record.initial.gravity_magnitude_m_per_s2 = magnitude;
    record.optimizer = root.string("optimizer", false).value_or("levenberg_marquardt");
    if (const std::optional<JsonView> error = root.object("error", false)) {
        record.final_cost_px2 = error->number("final_cost_px2", NumberRange::non_negative("px^2"), false).value_or(0.0);
        record.status = error->string("status", false).value_or("");
        record.reason = error->string("reason", false).value_or("");
    }
    if (const std::optional<JsonView> frames = root.array("frames", false)) {
        for (std::size_t i = 0; i < frames->size(); ++i) {
            const JsonView f = frames->element(i);
            FrameFit fit;
            fit.frame = static_cast<int>(f.integer("frame", 0, 100000000).value_or(0));
            fit.edge_rms_px = f.number("edge_rms_px", NumberRange::non_negative("px"), false).value_or(0.0);
            fit.xor_px = f.integer("xor_px", 0, 1LL << 40, false).value_or(0);
            fit.iou = f.number("iou", NumberRange::closed(0.0, 1.0), false).value_or(0.0);
            record.frames.push_back(fit);
        }
    }
    record.seconds = root.number("timing_s", NumberRange::non_negative("s"), false).value_or(0.0);
    if (document.contains("details")) record.details = document["details"];
    return record;
}

void check_before_writing(const RigidFitRecord& r, Diagnostics& diagnostics) {
    auto finite = [&](const Eigen::VectorXd& v, const char* field) {
        if (!v.allFinite()) diagnostics.error(field, "not finite", "the fit diverged: try --guess or other frames");
    };
    finite(r.initial.com_m, "/initial/com_cam");
    finite(r.initial.orientation.coeffs(), "/initial/orientation_cam_wxyz");
    finite(r.initial.com_velocity_m_per_s, "/initial/com_velocity_cam");
    finite(r.initial.angular_velocity_rad_per_s, "/initial/angular_velocity_cam");
    finite(r.initial.gravity.direction(), "/gravity_cam");
    if (!(r.fps > 0.0)) diagnostics.error("/fps", "frame rate must be positive", "take it from capture.json");
}

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

nlohmann::json rigid_fit_to_json(const RigidFitRecord& r, const RigidBody& body) {
    const RigidState s = r.initial.initial_state();
    nlohmann::json frames = nlohmann::json::array();
    double mean_rms = 0.0, max_rms = 0.0, mean_iou = 0.0, min_iou = 1.0;
    for (const FrameFit& f : r.frames) {
        frames.push_back({{"frame", f.frame}, {"edge_rms_px", f.edge_rms_px}, {"xor_px", f.xor_px}, {"iou", f.iou}});
        mean_rms += f.edge_rms_px / static_cast<double>(r.frames.size());
        max_rms = std::max(max_rms, f.edge_rms_px);
        mean_iou += f.iou / static_cast<double>(r.frames.size());
        min_iou = std::min(min_iou, f.iou);
    }
    nlohmann::json symmetries = nlohmann::json::array();
    for (const Eigen::Matrix3d& S : body.symmetries)
        symmetries.push_back({{S(0, 0), S(0, 1), S(0, 2)}, {S(1, 0), S(1, 1), S(1, 2)}, {S(2, 0), S(2, 1), S(2, 2)}});
    nlohmann::json document = {
        {"format", kRigidFitFormatName},
        {"version", kRigidFitVersion.to_string()},
        {"conventions", kCameraSpaceConventions},
        {"capture", r.capture},
        {"capture_json_sha256", r.capture_json_sha256},
        {"fps", r.fps},
        {"initial_frame", r.initial_frame},
        {"fit_frames", {r.first_fitted_frame, r.last_fitted_frame}},
        {"gravity_magnitude_m_per_s2", r.initial.gravity_magnitude_m_per_s2},
        {"initial",
         {{"position_cam", array_of(s.origin_m(body))},
          {"com_cam", array_of(s.com_m)},
          {"orientation_cam_wxyz", array_of(s.orientation)},
          {"com_velocity_cam", array_of(s.com_velocity_m_per_s)},
          {"origin_velocity_cam", array_of(s.origin_velocity_m_per_s(body))},
          {"angular_velocity_cam", array_of(s.angular_velocity_rad_per_s())},
          {"angular_velocity_body", array_of(s.angular_velocity_body_rad_per_s)}}},
        {"gravity_cam", array_of(r.initial.gravity_m_per_s2())},
        {"gravity_angles_deg",
         {{"tilt", r.initial.gravity.tilt_rad * 180.0 / M_PI}, {"roll", r.initial.gravity.roll_rad * 180.0 / M_PI}}},
        {"optimizer", r.optimizer},
        {"error",
         {{"final_cost_px2", r.final_cost_px2},
          {"mean_edge_rms_px", mean_rms},
          {"max_edge_rms_px", max_rms},
          {"mean_iou", r.frames.empty() ? 0.0 : mean_iou},
          {"min_iou", r.frames.empty() ? 0.0 : min_iou},
          {"status", r.status},
          {"reason", r.reason}}},
        {"frames", frames},
        {"symmetries_body", symmetries},
        {"timing_s", r.seconds},
    };
    if (!r.details.is_null()) document["details"] = r.details;
    return document;
}

void write_rigid_fit(const std::string& path, const RigidFitRecord& record, const RigidBody& body) {
    Diagnostics diagnostics(path);
    check_before_writing(record, diagnostics);
    diagnostics.throw_if_errors();
    const nlohmann::json document = rigid_fit_to_json(record, body);
    parse_rigid_fit(document, diagnostics, Strictness::strict);
    diagnostics.throw_if_errors();
    const std::string text = formats::dump_json(document);
    formats::write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

RigidFitRecord read_rigid_fit(const std::string& path) {
    const std::string text = formats::read_text_file(path);
    Diagnostics diagnostics(path);
    std::optional<nlohmann::json> document = formats::parse_json_text(text, diagnostics);
    std::optional<RigidFitRecord> record;
    if (document) record = parse_rigid_fit(*document, diagnostics, Strictness::lenient);
    diagnostics.throw_if_errors();
    return *record;
}

std::vector<Problem> validate_rigid_fit_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    std::string text;
    try {
        text = formats::read_text_file(path);
    } catch (const IoError& error) {
        diagnostics.error("", error.what(), error.fix());
        return diagnostics.problems();
    }
    if (std::optional<nlohmann::json> document = formats::parse_json_text(text, diagnostics))
        parse_rigid_fit(*document, diagnostics, strictness);
    return diagnostics.problems();
}

GuessFile read_guess_file(const std::string& path) {
    const std::string text = formats::read_text_file(path);
    Diagnostics diagnostics(path);
    GuessFile out;
    if (std::optional<nlohmann::json> document = formats::parse_json_text(text, diagnostics)) {
        const JsonView root(*document, "", diagnostics, Strictness::lenient);
        if (!document->is_object()) {
            diagnostics.error("", "a guess is a JSON object", "write e.g. {\"initial\": {\"orientation_cam_wxyz\": [1, 0, 0, 0]}}");
        } else {
            // A rigid fit file must be one we can read; other JSON (e.g. truth.json) is taken as it is.
            if (document->contains("format")) formats::check_format_header(root, kRigidFitFormatName, kRigidFitVersion);
            if (root.has("initial_frame"))
                out.initial_frame = static_cast<int>(root.integer("initial_frame", 0, 100000000).value_or(1));
            if (const std::optional<JsonView> initial = root.object("initial", false)) {
                out.guess.origin_m = vector3(*initial, "position_cam", false);
                out.guess.orientation = quaternion(*initial, "orientation_cam_wxyz", false);
                out.guess.com_velocity_m_per_s = vector3(*initial, "com_velocity_cam", false);
                out.guess.angular_velocity_rad_per_s = vector3(*initial, "angular_velocity_cam", false);
            }
            out.guess.gravity_m_per_s2 = vector3(root, "gravity_cam", false);
            if (out.guess.gravity_m_per_s2 && !(out.guess.gravity_m_per_s2->norm() > 0.0)) {
                diagnostics.error("/gravity_cam", "gravity is the zero vector", "give gravity's direction in camera space");
                out.guess.gravity_m_per_s2.reset();
            }
            const InitialGuess& g = out.guess;
            if (!diagnostics.has_errors() && !g.origin_m && !g.orientation && !g.com_velocity_m_per_s &&
                !g.angular_velocity_rad_per_s && !g.gravity_m_per_s2)
                diagnostics.error("/initial", "the guess gives no usable value",
                                  "give some of initial.position_cam, initial.orientation_cam_wxyz, initial.com_velocity_cam, "
                                  "initial.angular_velocity_cam and gravity_cam");
        }
    }
    diagnostics.throw_if_errors();
    return out;
}

}  // namespace flowvid::rigid
