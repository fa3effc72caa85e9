#include "flowvid/formats/swatch_frames.hpp"

#include "json_extras.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace flowvid::formats {

namespace {

bool known_status(const std::string& status) {
    for (const char* known : kSwatchFramesStatuses)
        if (status == known) return true;
    return false;
}

}  // namespace

std::optional<SwatchFramesFile> parse_swatch_frames(const nlohmann::json& document, Diagnostics& diagnostics,
                                                    Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    // Files of flowvid swatch's first release had no header: the fix names the one to add.
    if (!detail::check_header_first_files_lacked(root, kSwatchFramesFormatName, kSwatchFramesFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "status", "reason", "equilibrium_converged", "grid", "pinned_vertices",
                           "wall_time_s", "frames"});
    SwatchFramesFile out;
    if (const std::optional<std::string> status = root.string("status")) {
        if (known_status(*status))
            out.status = *status;
        else
            diagnostics.error("/status", "\"" + status->substr(0, 40) + "\" is not a status of a swatch run",
                              "write \"ok\", \"blew_up\", \"step_underflow\" or \"cancelled\"");
    }
    out.reason = root.string("reason").value_or("");
    out.equilibrium_converged = root.boolean("equilibrium_converged").value_or(false);
    out.wall_time_s = root.number("wall_time_s", NumberRange::non_negative("s")).value_or(0.0);
    bool grid_ok = false;
    if (const std::optional<JsonView> grid = root.array("grid")) {
        if (grid->size() != 2) {
            diagnostics.error(grid->pointer(), "expected [rows, cols], found " + grid->json().dump().substr(0, 40),
                              "write the grid as two integers, e.g. [12, 12]");
        } else {
            grid_ok = true;
            int* sides[] = {&out.rows, &out.cols};
            for (std::size_t k = 0; k < 2; ++k) {
                const JsonView side = grid->element(k);
                const std::optional<double> v = side.as_number(NumberRange::closed(2.0, kSwatchFramesMaxGridSide, "vertices"));
                if (v && *v == std::floor(*v)) {
                    *sides[k] = static_cast<int>(*v);
                } else {
                    if (v) diagnostics.error(side.pointer(), "expected an integer", "write the grid as two integers, e.g. [12, 12]");
                    grid_ok = false;
                }
            }
        }
    }
    const std::int64_t vertex_count = static_cast<std::int64_t>(out.rows) * out.cols;
    if (const std::optional<JsonView> pinned = root.array("pinned_vertices")) {
        // Without a valid grid the index is still bounded by the largest grid, so it fits an int.
        constexpr double largest_grid_last = static_cast<double>(kSwatchFramesMaxGridSide) * kSwatchFramesMaxGridSide - 1.0;
        for (std::size_t i = 0; i < pinned->size(); ++i) {
            const JsonView vertex = pinned->element(i);
            const double last = grid_ok ? static_cast<double>(vertex_count - 1) : largest_grid_last;
            const std::optional<double> v = vertex.as_number(NumberRange::closed(0.0, last, "(a vertex r * cols + c of the grid)"));
            if (v && *v == std::floor(*v))
                out.pinned_vertices.push_back(static_cast<int>(*v));
            else if (v)
                diagnostics.error(vertex.pointer(), "expected an integer vertex index", "write the vertex r * cols + c");
        }
    }
    if (const std::optional<JsonView> frames = root.array("frames")) {
        if (frames->size() == 0 && out.ok())
            diagnostics.error(frames->pointer(), "a run that ended \"ok\" has at least one frame",
                              "write every simulated frame (frame 1 is the start)");
        const bool allow_null = !out.ok();
        for (std::size_t f = 0; f < frames->size() && grid_ok; ++f) {
            const JsonView frame = frames->element(f);
            if (!frame.json().is_array() || static_cast<std::int64_t>(frame.size()) != vertex_count) {
                diagnostics.error(frame.pointer(),
                                  frame.json().is_array()
                                      ? "has " + std::to_string(frame.size()) + " vertices but the grid has " +
                                            std::to_string(vertex_count) + " (rows x cols)"
                                      : std::string("expected an array of [x, y, z], found ") + frame.json().type_name(),
                                  "write one [x, y, z] per grid vertex r * cols + c");
                continue;
            }
            std::vector<Eigen::Vector3d> points;
            points.reserve(frame.size());
            bool ok = true;
            for (std::size_t i = 0; i < frame.size(); ++i) {
                if (const std::optional<Eigen::Vector3d> p = detail::point_m(frame.element(i), allow_null)) points.push_back(*p);
                else ok = false;
            }
            if (ok) out.frames_m.push_back(std::move(points));
        }
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return out;
}

nlohmann::json swatch_frames_to_json(const SwatchFramesFile& s) {
    nlohmann::json frames = nlohmann::json::array();
    for (const std::vector<Eigen::Vector3d>& frame : s.frames_m) {
        nlohmann::json points = nlohmann::json::array();
        for (const Eigen::Vector3d& p : frame) points.push_back({p.x(), p.y(), p.z()});
        frames.push_back(std::move(points));
    }
    return {{"format", kSwatchFramesFormatName},
            {"version", kSwatchFramesFormatVersion.to_string()},
            {"status", s.status},
            {"reason", s.reason},
            {"equilibrium_converged", s.equilibrium_converged},
            {"grid", {s.rows, s.cols}},
            {"pinned_vertices", s.pinned_vertices},
            {"wall_time_s", s.wall_time_s},
            {"frames", std::move(frames)}};
}

SwatchFramesFile read_swatch_frames(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<SwatchFramesFile>(path, parse_swatch_frames, warnings);
}

void write_swatch_frames(const std::string& path, const SwatchFramesFile& frames) {
    detail::write_validated_json(path, swatch_frames_to_json(frames), parse_swatch_frames);
}

std::vector<Problem> validate_swatch_frames_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_swatch_frames);
}

nlohmann::json summarize_swatch_frames(const SwatchFramesFile& s) {
    // How far the swatch hangs below its highest point in the last frame (metres), a quick look at the result.
    double drop_m = 0.0;
    if (!s.frames_m.empty() && !s.frames_m.back().empty()) {
        double top = -std::numeric_limits<double>::infinity();
        double bottom = std::numeric_limits<double>::infinity();
        for (const Eigen::Vector3d& p : s.frames_m.back())
            if (std::isfinite(p.z())) {
                top = std::max(top, p.z());
                bottom = std::min(bottom, p.z());
            }
        if (top >= bottom) drop_m = top - bottom;
    }
    nlohmann::json out = {{"format", kSwatchFramesFormatName},
                          {"status", s.status},
                          {"equilibrium_converged", s.equilibrium_converged},
                          {"grid", {s.rows, s.cols}},
                          {"frames", s.frames_m.size()},
                          {"pinned_vertices", s.pinned_vertices.size()},
                          {"wall_time_s", s.wall_time_s},
                          {"last_frame_height_span_m", drop_m}};
    if (!s.reason.empty()) out["reason"] = s.reason;
    return out;
}

}  // namespace flowvid::formats
