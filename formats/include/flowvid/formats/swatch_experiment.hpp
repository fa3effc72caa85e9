#pragma once
// Swatch experiment (*.swatch_experiment.json, format "flowvid.swatch_experiment",
// version 1.0): a rectangular swatch of fabric hung by pinned points that
// follow prescribed trajectories, frame by frame -- what `flowvid swatch`
// reads and the Blender add-on writes to calibrate Blender's cloth against
// flowvid. Portable data only: which simulator runs it is not its concern.
// formats/specs/swatch_experiment.md describes every field.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kSwatchExperimentFormatName = "flowvid.swatch_experiment";
inline constexpr FormatVersion kSwatchExperimentFormatVersion{1, 0};
// Bounds a reader accepts (they keep a hostile file from asking for an
// unbounded allocation): 24 hours at 30 fps, and far more pins than a grid has.
inline constexpr int kSwatchExperimentMaxFrames = 2592000;
inline constexpr std::size_t kSwatchExperimentMaxPins = 100000;

// One pinned point of the swatch.
struct SwatchPinTrajectory {
    // Normalised position on the swatch: (0, 0) bottom-left as hung, (1, 1) top-right.
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
    // World position (metres) at every frame: exactly frame_count points.
    std::vector<Eigen::Vector3d> positions_m;

    bool operator==(const SwatchPinTrajectory& other) const {
        return uv == other.uv && positions_m == other.positions_m;
    }
};

struct SwatchExperimentFile {
    std::string name;                // optional label ("static", "waving"); "" when none
    double width_m = 0.30;           // swatch size along u (warp), metres, > 0
    double height_m = 0.30;          // swatch size along v (weft), metres, > 0
    double fps = 30.0;               // frames per second, > 0
    int frame_count = 1;             // frames, >= 1; frame 1 is the start
    std::optional<double> mass_kg;   // > 0: the swatch's total mass; absent: the fabric's own areal density
    std::vector<SwatchPinTrajectory> pins;  // at least one

    bool operator==(const SwatchExperimentFile& other) const {
        return name == other.name && width_m == other.width_m && height_m == other.height_m && fps == other.fps &&
               frame_count == other.frame_count && mass_kg == other.mass_kg && pins == other.pins;
    }
};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the experiment when valid.
std::optional<SwatchExperimentFile> parse_swatch_experiment(const nlohmann::json& document, Diagnostics& diagnostics,
                                                            Strictness strictness = Strictness::lenient);
nlohmann::json swatch_experiment_to_json(const SwatchExperimentFile& experiment);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
SwatchExperimentFile read_swatch_experiment(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (a NaN is named by its field), then writes atomically: on a
// problem the file at `path` is left as it was.
void write_swatch_experiment(const std::string& path, const SwatchExperimentFile& experiment);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_swatch_experiment_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_swatch_experiment(const SwatchExperimentFile& experiment);

}  // namespace flowvid::formats
