#include "flowvid/formats/rigid_fit.hpp"

#include "json_extras.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace flowvid::formats {

namespace {

constexpr std::int64_t kMaxFrame = 100000000;

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
        view.diagnostics().error(json_pointer_child(view.pointer(), key),
                                 "not a unit quaternion (norm " + std::to_string(q.norm()) + ")",
                                 "write the orientation as a unit quaternion (w, x, y, z)");
        return std::nullopt;
    }
    return q;  // as written: users of the state normalise it
}

// A body-frame rotation: three rows of three numbers, orthonormal, determinant +1.
std::optional<Eigen::Matrix3d> rotation(const JsonView& element) {
    Diagnostics& diag = element.diagnostics();
    if (!element.json().is_array() || element.size() != 3) {
        diag.error(element.pointer(), "expected a 3x3 rotation (three rows of three numbers)",
                   "write each symmetry as [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]]");
        return std::nullopt;
    }
    Eigen::Matrix3d m;
    bool ok = true;
    for (std::size_t r = 0; r < 3; ++r) {
        const JsonView row = element.element(r);
        if (!row.json().is_array() || row.size() != 3) {
            diag.error(row.pointer(), "expected a row of 3 numbers", "write each row as three numbers");
            ok = false;
            continue;
        }
        for (std::size_t c = 0; c < 3; ++c) {
            const std::optional<double> v = row.element(c).as_number(NumberRange{});
            if (v) m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = *v;
            else ok = false;
        }
    }
    if (!ok) return std::nullopt;
    if ((m.transpose() * m - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || m.determinant() < 0.0) {
        diag.error(element.pointer(), "not a rotation (orthonormal, determinant +1)",
                   "write the body's symmetry rotations as `flowvid fit rigid` finds them");
        return std::nullopt;
    }
    return m;
}

void parse_error_block(const JsonView& root, RigidFit& fit) {
    const std::optional<JsonView> error = root.object("error", false);
    if (!error) return;
    error->check_known_keys({"final_cost_px2", "mean_edge_rms_px", "max_edge_rms_px", "mean_iou", "min_iou", "status", "reason"});
    RigidFitError out;
    out.final_cost_px2 = error->number("final_cost_px2", NumberRange::non_negative("px^2"), false).value_or(0.0);
    out.mean_edge_rms_px = error->number("mean_edge_rms_px", NumberRange::non_negative("px"), false);
    out.max_edge_rms_px = error->number("max_edge_rms_px", NumberRange::non_negative("px"), false);
    // A mean of IoUs of 1 may pass 1 by a rounding error.
    out.mean_iou = error->number("mean_iou", NumberRange::closed(0.0, 1.0 + 1e-9), false);
    out.min_iou = error->number("min_iou", NumberRange::closed(0.0, 1.0), false);
    out.status = error->string("status", false).value_or("");
    out.reason = error->string("reason", false).value_or("");
    fit.error = out;
}

void parse_frames(const JsonView& root, RigidFit& fit) {
    const std::optional<JsonView> frames = root.array("frames", false);
    if (!frames) return;
    for (std::size_t i = 0; i < frames->size(); ++i) {
        const JsonView f = frames->element(i);
        if (!detail::expect_object(f, "write each frame as {\"frame\": ..., \"edge_rms_px\": ..., \"xor_px\": ..., \"iou\": ...}"))
            continue;
        f.check_known_keys({"frame", "edge_rms_px", "xor_px", "iou"});
        RigidFitFrame frame;
        frame.frame = static_cast<int>(f.integer("frame", 0, kMaxFrame).value_or(0));
        frame.edge_rms_px = f.number("edge_rms_px", NumberRange::non_negative("px"), false).value_or(0.0);
        frame.xor_px = f.integer("xor_px", 0, 1LL << 40, false).value_or(0);
        frame.iou = f.number("iou", NumberRange::closed(0.0, 1.0), false).value_or(0.0);
        fit.frames.push_back(frame);
    }
}

// Values JSON cannot hold: named with the fit's advice before they would become null.
void check_finite(const RigidFit& fit, Diagnostics& diagnostics) {
    const auto finite = [&](const Eigen::VectorXd& v, const char* field) {
        if (!v.allFinite()) diagnostics.error(field, "not finite", "the fit diverged: try --guess or other frames");
    };
    finite(fit.initial.position_cam, "/initial/position_cam");
    finite(fit.initial.com_cam, "/initial/com_cam");
    finite(fit.initial.orientation_cam.coeffs(), "/initial/orientation_cam_wxyz");
    finite(fit.initial.com_velocity_cam, "/initial/com_velocity_cam");
    if (fit.initial.origin_velocity_cam) finite(*fit.initial.origin_velocity_cam, "/initial/origin_velocity_cam");
    finite(fit.initial.angular_velocity_cam, "/initial/angular_velocity_cam");
    if (fit.initial.angular_velocity_body) finite(*fit.initial.angular_velocity_body, "/initial/angular_velocity_body");
    finite(fit.gravity_cam, "/gravity_cam");
    if (!(fit.fps > 0.0)) diagnostics.error("/fps", "frame rate must be positive", "take it from capture.json");
}

}  // namespace

std::optional<RigidFit> parse_rigid_fit(const nlohmann::json& document, Diagnostics& diagnostics, Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!document.is_object()) {
        diagnostics.error("", "a rigid fit file is a JSON object", "write the file with `flowvid fit rigid`");
        return std::nullopt;
    }
    if (!check_format_header(root, kRigidFitFormatName, kRigidFitFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "conventions", "capture", "capture_json_sha256", "fps", "initial_frame",
                           "fit_frames", "gravity_magnitude_m_per_s2", "initial", "gravity_cam", "gravity_angles_deg",
                           "optimizer", "error", "frames", "details", "timing_s", "symmetries_body"});
    RigidFit fit;
    fit.conventions = root.string("conventions", false).value_or(kRigidFitConventions);
    fit.capture = root.string("capture").value_or("");
    fit.capture_json_sha256 = root.string("capture_json_sha256", false).value_or("");
    fit.fps = root.number("fps", NumberRange::positive("frames/s")).value_or(30.0);
    fit.initial_frame = static_cast<int>(root.integer("initial_frame", 0, kMaxFrame).value_or(1));
    if (const std::optional<JsonView> range = root.array("fit_frames")) {
        if (range->size() != 2) {
            diagnostics.error("/fit_frames", "expected [first, last]", "write the fitted frame range as two integers");
        } else {
            const auto frame_number = [&](std::size_t i) -> std::optional<int> {
                const JsonView element = range->element(i);
                const nlohmann::json& v = element.json();
                if (v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() == std::floor(v.get<double>()) &&
                    v.get<double>() >= 0.0 && v.get<double>() <= static_cast<double>(kMaxFrame))
                    return static_cast<int>(v.get<double>());
                diagnostics.error(element.pointer(), "expected a frame number (an integer in [0, 100000000]), found " + v.dump().substr(0, 24),
                                  "write the fitted frame range as two integers");
                return std::nullopt;
            };
            const std::optional<int> a = frame_number(0), b = frame_number(1);
            if (a && b) {
                fit.first_fitted_frame = *a;
                fit.last_fitted_frame = *b;
                if (*b < *a) diagnostics.error("/fit_frames", "the last frame comes before the first", "write [first, last]");
            }
        }
    }
    fit.gravity_magnitude_m_per_s2 = root.number("gravity_magnitude_m_per_s2", NumberRange::positive("m/s^2"), false)
                                         .value_or(kRigidFitDefaultGravity_m_per_s2);
    if (const std::optional<JsonView> initial = root.object("initial")) {
        initial->check_known_keys({"position_cam", "com_cam", "orientation_cam_wxyz", "com_velocity_cam", "origin_velocity_cam",
                                   "angular_velocity_cam", "angular_velocity_body"});
        const std::optional<Eigen::Vector3d> position = vector3(*initial, "position_cam", true);
        const std::optional<Eigen::Vector3d> com = vector3(*initial, "com_cam", true);
        const std::optional<Eigen::Quaterniond> q = quaternion(*initial, "orientation_cam_wxyz", true);
        const std::optional<Eigen::Vector3d> v = vector3(*initial, "com_velocity_cam", true);
        const std::optional<Eigen::Vector3d> w = vector3(*initial, "angular_velocity_cam", true);
        if (position) fit.initial.position_cam = *position;
        if (com) fit.initial.com_cam = *com;
        if (q) fit.initial.orientation_cam = *q;
        if (v) fit.initial.com_velocity_cam = *v;
        if (w) fit.initial.angular_velocity_cam = *w;
        fit.initial.origin_velocity_cam = vector3(*initial, "origin_velocity_cam", false);
        fit.initial.angular_velocity_body = vector3(*initial, "angular_velocity_body", false);
    }
    if (const std::optional<Eigen::Vector3d> g = vector3(root, "gravity_cam", true)) {
        if (!(g->norm() > 0.0)) diagnostics.error("/gravity_cam", "gravity is the zero vector", "write gravity in camera space, m/s^2");
        else fit.gravity_cam = *g;
    }
    if (const std::optional<JsonView> angles = root.object("gravity_angles_deg", false)) {
        angles->check_known_keys({"tilt", "roll"});
        // The fit's own angles, not wrapped into a range: gravity_cam is what readers use.
        fit.gravity_tilt_deg = angles->number("tilt", NumberRange{});
        fit.gravity_roll_deg = angles->number("roll", NumberRange{});
    }
    fit.optimizer = root.string("optimizer", false).value_or("levenberg_marquardt");
    parse_error_block(root, fit);
    parse_frames(root, fit);
    if (const std::optional<JsonView> symmetries = root.array("symmetries_body", false))
        for (std::size_t i = 0; i < symmetries->size(); ++i)
            if (const std::optional<Eigen::Matrix3d> s = rotation(symmetries->element(i))) fit.symmetries_body.push_back(*s);
    fit.timing_s = root.number("timing_s", NumberRange::non_negative("s"), false);
    if (document.contains("details")) fit.details = document["details"];
    if (diagnostics.has_errors()) return std::nullopt;
    return fit;
}

nlohmann::json rigid_fit_to_json(const RigidFit& fit) {
    nlohmann::json frames = nlohmann::json::array();
    for (const RigidFitFrame& f : fit.frames)
        frames.push_back({{"frame", f.frame}, {"edge_rms_px", f.edge_rms_px}, {"xor_px", f.xor_px}, {"iou", f.iou}});
    nlohmann::json symmetries = nlohmann::json::array();
    for (const Eigen::Matrix3d& S : fit.symmetries_body)
        symmetries.push_back({{S(0, 0), S(0, 1), S(0, 2)}, {S(1, 0), S(1, 1), S(1, 2)}, {S(2, 0), S(2, 1), S(2, 2)}});
    nlohmann::json initial = {{"position_cam", array_of(fit.initial.position_cam)},
                              {"com_cam", array_of(fit.initial.com_cam)},
                              {"orientation_cam_wxyz", array_of(fit.initial.orientation_cam)},
                              {"com_velocity_cam", array_of(fit.initial.com_velocity_cam)},
                              {"angular_velocity_cam", array_of(fit.initial.angular_velocity_cam)}};
    if (fit.initial.origin_velocity_cam) initial["origin_velocity_cam"] = array_of(*fit.initial.origin_velocity_cam);
    if (fit.initial.angular_velocity_body) initial["angular_velocity_body"] = array_of(*fit.initial.angular_velocity_body);
    // nlohmann objects sort their keys: the file's key order is fixed.
    nlohmann::json document = {
        {"format", kRigidFitFormatName},
        {"version", kRigidFitFormatVersion.to_string()},
        {"conventions", fit.conventions},
        {"capture", fit.capture},
        {"capture_json_sha256", fit.capture_json_sha256},
        {"fps", fit.fps},
        {"initial_frame", fit.initial_frame},
        {"fit_frames", {fit.first_fitted_frame, fit.last_fitted_frame}},
        {"gravity_magnitude_m_per_s2", fit.gravity_magnitude_m_per_s2},
        {"initial", initial},
        {"gravity_cam", array_of(fit.gravity_cam)},
        {"optimizer", fit.optimizer},
        {"frames", frames},
        {"symmetries_body", symmetries},
    };
    if (fit.gravity_tilt_deg || fit.gravity_roll_deg) {
        nlohmann::json angles = nlohmann::json::object();
        if (fit.gravity_tilt_deg) angles["tilt"] = *fit.gravity_tilt_deg;
        if (fit.gravity_roll_deg) angles["roll"] = *fit.gravity_roll_deg;
        document["gravity_angles_deg"] = angles;
    }
    if (fit.error) {
        const RigidFitError& e = *fit.error;
        nlohmann::json error = {{"final_cost_px2", e.final_cost_px2}, {"status", e.status}, {"reason", e.reason}};
        if (e.mean_edge_rms_px) error["mean_edge_rms_px"] = *e.mean_edge_rms_px;
        if (e.max_edge_rms_px) error["max_edge_rms_px"] = *e.max_edge_rms_px;
        if (e.mean_iou) error["mean_iou"] = *e.mean_iou;
        if (e.min_iou) error["min_iou"] = *e.min_iou;
        document["error"] = error;
    }
    if (fit.timing_s) document["timing_s"] = *fit.timing_s;
    if (!fit.details.is_null()) document["details"] = fit.details;
    return document;
}

RigidFit read_rigid_fit(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<RigidFit>(path, parse_rigid_fit, warnings);
}

void write_rigid_fit(const std::string& path, const RigidFit& fit) {
    Diagnostics diagnostics(path);
    check_finite(fit, diagnostics);
    diagnostics.throw_if_errors();
    detail::write_validated_json(path, rigid_fit_to_json(fit), parse_rigid_fit);
}

std::vector<Problem> validate_rigid_fit_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_rigid_fit);
}

nlohmann::json summarize_rigid_fit(const RigidFit& fit) {
    nlohmann::json summary = {{"format", kRigidFitFormatName},
                              {"capture", fit.capture},
                              {"fps", fit.fps},
                              {"initial_frame", fit.initial_frame},
                              {"fit_frames", std::to_string(fit.first_fitted_frame) + ":" + std::to_string(fit.last_fitted_frame)},
                              {"optimizer", fit.optimizer},
                              {"com_cam", array_of(fit.initial.com_cam)},
                              {"orientation_cam_wxyz", array_of(fit.initial.orientation_cam)},
                              {"com_velocity_cam", array_of(fit.initial.com_velocity_cam)},
                              {"angular_velocity_cam", array_of(fit.initial.angular_velocity_cam)},
                              {"gravity_cam", array_of(fit.gravity_cam)},
                              {"frames", fit.frames.size()}};
    if (fit.error) {
        summary["final_cost_px2"] = fit.error->final_cost_px2;
        summary["status"] = fit.error->status;
        if (fit.error->mean_iou) summary["mean_iou"] = *fit.error->mean_iou;
    }
    return summary;
}

RigidFitGuess read_rigid_fit_guess(const std::string& path) {
    const std::string text = read_text_file(path);
    Diagnostics diagnostics(path);
    RigidFitGuess out;
    if (std::optional<nlohmann::json> document = parse_json_text(text, diagnostics)) {
        const JsonView root(*document, "", diagnostics, Strictness::lenient);
        if (!document->is_object()) {
            diagnostics.error("", "a guess is a JSON object", "write e.g. {\"initial\": {\"orientation_cam_wxyz\": [1, 0, 0, 0]}}");
        } else {
            // A rigid fit file must be one we can read; other JSON (e.g. truth.json) is taken as it is.
            if (document->contains("format")) check_format_header(root, kRigidFitFormatName, kRigidFitFormatVersion);
            if (root.has("initial_frame"))
                out.initial_frame = static_cast<int>(root.integer("initial_frame", 0, kMaxFrame).value_or(1));
            if (const std::optional<JsonView> initial = root.object("initial", false)) {
                out.position_cam = vector3(*initial, "position_cam", false);
                out.orientation_cam = quaternion(*initial, "orientation_cam_wxyz", false);
                out.com_velocity_cam = vector3(*initial, "com_velocity_cam", false);
                out.angular_velocity_cam = vector3(*initial, "angular_velocity_cam", false);
            }
            out.gravity_cam = vector3(root, "gravity_cam", false);
            if (out.gravity_cam && !(out.gravity_cam->norm() > 0.0)) {
                diagnostics.error("/gravity_cam", "gravity is the zero vector", "give gravity's direction in camera space");
                out.gravity_cam.reset();
            }
            if (!diagnostics.has_errors() && !out.position_cam && !out.orientation_cam && !out.com_velocity_cam &&
                !out.angular_velocity_cam && !out.gravity_cam)
                diagnostics.error("/initial", "the guess gives no usable value",
                                  "give some of initial.position_cam, initial.orientation_cam_wxyz, initial.com_velocity_cam, "
                                  "initial.angular_velocity_cam and gravity_cam");
        }
    }
    diagnostics.throw_if_errors();
    return out;
}

}  // namespace flowvid::formats
