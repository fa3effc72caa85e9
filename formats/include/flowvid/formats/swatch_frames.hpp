#pragma once
// Swatch frames (*.swatch_frames.json, format "flowvid.swatch_frames",
// version 1.0): the simulated frames of a swatch experiment
// (flowvid.swatch_experiment) on a rows x cols grid of vertices, as
// `flowvid swatch` writes them and the Blender add-on reads them. A run that
// stopped early is written too; its status says so.
// formats/specs/swatch_frames.md describes every field.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kSwatchFramesFormatName = "flowvid.swatch_frames";
inline constexpr FormatVersion kSwatchFramesFormatVersion{1, 0};
// Largest grid side a reader accepts.
inline constexpr int kSwatchFramesMaxGridSide = 4096;

// How the run ended. ok: every frame; the others stopped early (the frames
// so far are kept, and a coordinate that was not finite is stored as null).
inline constexpr const char* kSwatchFramesStatuses[] = {"ok", "blew_up", "step_underflow", "cancelled"};

struct SwatchFramesFile {
    std::string status = "ok";         // one of kSwatchFramesStatuses
    std::string reason;                // why the run stopped ("" when ok)
    bool equilibrium_converged = true; // whether the start's static equilibrium converged
    int rows = 2;                      // grid rows (>= 2); row 0 at v = 0 (the bottom as hung)
    int cols = 2;                      // grid columns (>= 2); column 0 at u = 0
    std::vector<int> pinned_vertices;  // vertex r * cols + c of each experiment pin, in the experiment's order
    double wall_time_s = 0.0;          // the simulation's wall-clock time, seconds, >= 0
    // frames[k] holds rows * cols world positions (metres), vertex r * cols + c.
    // Non-finite coordinates (NaN) only when status is not "ok".
    std::vector<std::vector<Eigen::Vector3d>> frames_m;

    bool ok() const { return status == "ok"; }
    bool operator==(const SwatchFramesFile& other) const {
        return status == other.status && reason == other.reason &&
               equilibrium_converged == other.equilibrium_converged && rows == other.rows && cols == other.cols &&
               pinned_vertices == other.pinned_vertices && wall_time_s == other.wall_time_s &&
               frames_m == other.frames_m;
    }
};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the frames when valid.
std::optional<SwatchFramesFile> parse_swatch_frames(const nlohmann::json& document, Diagnostics& diagnostics,
                                                    Strictness strictness = Strictness::lenient);
nlohmann::json swatch_frames_to_json(const SwatchFramesFile& frames);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
SwatchFramesFile read_swatch_frames(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (a NaN in an "ok" run is named by its field), then writes
// atomically: on a problem the file at `path` is left as it was.
void write_swatch_frames(const std::string& path, const SwatchFramesFile& frames);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_swatch_frames_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_swatch_frames(const SwatchFramesFile& frames);

}  // namespace flowvid::formats
