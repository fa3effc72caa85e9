#include "flowvid/formats/flowlines.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <map>
#include <string_view>
#include <unordered_set>
#include <ostream>
#include <stdexcept>

namespace flowvid::formats {

// ---- helpers ------------------------------------------------------------------

double polyline_length(const std::vector<Eigen::Vector2d>& points) {
    double length = 0.0;
    for (std::size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
    return length;
}

std::vector<double> cumulative_arc_lengths(const std::vector<Eigen::Vector2d>& points) {
    std::vector<double> lengths(points.size(), 0.0);
    for (std::size_t i = 1; i < points.size(); ++i) lengths[i] = lengths[i - 1] + (points[i] - points[i - 1]).norm();
    return lengths;
}

Eigen::Vector2d point_at_arc_length(const std::vector<Eigen::Vector2d>& points, double s) {
    if (points.empty()) throw std::invalid_argument("point_at_arc_length: empty polyline");
    if (!(s > 0.0)) return points.front();  // also NaN
    double travelled = 0.0;
    for (std::size_t i = 1; i < points.size(); ++i) {
        const double segment = (points[i] - points[i - 1]).norm();
        if (segment > 0.0 && travelled + segment >= s) {
            const double t = (s - travelled) / segment;
            return points[i - 1] + t * (points[i] - points[i - 1]);
        }
        travelled += segment;
    }
    return points.back();
}

std::vector<Eigen::Vector2d> points_at_frame(const FlowLine& line, double frame) {
    if (line.keys.empty()) {
        if (line.points.empty())
            throw std::invalid_argument("points_at_frame: line \"" + line.id + "\" has neither points nor keys");
        return line.points;
    }
    if (!std::isfinite(frame)) throw std::invalid_argument("points_at_frame: frame is not finite");
    const std::size_t count = line.keys.front().points.size();
    for (const FlowLineKey& key : line.keys)
        if (key.points.size() != count)
            throw std::invalid_argument("points_at_frame: keys of line \"" + line.id + "\" differ in point count");
    if (frame <= line.keys.front().frame) return line.keys.front().points;
    if (frame >= line.keys.back().frame) return line.keys.back().points;
    // First key whose frame is > `frame`; the one before it is <= `frame`.
    const auto after = std::upper_bound(line.keys.begin(), line.keys.end(), frame,
                                        [](double f, const FlowLineKey& key) { return f < key.frame; });
    const FlowLineKey& b = *after;
    const FlowLineKey& a = *(after - 1);
    if (frame == a.frame) return a.points;
    const double t = (frame - a.frame) / static_cast<double>(b.frame - a.frame);
    std::vector<Eigen::Vector2d> points(count);
    for (std::size_t i = 0; i < count; ++i) points[i] = (1.0 - t) * a.points[i] + t * b.points[i];
    return points;
}

const FlowLine* find_input_line(const FlowLineSet& set, const std::string& id) {
    for (const FlowLine& line : set.inputs)
        if (line.id == id) return &line;
    return nullptr;
}

// ---- semantic checks ------------------------------------------------------------

namespace {

constexpr double kMaxFlowLineCoordinatePixels = 1e6;

std::string join_leaf(const std::string& a, const std::string& b) {
    if (a.empty()) return b;
    if (b.empty()) return a;
    return a + "/" + b;
}

// Checks one polyline (a fixed line or one key). `leaf` is its field relative
// to the line, e.g. "points" or "keys/3/points".
void check_polyline(const std::vector<Eigen::Vector2d>& points, const FlowLineSet& set, Diagnostics& diag,
                    const std::function<std::string(const std::string&)>& where, const std::string& leaf) {
    if (points.size() < 2) {
        diag.error(where(leaf),
                   "a flow line needs at least 2 points, found " + std::to_string(points.size()),
                   "draw the line from where the flow starts to where it ends (two or more points)");
        return;
    }
    std::size_t bad = 0, first_bad = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (points[i].allFinite()) continue;
        if (bad++ == 0) first_bad = i;
    }
    if (bad > 0) {
        diag.error(where(join_leaf(leaf, std::to_string(first_bad))),
                   std::to_string(bad) + " point(s) are not finite (NaN or infinity), the first is point " +
                       std::to_string(first_bad),
                   "give every point finite pixel coordinates");
        return;
    }
    // Finite but absurd coordinates (1e308) would overflow every length and
    // area computed from them; no frame is a million pixels across.
    std::size_t huge = 0, first_huge = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (points[i].cwiseAbs().maxCoeff() <= kMaxFlowLineCoordinatePixels) continue;
        if (huge++ == 0) first_huge = i;
    }
    if (huge > 0) {
        diag.error(where(join_leaf(leaf, std::to_string(first_huge))),
                   std::to_string(huge) + " point(s) lie more than 1e6 pixels from the image origin, the first is point " +
                       std::to_string(first_huge),
                   "give pixel coordinates of the video frames (x right, y down)");
        return;
    }
    if (polyline_length(points) == 0.0) {
        diag.error(where(leaf), "zero-length line: all its points coincide",
                   "draw the line with at least two distinct points along the flow");
        return;
    }
    std::size_t repeats = 0, first_repeat = 0;
    for (std::size_t i = 1; i < points.size(); ++i) {
        if (points[i] != points[i - 1]) continue;
        if (repeats++ == 0) first_repeat = i;
    }
    if (repeats > 0)
        diag.warning(where(join_leaf(leaf, std::to_string(first_repeat))),
                     std::to_string(repeats) + " point(s) repeat the point before them (first: point " +
                         std::to_string(first_repeat) + "); the flow direction there is undefined",
                     "remove the repeated points");
    // Lines may start or end outside the frame (flow enters from off-screen),
    // but one image size beyond the border is almost certainly a mistake
    // (wrong units, wrong image size, a stray point).
    const double w = set.width, h = set.height;
    std::size_t far = 0, first_far = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector2d& p = points[i];
        if (p.x() >= -w && p.x() <= 2.0 * w && p.y() >= -h && p.y() <= 2.0 * h) continue;
        if (far++ == 0) first_far = i;
    }
    if (far > 0 && set.width > 0 && set.height > 0) {
        const Eigen::Vector2d& p = points[first_far];
        diag.warning(where(join_leaf(leaf, std::to_string(first_far))),
                     std::to_string(far) + " point(s) lie far outside the " + std::to_string(set.width) + "x" +
                         std::to_string(set.height) + " image (first: point " + std::to_string(first_far) + " at (" +
                         std::to_string(p.x()) + ", " + std::to_string(p.y()) + "))",
                     "check the image size and that coordinates are pixels (x right, y down)");
    }
}

void check_line_geometry(const FlowLine& line, bool output, const FlowLineSet& set, Diagnostics& diag,
                         const std::function<std::string(const std::string&)>& where) {
    const bool has_points = !line.points.empty();
    const bool has_keys = !line.keys.empty();
    if (has_points && has_keys) {
        diag.error(where(""), "has both \"points\" and \"keys\"",
                   "keep \"points\" for a fixed line or \"keys\" for a line that moves, not both");
        return;
    }
    if (!has_points && !has_keys) {
        diag.error(where("points"), "the line has no points",
                   output ? "add \"points\" (a fixed line) or \"keys\" (a line that moves)" : "add \"points\"");
        return;
    }
    if (has_keys && !output) {
        diag.error(where("keys"), "an input line cannot vary over time",
                   "input lines follow the flow in the input video and are fixed: give \"points\"");
        return;
    }
    if (has_points) {
        check_polyline(line.points, set, diag, where, "points");
        return;
    }
    const std::size_t count = line.keys.front().points.size();
    for (std::size_t k = 0; k < line.keys.size(); ++k) {
        const FlowLineKey& key = line.keys[k];
        const std::string key_leaf = "keys/" + std::to_string(k);
        if (k > 0 && key.frame <= line.keys[k - 1].frame)
            diag.error(where(key_leaf + "/frame"),
                       "frame " + std::to_string(key.frame) + " does not come after the previous key's frame " +
                           std::to_string(line.keys[k - 1].frame),
                       "list keys in strictly increasing frame order, one key per frame");
        if (k > 0 && key.points.size() != count)
            diag.error(where(key_leaf + "/points"),
                       "has " + std::to_string(key.points.size()) + " points but key 0 has " + std::to_string(count),
                       "give every key of a line the same number of points (they are interpolated point by point)");
        check_polyline(key.points, set, diag, where, key_leaf + "/points");
    }
}

// JSON text must be UTF-8; a Latin-1 title or id from an SVG would make the
// JSON writer fail half-way, so it is refused here with its field.
bool is_valid_utf8(const std::string& text) {
    std::size_t i = 0;
    while (i < text.size()) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        std::size_t extra = 0;
        std::uint32_t code = 0;
        if (c < 0x80) extra = 0, code = c;
        else if ((c & 0xE0) == 0xC0) extra = 1, code = c & 0x1F;
        else if ((c & 0xF0) == 0xE0) extra = 2, code = c & 0x0F;
        else if ((c & 0xF8) == 0xF0) extra = 3, code = c & 0x07;
        else return false;
        if (i + extra >= text.size()) return false;  // truncated sequence
        for (std::size_t k = 1; k <= extra; ++k) {
            const unsigned char next = static_cast<unsigned char>(text[i + k]);
            if ((next & 0xC0) != 0x80) return false;
            code = (code << 6) | (next & 0x3F);
        }
        static const std::uint32_t kMinimum[4] = {0, 0x80, 0x800, 0x10000};  // no overlong forms
        if (code < kMinimum[extra] || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return false;
        i += extra + 1;
    }
    return true;
}

std::string list_ids(const std::vector<FlowLine>& lines) {
    std::string text;
    std::size_t shown = 0;
    for (const FlowLine& line : lines) {
        if (line.id.empty()) continue;
        if (shown == 8) {
            text += ", ...";
            break;
        }
        text += (shown++ == 0 ? "" : ", ") + line.id;
    }
    return text;
}

}  // namespace

namespace detail {

void check_flowline_set(const FlowLineSet& set, Diagnostics& diag, const FlowLineNamer& name,
                        const std::string& image_field, const std::vector<bool>* inputs_broken,
                        const std::vector<bool>* outputs_broken) {
    if (set.width < 1 || set.height < 1)
        diag.error(image_field,
                   "image size " + std::to_string(set.width) + "x" + std::to_string(set.height) + " is not positive",
                   "give the width and height of the video frames in pixels");
    if (set.inputs.empty())
        diag.error(name(false, kAllLines, ""), "no input flow lines",
                   "draw at least one input line along the flow in the input video");

    const std::string utf8_fix = "save the file as UTF-8 (or use plain ASCII)";
    if (!is_valid_utf8(set.description))
        diag.error(name(false, kAllLines, "description"), "the description is not valid UTF-8 text", utf8_fix);

    std::map<std::string, std::string> first_use;  // id -> where it was first used
    auto check_lines = [&](const std::vector<FlowLine>& lines, bool output, const std::vector<bool>* broken) {
        for (std::size_t i = 0; i < lines.size(); ++i) {
            const FlowLine& line = lines[i];
            auto where = [&](const std::string& leaf) { return name(output, i, leaf); };
            if (line.id.empty()) {
                diag.error(where("id"), "empty id", "give every line a unique id, e.g. \"in-1\" or \"out-1\"");
            } else if (!is_valid_utf8(line.id)) {
                diag.error(where("id"), "the id is not valid UTF-8 text", utf8_fix);
            } else if (std::any_of(line.id.begin(), line.id.end(),
                                   [](char c) { return static_cast<unsigned char>(c) <= ' ' || c == 0x7F; })) {
                // SVG editors and data-from references cannot carry spaces reliably.
                diag.error(where("id"), "the id \"" + line.id + "\" contains spaces or control characters",
                           "use letters, digits, '-' and '_', e.g. \"in-1\"");
            } else {
                auto [it, inserted] = first_use.emplace(line.id, where("id"));
                if (!inserted)
                    diag.error(where("id"), "id \"" + line.id + "\" is already used by " + it->second,
                               "give every line (inputs and outputs together) its own id");
            }
            if (!(broken && i < broken->size() && (*broken)[i])) check_line_geometry(line, output, set, diag, where);
        }
    };
    check_lines(set.inputs, false, inputs_broken);
    check_lines(set.outputs, true, outputs_broken);

    for (std::size_t i = 0; i < set.inputs.size(); ++i) {
        if (!set.inputs[i].from.empty())
            diag.error(name(false, i, "from"), "an input line names a source line",
                       "remove \"from\": only output lines say which input line's texture they carry");
        if (set.inputs[i].time_offset_frames != 0)
            diag.error(name(false, i, "time_offset_frames"), "an input line has a time offset",
                       "remove \"time_offset_frames\": only output lines are shown at an offset in time");
    }
    // Looked up by hash: drawings with many lines must validate in linear time.
    std::unordered_set<std::string_view> input_ids, output_ids;
    for (const FlowLine& line : set.inputs) input_ids.insert(line.id);
    for (const FlowLine& line : set.outputs) output_ids.insert(line.id);
    for (std::size_t i = 0; i < set.outputs.size(); ++i) {
        const FlowLine& line = set.outputs[i];
        if (!is_valid_utf8(line.from)) {
            diag.error(name(true, i, "from"), "not valid UTF-8 text", utf8_fix);
        } else if (line.from.empty()) {
            diag.error(name(true, i, "from"), "the output line does not name its input line",
                       "set it to the id of the input line whose texture this line carries (one of: " +
                           list_ids(set.inputs) + ")");
        } else if (!input_ids.count(line.from)) {
            const bool is_output = output_ids.count(line.from) > 0;
            diag.error(name(true, i, "from"),
                       "\"" + line.from + "\" is " + (is_output ? "an output line" : "not the id of any input line"),
                       "name one of the input lines: " + list_ids(set.inputs));
        }
    }
}

}  // namespace detail

namespace {

std::string json_line_name(bool output, std::size_t index, const std::string& leaf) {
    if (index == detail::kAllLines) return leaf == "description" ? "/description" : output ? "/outputs" : "/inputs";
    std::string pointer = std::string(output ? "/outputs/" : "/inputs/") + std::to_string(index);
    if (!leaf.empty()) pointer += "/" + leaf;
    return pointer;
}

// Reads [[x, y], ...]; reports every bad element. Returns false on any error.
bool parse_points(const JsonView& line, const std::string& key, std::vector<Eigen::Vector2d>& out) {
    std::optional<JsonView> list = line.array(key);
    if (!list) return false;
    Diagnostics& diag = line.diagnostics();
    bool ok = true;
    out.clear();
    out.reserve(list->size());
    const NumberRange any_finite{-INFINITY, INFINITY, false, "px"};
    for (std::size_t i = 0; i < list->size(); ++i) {
        JsonView point = list->element(i);
        if (!point.json().is_array() || point.size() != 2) {
            diag.error(point.pointer(),
                       std::string("expected a point [x, y], found ") +
                           (point.json().is_array() ? "an array of " + std::to_string(point.size()) + " values"
                                                    : point.json().type_name()),
                       "write each point as [x, y] in pixels");
            ok = false;
            continue;
        }
        std::optional<double> x = point.element(0).as_number(any_finite);
        std::optional<double> y = point.element(1).as_number(any_finite);
        if (!x || !y) {
            ok = false;
            continue;
        }
        out.emplace_back(*x, *y);
    }
    return ok;
}

// Parses one line object; returns false when its geometry could not be read
// (problems already reported), so the semantic checks skip it.
bool parse_line(const JsonView& item, bool output, FlowLine& line) {
    Diagnostics& diag = item.diagnostics();
    if (!item.json().is_object()) {
        diag.error(item.pointer(), std::string("expected a line object, found ") + item.json().type_name(),
                   output ? "write {\"id\": ..., \"from\": ..., \"points\": [[x, y], ...]}"
                          : "write {\"id\": ..., \"points\": [[x, y], ...]}");
        return false;
    }
    // Inputs accept the same keys so that a misplaced "from" or "keys" gets a
    // specific message from the semantic checks rather than "unknown key".
    item.check_known_keys({"id", "from", "time_offset_frames", "points", "keys"});
    bool ok = true;
    if (std::optional<std::string> id = item.string("id")) line.id = *id;
    else line.id.clear();
    // A missing or empty "from" is reported by the semantic check, with the list of inputs.
    if (std::optional<std::string> from = item.string("from", false)) line.from = *from;
    if (item.has("time_offset_frames")) {
        std::optional<std::int64_t> offset = item.integer("time_offset_frames", -1000000000, 1000000000);
        if (!offset) return false;
        line.time_offset_frames = static_cast<int>(*offset);
    }
    const bool has_points = item.has("points");
    const bool has_keys = item.has("keys");
    if (has_points && has_keys) {
        diag.error(item.pointer(), "has both \"points\" and \"keys\"",
                   "keep \"points\" for a fixed line or \"keys\" for a line that moves, not both");
        return false;
    }
    if (!has_keys) {
        if (!has_points) {
            diag.error(json_pointer_child(item.pointer(), "points"), "missing",
                       output ? "add \"points\": [[x, y], ...] (or \"keys\" for a line that moves)"
                              : "add \"points\": [[x, y], ...] in pixels, in the direction of flow");
            return false;
        }
        return parse_points(item, "points", line.points);
    }
    std::optional<JsonView> keys = item.array("keys");
    if (!keys) return false;
    if (keys->size() == 0) {
        diag.error(keys->pointer(), "no keys", "add {\"frame\": f, \"points\": [[x, y], ...]} per key frame");
        return false;
    }
    for (std::size_t k = 0; k < keys->size(); ++k) {
        JsonView key_view = keys->element(k);
        if (!key_view.json().is_object()) {
            diag.error(key_view.pointer(), std::string("expected a key object, found ") + key_view.json().type_name(),
                       "write {\"frame\": f, \"points\": [[x, y], ...]}");
            ok = false;
            continue;
        }
        key_view.check_known_keys({"frame", "points"});
        FlowLineKey key;
        std::optional<std::int64_t> frame = key_view.integer("frame", -1000000000, 1000000000);
        if (frame) key.frame = static_cast<int>(*frame);
        else ok = false;
        if (!parse_points(key_view, "points", key.points)) ok = false;
        line.keys.push_back(std::move(key));
    }
    return ok;
}

}  // namespace

std::optional<FlowLineSet> parse_flowline_set(const nlohmann::json& document, Diagnostics& diagnostics,
                                              Strictness strictness) {
    JsonView root(document, "", diagnostics, strictness);
    if (!check_format_header(root, kFlowLinesFormatName, kFlowLinesFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "description", "image", "inputs", "outputs"});

    FlowLineSet set;
    set.description = root.string("description", false).value_or("");
    bool image_ok = false;
    if (std::optional<JsonView> image = root.object("image")) {
        image->check_known_keys({"width", "height", "pixel_convention"});
        std::optional<std::int64_t> width = image->integer("width", 1, 1000000);
        std::optional<std::int64_t> height = image->integer("height", 1, 1000000);
        if (std::optional<std::string> convention = image->string("pixel_convention")) {
            if (*convention != kFlowLinesPixelConvention)
                diagnostics.error("/image/pixel_convention", "unknown pixel convention \"" + *convention + "\"",
                                  "write \"opencv\" and give coordinates with x right, y down, the top-left "
                                  "pixel's centre at (0, 0)");
        }
        if (width && height) {
            set.width = static_cast<int>(*width);
            set.height = static_cast<int>(*height);
            image_ok = true;
        }
    }

    std::vector<bool> inputs_broken, outputs_broken;
    auto parse_lines = [&](const char* key, bool output, bool required, std::vector<FlowLine>& lines,
                           std::vector<bool>& broken) {
        std::optional<JsonView> list = root.array(key, required);
        if (!list) return false;
        for (std::size_t i = 0; i < list->size(); ++i) {
            FlowLine line;
            broken.push_back(!parse_line(list->element(i), output, line));
            lines.push_back(std::move(line));
        }
        return true;
    };
    const bool inputs_ok = parse_lines("inputs", false, true, set.inputs, inputs_broken);
    parse_lines("outputs", true, false, set.outputs, outputs_broken);

    if (inputs_ok && image_ok) {
        detail::check_flowline_set(set, diagnostics, json_line_name, "/image", &inputs_broken, &outputs_broken);
    } else if (inputs_ok) {
        // Without an image size the bounds checks are meaningless; the rest still applies.
        FlowLineSet sized = set;
        sized.width = sized.height = 0;
        Diagnostics local(diagnostics.file());
        detail::check_flowline_set(sized, local, json_line_name, "/image", &inputs_broken, &outputs_broken);
        for (const Problem& problem : local.problems())
            if (problem.field != "/image") diagnostics.merge({problem});
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return set;
}

namespace {

// Integral coordinates are written as JSON integers ("200", not "200.0") so
// hand-written files and written files look alike; -0.0 stays a double to keep
// its sign bit, so reading back is bit-exact.
nlohmann::json number_json(double value) {
    if (std::isfinite(value) && value == std::floor(value) && std::fabs(value) < 9007199254740992.0 &&
        !(value == 0.0 && std::signbit(value)))
        return nlohmann::json(static_cast<std::int64_t>(value));
    return nlohmann::json(value);
}

nlohmann::json points_json(const std::vector<Eigen::Vector2d>& points) {
    nlohmann::json list = nlohmann::json::array();
    for (const Eigen::Vector2d& p : points) list.push_back({number_json(p.x()), number_json(p.y())});
    return list;
}

nlohmann::json line_json(const FlowLine& line, bool output) {
    nlohmann::json entry = {{"id", line.id}};
    if (output) entry["from"] = line.from;
    if (output && line.time_offset_frames != 0) entry["time_offset_frames"] = line.time_offset_frames;
    if (line.keys.empty()) {
        entry["points"] = points_json(line.points);
    } else {
        nlohmann::json keys = nlohmann::json::array();
        for (const FlowLineKey& key : line.keys) keys.push_back({{"frame", key.frame}, {"points", points_json(key.points)}});
        entry["keys"] = keys;
    }
    return entry;
}

std::string points_text(const std::vector<Eigen::Vector2d>& points) {
    std::string text = "[";
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (i) text += ", ";
        text += '[';
        text += number_json(points[i].x()).dump();
        text += ", ";
        text += number_json(points[i].y()).dump();
        text += ']';
    }
    return text + "]";
}

std::string line_text(const FlowLine& line, bool output) {
    std::string text = "{\"id\": " + nlohmann::json(line.id).dump();
    if (output) text += ", \"from\": " + nlohmann::json(line.from).dump();
    if (output && line.time_offset_frames != 0) text += ", \"time_offset_frames\": " + std::to_string(line.time_offset_frames);
    if (line.keys.empty()) return text + ", \"points\": " + points_text(line.points) + "}";
    text += ", \"keys\": [\n";
    for (std::size_t k = 0; k < line.keys.size(); ++k) {
        text += "      {\"frame\": " + std::to_string(line.keys[k].frame) +
                ", \"points\": " + points_text(line.keys[k].points) + "}";
        text += k + 1 < line.keys.size() ? ",\n" : "\n";
    }
    return text + "    ]}";
}

}  // namespace

nlohmann::json flowline_set_to_json(const FlowLineSet& set) {
    nlohmann::json document = nlohmann::json::object();
    document["format"] = kFlowLinesFormatName;
    document["version"] = kFlowLinesFormatVersion.to_string();
    if (!set.description.empty()) document["description"] = set.description;
    document["image"] = {{"width", set.width}, {"height", set.height}, {"pixel_convention", kFlowLinesPixelConvention}};
    document["inputs"] = nlohmann::json::array();
    for (const FlowLine& line : set.inputs) document["inputs"].push_back(line_json(line, false));
    document["outputs"] = nlohmann::json::array();
    for (const FlowLine& line : set.outputs) document["outputs"].push_back(line_json(line, true));
    return document;
}

// dump_json would put every coordinate on its own line; one polyline per line
// keeps files readable and diffable. The keys come in a fixed, logical order.
std::string flowline_set_to_text(const FlowLineSet& set) {
    std::string text = "{\n";
    text += "  \"format\": " + nlohmann::json(kFlowLinesFormatName).dump() + ",\n";
    text += "  \"version\": " + nlohmann::json(kFlowLinesFormatVersion.to_string()).dump() + ",\n";
    if (!set.description.empty()) text += "  \"description\": " + nlohmann::json(set.description).dump() + ",\n";
    text += "  \"image\": {\"width\": " + std::to_string(set.width) + ", \"height\": " + std::to_string(set.height) +
            ", \"pixel_convention\": " + nlohmann::json(kFlowLinesPixelConvention).dump() + "},\n";
    auto lines = [&](const char* key, const std::vector<FlowLine>& list, bool output, bool last) {
        text += std::string("  \"") + key + "\": [";
        if (list.empty()) {
            text += "]";
        } else {
            text += "\n";
            for (std::size_t i = 0; i < list.size(); ++i)
                text += "    " + line_text(list[i], output) + (i + 1 < list.size() ? ",\n" : "\n");
            text += "  ]";
        }
        text += last ? "\n" : ",\n";
    };
    lines("inputs", set.inputs, false, false);
    lines("outputs", set.outputs, true, true);
    return text + "}\n";
}

void validate_flowline_set(const FlowLineSet& set, Diagnostics& diagnostics) {
    detail::check_flowline_set(set, diagnostics, json_line_name, "/image");
}

FlowLineSet read_flowline_set(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<FlowLineSet>(path, parse_flowline_set, warnings);
}

void write_flowline_set(const std::string& path, const FlowLineSet& set) {
    Diagnostics diagnostics(path);
    // Checked on the values first: NaN would turn into null in JSON.
    validate_flowline_set(set, diagnostics);
    diagnostics.throw_if_errors();
    const std::string text = flowline_set_to_text(set);
    // Validate exactly what will be written with the reader's own rules.
    Diagnostics written(path);
    if (std::optional<nlohmann::json> document = parse_json_text(text, written))
        parse_flowline_set(*document, written, Strictness::strict);
    written.throw_if_errors();
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

std::vector<Problem> validate_flowline_set_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    const std::optional<std::string> read = read_text_reporting(path, diagnostics);
    if (!read) return diagnostics.problems();
    const std::string& text = *read;
    std::string extension = path.size() >= 4 ? path.substr(path.size() - 4) : std::string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    // SVG by name or by content (a JSON document never starts with '<').
    const std::size_t first = text.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
    if (extension == ".svg" || (first != std::string::npos && text[first] == '<')) {
        parse_flowlines_svg(text, diagnostics);
        return diagnostics.problems();
    }
    if (std::optional<nlohmann::json> document = parse_json_text(text, diagnostics))
        parse_flowline_set(*document, diagnostics, strictness);
    return diagnostics.problems();
}

nlohmann::json summarize_flowline_set(const FlowLineSet& set) {
    nlohmann::json summary = {{"format", kFlowLinesFormatName},
                              {"width", set.width},
                              {"height", set.height},
                              {"pixel_convention", kFlowLinesPixelConvention}};
    if (!set.description.empty()) summary["description"] = set.description;
    auto describe = [](const FlowLine& line, bool output) {
        nlohmann::json entry = {{"id", line.id}};
        if (output) entry["from"] = line.from;
        const std::vector<Eigen::Vector2d>& shape = line.keys.empty() ? line.points : line.keys.front().points;
        entry["points"] = shape.size();
        entry["length_px"] = polyline_length(shape);
        if (!line.keys.empty()) {
            entry["keys"] = line.keys.size();
            entry["frames"] = {line.keys.front().frame, line.keys.back().frame};
        }
        return entry;
    };
    nlohmann::json inputs = nlohmann::json::array(), outputs = nlohmann::json::array();
    std::size_t time_varying = 0;
    for (const FlowLine& line : set.inputs) inputs.push_back(describe(line, false));
    for (const FlowLine& line : set.outputs) {
        outputs.push_back(describe(line, true));
        if (line.is_time_varying()) ++time_varying;
    }
    summary["input_count"] = set.inputs.size();
    summary["output_count"] = set.outputs.size();
    summary["time_varying_outputs"] = time_varying;
    summary["inputs"] = inputs;
    summary["outputs"] = outputs;
    return summary;
}

}  // namespace flowvid::formats
