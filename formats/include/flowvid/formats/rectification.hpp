#pragma once
// Rectification (rectify.json, format "flowvid.rectification", version 1.0):
// what `flowvid rectify` did to a capture's footage so that gravity points
// straight down the image: the roll angle it removed (from a rigid fit), the
// tilt it left, and the pixel homography it applied (input -> output).
// formats/specs/rectification.md describes every field.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kRectificationFormatName = "flowvid.rectification";
inline constexpr FormatVersion kRectificationFormatVersion{1, 0};

struct RectificationFile {
    std::string fit;                      // the rigid fit file (flowvid.rigid_fit) the angles came from, as given
    double roll_deg = 0.0;                // gravity roll removed, degrees in [-180, 180]
    double tilt_deg_not_corrected = 0.0;  // gravity tilt (pitch) left in the footage, degrees in [-90, 90]
    // Output pixel (homogeneous) = H * input pixel; pixel centres at integers, x right, y down.
    Eigen::Matrix3d homography_output_from_input = Eigen::Matrix3d::Identity();

    bool operator==(const RectificationFile& other) const {
        return fit == other.fit && roll_deg == other.roll_deg && tilt_deg_not_corrected == other.tilt_deg_not_corrected &&
               homography_output_from_input == other.homography_output_from_input;
    }
};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the rectification when valid.
std::optional<RectificationFile> parse_rectification(const nlohmann::json& document, Diagnostics& diagnostics,
                                                     Strictness strictness = Strictness::lenient);
nlohmann::json rectification_to_json(const RectificationFile& rectification);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
RectificationFile read_rectification(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (a NaN is named by its field), then writes atomically.
void write_rectification(const std::string& path, const RectificationFile& rectification);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_rectification_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_rectification(const RectificationFile& rectification);

}  // namespace flowvid::formats
