#pragma once
// Flow-line set (*.flowlines.json): the artist's input flow lines drawn over a
// video and the edited output lines that say where each input's texture goes
// (thesis chapter 3.2-3.4). Format name "flowvid.flowlines", version 1.0; see
// formats/specs/flowlines.md. Also reads and writes the SVG form artists draw
// in (capture.md, "Flow lines in SVG").
//
// Coordinates are image pixels in the OpenCV convention: x right, y down, the
// centre of the top-left pixel at (0, 0). A line's point order is the direction
// of flow.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kFlowLinesFormatName = "flowvid.flowlines";
inline constexpr FormatVersion kFlowLinesFormatVersion{1, 1};
inline constexpr const char* kFlowLinesPixelConvention = "opencv";

// The polyline of a time-varying line at one output frame.
struct FlowLineKey {
    int frame = 0;                               // output frame number, strictly increasing within a line
    std::vector<Eigen::Vector2d> points;         // #P polyline, pixels; same #P in every key of a line
    bool operator==(const FlowLineKey&) const = default;
};

// One flow line. Either `points` (a fixed line) or `keys` (a line that moves,
// e.g. projected from a particle simulation: outputs only) is non-empty.
struct FlowLine {
    std::string id;                              // unique among inputs and outputs
    std::vector<Eigen::Vector2d> points;         // #P polyline, pixels, in flow direction
    std::vector<FlowLineKey> keys;               // time-varying line (output lines only)
    std::string from;                            // output lines: id of the input line whose texture it carries
    // Output lines: output frame t shows the particles the infinite sequence
    // has at frame t + this (lines carrying one input side by side then show
    // different particles). 0 for drawn lines.
    int time_offset_frames = 0;
    bool is_time_varying() const { return !keys.empty(); }
    bool operator==(const FlowLine&) const = default;
};

struct FlowLineSet {
    int width = 0;                               // image size, pixels
    int height = 0;
    std::string description;                     // optional, free text
    std::vector<FlowLine> inputs;                // lines along the flow in the input video
    std::vector<FlowLine> outputs;               // edited lines, each naming its input in `from`
    bool operator==(const FlowLineSet&) const = default;
};

// ---- helpers for the algorithms -------------------------------------------

// The line's polyline at `frame`: a fixed line's points; for a keyed line the
// points interpolated linearly between the two surrounding keys, clamped to
// the first/last key outside their range. Throws std::invalid_argument for a
// line with neither points nor keys, keys of different point counts, or a
// non-finite frame (a validated set never has the first two).
std::vector<Eigen::Vector2d> points_at_frame(const FlowLine& line, double frame);

// Total length of a polyline, pixels (0 for fewer than two points).
double polyline_length(const std::vector<Eigen::Vector2d>& points);
// Arc length from the first point to each point, pixels: #P values, first 0.
std::vector<double> cumulative_arc_lengths(const std::vector<Eigen::Vector2d>& points);
// The point at arc length `s` pixels from the start, clamped to [0, length].
// Requires at least one point.
Eigen::Vector2d point_at_arc_length(const std::vector<Eigen::Vector2d>& points, double s);

// The input line with this id, or nullptr.
const FlowLine* find_input_line(const FlowLineSet& set, const std::string& id);

// ---- JSON file --------------------------------------------------------------

// Validates a parsed document and, when valid, returns the set. Every problem
// is added to `diagnostics` (errors and warnings).
std::optional<FlowLineSet> parse_flowline_set(const nlohmann::json& document, Diagnostics& diagnostics,
                                              Strictness strictness = Strictness::lenient);
nlohmann::json flowline_set_to_json(const FlowLineSet& set);
// The exact text write_flowline_set writes: the JSON of flowline_set_to_json
// laid out with one polyline per line.
std::string flowline_set_to_text(const FlowLineSet& set);

// Checks a set held in memory (finite coordinates, >= 2 points, distinct ids,
// `from` naming an input, ...) with the rules the reader applies. Problems are
// named by JSON pointer ("/outputs/2/from").
void validate_flowline_set(const FlowLineSet& set, Diagnostics& diagnostics);

// Reads and validates a file; throws ValidationError (every problem) or IoError.
// Warnings (newer minor version, unknown keys, points far outside the image)
// go to `warnings` when given.
FlowLineSet read_flowline_set(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates, then writes atomically. Throws ValidationError if the set is not
// valid (e.g. NaN, duplicate ids), leaving any previous file untouched.
void write_flowline_set(const std::string& path, const FlowLineSet& set);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
// A path ending in ".svg", or text starting with '<', is checked as an SVG
// drawing (import rules).
std::vector<Problem> validate_flowline_set_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_flowline_set(const FlowLineSet& set);

// ---- SVG drawing --------------------------------------------------------------

// Imports flow lines drawn in SVG (formats/specs/flowlines.md, "SVG import"):
// paths, polylines and lines in the group id="input" and id="output", curves
// flattened to kFlowLinesSvgTolerancePx, transforms and viewBox applied.
// Problems name `file_name` and the element (id and line).
inline constexpr double kFlowLinesSvgTolerancePx = 0.1;
std::optional<FlowLineSet> parse_flowlines_svg(const std::string& svg_text, const std::string& file_name,
                                               Diagnostics& diagnostics);
// The same, naming diagnostics.file() in problems.
std::optional<FlowLineSet> parse_flowlines_svg(const std::string& svg_text, Diagnostics& diagnostics);
// Reads an SVG file; throws ValidationError (every problem) or IoError.
FlowLineSet import_flowlines_svg(const std::string& path, std::vector<Problem>* warnings = nullptr);

// An SVG an artist can keep drawing in: groups "input" and "output", one
// `<path d="M x,y L ...">` per line with its id and data-from. Coordinates are
// written with enough digits to read back bit-exactly. A time-varying line is
// written as its first key (noted in the path's <desc>). When
// `background_href` is given, an <image> of the frame is placed under the lines.
std::string flowline_set_to_svg(const FlowLineSet& set, const std::string& background_href = {});
// Validates, then writes atomically (ValidationError leaves any old file intact).
void write_flowlines_svg(const std::string& path, const FlowLineSet& set, const std::string& background_href = {});

namespace detail {
// Names a line (or a field of it) in problems: JSON pointers for files, SVG
// elements for drawings. `output` selects outputs, `index` the line, `leaf`
// the field ("points", "keys/0/points", "from", ... possibly empty). `index`
// kAllLines names the whole list of inputs or outputs.
inline constexpr std::size_t kAllLines = static_cast<std::size_t>(-1);
using FlowLineNamer = std::function<std::string(bool output, std::size_t index, const std::string& leaf)>;
// The semantic checks shared by the JSON reader, the writers and the SVG importer.
// `image_field` names the image size; lines flagged in `inputs_broken` /
// `outputs_broken` (already reported while parsing) skip the geometry checks
// but still count for ids and `from`.
void check_flowline_set(const FlowLineSet& set, Diagnostics& diagnostics, const FlowLineNamer& name,
                        const std::string& image_field, const std::vector<bool>* inputs_broken = nullptr,
                        const std::vector<bool>* outputs_broken = nullptr);
}  // namespace detail

}  // namespace flowvid::formats
