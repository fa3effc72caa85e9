#pragma once
// fit.json: the result of `flowvid fit rigid` (format "flowvid.rigid_fit",
// version 1.0), read back by `flowvid predict rigid` and `flowvid rectify`,
// and guess files for `flowvid fit rigid --guess`.
//
// The file format itself (reader, validator, writer) is
// flowvid::formats::RigidFit (formats/include/flowvid/formats/rigid_fit.hpp,
// spec formats/specs/rigid_fit.md); this header turns a fit of a body into
// that file's content and back.
//
// The state keys and their meaning are those of a rigid.toss capture's
// truth/truth.json (see its "conventions" string, repeated in the file):
// camera space = the capture's OpenCV camera (x right, y down, z forward,
// metres); orientation = rotation camera_from_body as (w, x, y, z); angular
// velocity in rad/s in camera axes; "position_cam" is the body-frame (mesh)
// origin, "com_cam" the centre of mass. "initial" holds at "initial_frame"
// (the capture's first frame, whatever frames were fitted).

#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/formats/rigid_fit.hpp"
#include "flowvid/rigid/fit.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::rigid {

inline constexpr const char* kRigidFitFormatName = formats::kRigidFitFormatName;
inline constexpr formats::FormatVersion kRigidFitVersion = formats::kRigidFitFormatVersion;
inline constexpr const char* kCameraSpaceConventions = formats::kRigidFitConventions;

struct RigidFitRecord {
    std::string capture;              // the capture folder as given to `fit`
    std::string capture_json_sha256;  // of its capture.json when fitted
    double fps = 30.0;
    int initial_frame = 1;            // "initial" holds at this frame
    int first_fitted_frame = 1;
    int last_fitted_frame = 1;
    FlightParameters initial;         // state at initial_frame and gravity
    // Results (written, and read back for information):
    std::string optimizer = "levenberg_marquardt";
    std::string status;               // optimizer status of the winning start
    std::string reason;
    double final_cost_px2 = 0.0;
    std::vector<FrameFit> frames;
    double seconds = 0.0;
    nlohmann::json details;           // free-form: trajectory estimate, multi-start figures

    // A FitResult whose parameters hold at initial_frame, for prediction.
    FitResult as_fit_result() const;
};

// Builds the record of a fit of frames first..last of `capture`.
RigidFitRecord make_rigid_fit_record(const FitResult& fit, const RigidBody& body, const formats::Capture& capture,
                                     const std::string& capture_argument);

// The file's content: the state at initial_frame with what the body adds
// (its origin, velocities in body axes, symmetries), gravity as a vector and
// as angles, the error summary over the frames.
formats::RigidFit to_rigid_fit_file(const RigidFitRecord& record, const RigidBody& body);
// The record a file holds (the state from com_cam, the orientation, the
// velocities and gravity; what the body adds is derived again when needed).
RigidFitRecord rigid_fit_record_from_file(const formats::RigidFit& file);

nlohmann::json rigid_fit_to_json(const RigidFitRecord& record, const RigidBody& body);
// Validates (finite numbers, unit quaternion, fps > 0) then writes atomically.
void write_rigid_fit(const std::string& path, const RigidFitRecord& record, const RigidBody& body);
// Throws IoError (cannot read) or ValidationError listing every problem.
RigidFitRecord read_rigid_fit(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Every problem of a file, for `flowvid validate` (the format's own validator).
using formats::validate_rigid_fit_file;

// A guess: a rigid_fit file, a capture's truth.json, or any JSON object with
// some of "initial": {"position_cam", "orientation_cam_wxyz",
// "com_velocity_cam", "angular_velocity_cam"}, "gravity_cam" and
// "initial_frame" (default: the capture's first frame). Throws like read_rigid_fit.
struct GuessFile {
    InitialGuess guess;  // time_s still 0: set it from initial_frame
    std::optional<int> initial_frame;
};
GuessFile read_guess_file(const std::string& path);

}  // namespace flowvid::rigid
