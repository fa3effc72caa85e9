#pragma once
// Rigid fit (fit.json, format "flowvid.rigid_fit", version 1.0): the result of
// `flowvid fit rigid`, read back by `flowvid predict rigid`, `flowvid
// rectify` and `flowvid diagnose --fit`; also rough guesses for `flowvid
// fit rigid --guess`. formats/specs/rigid_fit.md describes every field.
//
// The state keys and their meaning are those of a rigid.toss capture's
// truth/truth.json (its "conventions" string is repeated in the file):
// camera space = the capture's OpenCV camera (x right, y down, z forward,
// metres); orientation = rotation camera_from_body as (w, x, y, z); angular
// velocity in rad/s in camera axes; "position_cam" is the body-frame (mesh)
// origin, "com_cam" the centre of mass. "initial" holds at "initial_frame".
//
// This is the file's content only: libflowvid rigid/fit_file.hpp turns a fit
// (and its body) into one and back.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kRigidFitFormatName = "flowvid.rigid_fit";
inline constexpr FormatVersion kRigidFitFormatVersion{1, 0};
inline constexpr const char* kRigidFitConventions =
    "camera space = OpenCV camera of capture.json (x right, y down, z forward). Orientation q = rotation "
    "camera_from_body as (w,x,y,z). Angular velocity in rad/s in camera coordinates. 'position' is the body-frame "
    "(mesh) origin; the COM is also given.";
// Gravity's magnitude when a file does not give it (m/s^2).
inline constexpr double kRigidFitDefaultGravity_m_per_s2 = 9.81;

// The body's state at the file's initial frame, in camera space.
struct RigidFitState {
    Eigen::Vector3d position_cam = Eigen::Vector3d::Zero();          // body-frame (mesh) origin, m
    Eigen::Vector3d com_cam = Eigen::Vector3d::Zero();               // centre of mass, m
    Eigen::Quaterniond orientation_cam = Eigen::Quaterniond::Identity();  // camera_from_body, |q| within 1e-3 of 1 (as written)
    Eigen::Vector3d com_velocity_cam = Eigen::Vector3d::Zero();      // m/s
    std::optional<Eigen::Vector3d> origin_velocity_cam;              // m/s, of the body-frame origin
    Eigen::Vector3d angular_velocity_cam = Eigen::Vector3d::Zero();  // rad/s, camera axes
    std::optional<Eigen::Vector3d> angular_velocity_body;            // rad/s, body axes
};

struct RigidFitFrame {
    int frame = 0;             // the capture's frame number
    double edge_rms_px = 0.0;  // RMS distance between predicted and observed silhouette edges, px
    long long xor_px = 0;      // pixels in one silhouette but not the other
    double iou = 0.0;          // intersection over union of the silhouettes, [0, 1]
};

struct RigidFitError {
    double final_cost_px2 = 0.0;  // the optimizer's cost at the result, px^2
    // Over `frames`: written by the fit; optional on reading.
    std::optional<double> mean_edge_rms_px, max_edge_rms_px, mean_iou, min_iou;
    std::string status;           // the optimizer's status, e.g. "converged"
    std::string reason;           // why it stopped, for people
};

struct RigidFit {
    std::string conventions = kRigidFitConventions;
    std::string capture;              // the capture folder as given to the fit
    std::string capture_json_sha256;  // of its capture.json when fitted ("" when absent)
    double fps = 30.0;                // frames per second of the capture
    int initial_frame = 1;            // "initial" holds at this frame
    int first_fitted_frame = 1;       // "fit_frames": [first, last], inclusive
    int last_fitted_frame = 1;
    double gravity_magnitude_m_per_s2 = kRigidFitDefaultGravity_m_per_s2;
    RigidFitState initial;
    Eigen::Vector3d gravity_cam = Eigen::Vector3d(0.0, kRigidFitDefaultGravity_m_per_s2, 0.0);  // m/s^2, camera axes
    // Gravity's direction as the fit's angles (degrees, not wrapped): g is along
    // (sin roll cos tilt, cos roll cos tilt, sin tilt). gravity_cam is what readers use.
    std::optional<double> gravity_tilt_deg, gravity_roll_deg;
    std::string optimizer = "levenberg_marquardt";
    std::optional<RigidFitError> error;
    std::vector<RigidFitFrame> frames;
    std::vector<Eigen::Matrix3d> symmetries_body;  // body-frame rotations the mesh maps onto itself
    std::optional<double> timing_s;                // seconds the fit took
    nlohmann::json details;                        // free-form (null: none)
};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the fit when valid.
std::optional<RigidFit> parse_rigid_fit(const nlohmann::json& document, Diagnostics& diagnostics,
                                        Strictness strictness = Strictness::lenient);
nlohmann::json rigid_fit_to_json(const RigidFit& fit);
// Reads and validates; throws IoError (cannot read) or ValidationError listing every problem.
RigidFit read_rigid_fit(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (finite numbers, unit quaternion, fps > 0, ...; a non-finite
// value is named by its field) then writes atomically.
void write_rigid_fit(const std::string& path, const RigidFit& fit);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_rigid_fit_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_rigid_fit(const RigidFit& fit);

// A guess for `flowvid fit rigid --guess`: a rigid fit file, a capture's
// truth.json, or any JSON object with some of "initial": {"position_cam",
// "orientation_cam_wxyz", "com_velocity_cam", "angular_velocity_cam"},
// "gravity_cam" and "initial_frame". A file that declares a "format" must be
// a rigid fit this flowvid reads. Throws IoError or ValidationError (a guess
// that gives no usable value, too).
struct RigidFitGuess {
    std::optional<Eigen::Vector3d> position_cam;
    std::optional<Eigen::Quaterniond> orientation_cam;  // |q| within 1e-3 of 1 (as written)
    std::optional<Eigen::Vector3d> com_velocity_cam;
    std::optional<Eigen::Vector3d> angular_velocity_cam;
    std::optional<Eigen::Vector3d> gravity_cam;          // only the direction is used
    std::optional<int> initial_frame;                    // absent: the capture's first frame
};
RigidFitGuess read_rigid_fit_guess(const std::string& path);

}  // namespace flowvid::formats
