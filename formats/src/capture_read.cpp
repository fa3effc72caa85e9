// capture.json version 1: parsing and validation (every problem, with file,
// JSON pointer and fix), and the 3D tracks and evaluation-only truth it
// names. The capture's camera model, paths and JSON round trip are in
// capture.cpp; loading frames in capture_frames.cpp.

#include "flowvid/formats/capture.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/sha256.hpp"

#include "capture_json.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace flowvid::formats {
namespace fs = std::filesystem;

namespace {

using namespace capture_json;

constexpr double kRotationTolerance = 1e-6;
constexpr std::int64_t kMaxFrameCount = 10'000'000;
constexpr std::int64_t kMaxFrameNumber = 1'000'000'000;
constexpr std::int64_t kMaxImageSide = 100'000;
constexpr int kMaxFramesToScan = 10'000;  // beyond this only the first and last frame files are checked
constexpr double kMinCaptureFps = 1.0;
constexpr double kMaxCaptureFps = 1000.0;
constexpr double kMaxSwatchSideM = 10.0;
constexpr double kMaxSwatchMassKg = 100.0;

bool is_known_kind(const std::string& kind) {
    for (const char* known : kCaptureKinds)
        if (kind == known) return true;
    return false;
}

std::string list_kinds() {
    std::string text;
    for (const char* known : kCaptureKinds) text += (text.empty() ? "\"" : ", \"") + std::string(known) + "\"";
    return text;
}

std::string format_double(double value) {
    std::ostringstream text;
    text.precision(10);
    text << value;
    return text.str();
}

// A rows x cols matrix written as an array of rows; every entry finite.
std::optional<Eigen::MatrixXd> read_matrix(const JsonView& parent, const std::string& key, int rows, int cols,
                                           bool required = true) {
    std::optional<JsonView> list = parent.array(key, required);
    if (!list) return std::nullopt;
    Diagnostics& diag = parent.diagnostics();
    const std::string shape = std::to_string(rows) + " x " + std::to_string(cols);
    const std::string fix = "write " + std::to_string(rows) + " rows of " + std::to_string(cols) + " numbers: [[...], ...]";
    if (list->size() != static_cast<std::size_t>(rows)) {
        diag.error(list->pointer(),
                   "expected a " + shape + " matrix (" + std::to_string(rows) + " rows), found " +
                       std::to_string(list->size()) + " rows",
                   fix);
        return std::nullopt;
    }
    Eigen::MatrixXd m(rows, cols);
    bool ok = true;
    for (int r = 0; r < rows; ++r) {
        JsonView row = list->element(static_cast<std::size_t>(r));
        if (!row.json().is_array() || row.size() != static_cast<std::size_t>(cols)) {
            diag.error(row.pointer(), "expected a row of " + std::to_string(cols) + " numbers", fix);
            ok = false;
            continue;
        }
        for (int c = 0; c < cols; ++c) {
            std::optional<double> value = row.element(static_cast<std::size_t>(c)).as_number(NumberRange{});
            if (!value) ok = false;
            else m(r, c) = *value;
        }
    }
    if (!ok) return std::nullopt;
    return m;
}

std::optional<Eigen::Vector3d> read_vector3(const JsonView& parent, const std::string& key, const NumberRange& range,
                                            bool required = true) {
    std::optional<std::vector<double>> values = parent.numbers(key, 3, range, required);
    if (!values) return std::nullopt;
    return Eigen::Vector3d((*values)[0], (*values)[1], (*values)[2]);
}

std::size_t count_errors(const Diagnostics& diag) {
    return static_cast<std::size_t>(std::count_if(diag.problems().begin(), diag.problems().end(), [](const Problem& p) {
        return p.severity == Problem::Severity::error;
    }));
}

// The tracks' rows must be the capture's frames and their columns the grid's points.
std::vector<Problem> tracks_shape_problems(const VertexAnimation& animation, const TracksSpec& tracks,
                                           const FramesSpec& frames, const std::string& json_path) {
    std::vector<Problem> problems;
    const std::int64_t points = std::int64_t(tracks.rows) * tracks.cols;
    if (animation.vertex_count != points)
        problems.push_back({Problem::Severity::error, json_path, "/tracks/rows",
                            "tracks file \"" + tracks.file + "\" has " + std::to_string(animation.vertex_count) +
                                " columns (points) but the grid " + std::to_string(tracks.rows) + " x " +
                                std::to_string(tracks.cols) + " has " + std::to_string(points),
                            "set \"rows\" and \"cols\" to the uv grid the points were measured on (one column per point, "
                            "r*cols + c)"});
    if (animation.frame_count != frames.count)
        problems.push_back({Problem::Severity::error, json_path, "/tracks/file",
                            "tracks file \"" + tracks.file + "\" has " + std::to_string(animation.frame_count) +
                                " rows (frames) but the capture has " + std::to_string(frames.count) + " frames",
                            "write one row per capture frame (NaN for a frame where no point was seen)"});
    return problems;
}

class CaptureParser {
public:
    CaptureParser(const std::string& folder, Diagnostics& diag, Strictness strictness, CaptureFileChecks checks)
        : m_diag(diag), m_strictness(strictness), m_checks(checks) {
        m_capture.folder = folder;
        m_capture.json_path = (fs::path(folder.empty() ? "." : folder) / "capture.json").string();
    }

    std::optional<Capture> parse(const nlohmann::json& document) {
        JsonView root(document, "", m_diag, m_strictness);
        if (!check_header(root)) return std::nullopt;
        root.check_known_keys({"format", "version", "kind", "fps", "frames", "background", "masks", "camera", "world",
                               "projector", "swatch", "rigid", "flowlines", "tracks", "source"});

        if (std::optional<std::string> kind = root.string("kind")) {
            if (is_known_kind(*kind)) m_capture.kind = *kind;
            else
                m_diag.error("/kind", "unknown kind \"" + *kind + "\"", "use one of " + list_kinds());
        }
        const std::string& kind = m_capture.kind;
        const bool cloth = m_capture.is_cloth(), rigid = m_capture.is_rigid(), video = m_capture.is_video();
        const bool kind_known = !kind.empty();

        // Cameras film at 1 to 1000 frames per second; outside that a time step
        // of 1/fps is either a unit mistake or would simulate for ever.
        if (std::optional<double> fps = root.number("fps", NumberRange::closed(kMinCaptureFps, kMaxCaptureFps, "frames/s")))
            m_capture.fps = *fps;
        parse_frames(root);
        m_capture.background = root.string("background", false).value_or("");
        m_capture.masks = root.string("masks", false).value_or("");
        if (root.has("background") && root.json()["background"].is_string() && m_capture.background.empty())
            m_diag.error("/background", "empty path", "name the background image or drop the key");
        if (root.has("masks") && root.json()["masks"].is_string()) {
            if (!format_frame_pattern(m_capture.masks, 1))
                m_diag.error("/masks", "\"" + m_capture.masks + "\" is not a frame pattern with one %d conversion",
                             "write e.g. \"masks/%06d.png\"");
        }

        // Blocks: required by their kinds, ignored (with a warning) by others.
        const bool needs_camera = kind_known && !video;
        if (root.has("camera") || needs_camera) {
            if (std::optional<JsonView> camera = root.object("camera", needs_camera))
                m_capture.camera = parse_camera(*camera, false);
        }
        if (root.has("world") || (kind_known && !video)) {
            if (std::optional<JsonView> world = root.object("world", kind_known && !video)) parse_world(*world);
        }
        block(root, "projector", cloth, "cloth.* captures", [&](const JsonView& view) { parse_projector(view); });
        block(root, "swatch", cloth, "cloth.* captures", [&](const JsonView& view) { parse_swatch(view); });
        block(root, "rigid", rigid, "rigid.toss captures", [&](const JsonView& view) { parse_rigid(view); });
        if (root.has("tracks")) {
            if (!cloth && kind_known)
                m_diag.warning("/tracks", "\"tracks\" is only read for cloth.* captures, not " + kind + " (ignored)",
                               "remove it or correct \"kind\"");
            else if (std::optional<JsonView> tracks = root.object("tracks", false))
                parse_tracks(*tracks);
        }
        if (root.has("flowlines") || video) {
            if (!video && kind_known) {
                m_diag.warning("/flowlines", "flow lines are only read for video.flow captures (ignored)", "");
            } else if (std::optional<std::string> flowlines = root.string("flowlines", video)) {
                m_capture.flowlines = *flowlines;
                if (flowlines->empty()) m_diag.error("/flowlines", "empty path", "name the SVG file, e.g. \"flowlines.svg\"");
            }
        }
        if (root.has("source")) {
            if (root.object("source", false)) m_capture.source = root.json()["source"];
        }

        check_paths_stay_inside();

        // Files are checked even when capture.json has other mistakes, using
        // whatever parsed, so that one run reports everything.
        if (m_checks != CaptureFileChecks::none) check_files();
        if (m_diag.has_errors()) return std::nullopt;
        return std::move(m_capture);
    }

private:
    // "format" must name this format; "version" is the integer 1 (a "1.x"
    // string is accepted, as other flowvid files write versions that way).
    bool check_header(const JsonView& root) {
        if (!root.json().is_object()) {
            m_diag.error("/", "the document is not a JSON object",
                         std::string("a capture.json is a JSON object with \"format\": \"") + kCaptureFormatName + "\"");
            return false;
        }
        std::optional<std::string> format = root.string("format");
        if (format && *format != kCaptureFormatName) {
            m_diag.error("/format", "this is a \"" + *format + "\" file, not \"" + kCaptureFormatName + "\"",
                         std::string("set \"format\": \"") + kCaptureFormatName + "\" if this is a capture description");
            return false;
        }
        if (!root.has("version")) {
            m_diag.error("/version", "missing", "add \"version\": " + std::to_string(kCaptureFormatVersion));
            return false;
        }
        const nlohmann::json& version = root.json()["version"];
        int major = -1, minor = 0;
        if (version.is_number_integer()) {
            const auto value = version.get<std::int64_t>();
            if (value >= 0 && value < 1000000) major = static_cast<int>(value);
        } else if (version.is_number_float() && std::isfinite(version.get<double>()) &&
                   version.get<double>() == std::floor(version.get<double>()) && version.get<double>() >= 0 &&
                   version.get<double>() < 1e6) {
            major = static_cast<int>(version.get<double>());
        } else if (version.is_string()) {
            if (std::optional<FormatVersion> parsed = FormatVersion::parse(version.get<std::string>())) {
                major = parsed->major;
                minor = parsed->minor;
            }
        }
        if (major < 0) {
            m_diag.error("/version", "expected the integer version, found " + version.dump().substr(0, 40),
                         "write \"version\": " + std::to_string(kCaptureFormatVersion));
            return false;
        }
        if (!format) return false;
        if (major != kCaptureFormatVersion) {
            m_diag.error("/version",
                         "capture version " + std::to_string(major) + " is not supported (this flowvid reads version " +
                             std::to_string(kCaptureFormatVersion) + ")",
                         major > kCaptureFormatVersion ? "upgrade flowvid" : "convert the capture.json to version 1");
            return false;
        }
        if (minor > 0)
            m_diag.warning("/version", "version " + version.get<std::string>() + " is newer than " +
                                           std::to_string(kCaptureFormatVersion) + "; unknown keys are ignored",
                           "upgrade flowvid to use every field");
        m_capture.version = major;
        return true;
    }

    template <typename Parse>
    void block(const JsonView& root, const char* key, bool required, const char* used_by, Parse parse) {
        if (!root.has(key) && !required) return;
        if (!required && !m_capture.kind.empty()) {
            m_diag.warning(std::string("/") + key,
                           std::string("\"") + key + "\" is only read for " + used_by + ", not " + m_capture.kind +
                               " (ignored)",
                           "remove it or correct \"kind\"");
            return;
        }
        if (std::optional<JsonView> view = root.object(key, required)) parse(*view);
    }

    void parse_frames(const JsonView& root) {
        std::optional<JsonView> frames = root.object("frames");
        if (!frames) return;
        const std::size_t errors_before = count_errors(m_diag);
        frames->check_known_keys({"pattern", "video", "first", "count"});
        const bool has_pattern = frames->has("pattern"), has_video = frames->has("video");
        if (has_pattern && has_video) {
            m_diag.error("/frames", "has both \"pattern\" and \"video\"", "keep exactly one of them");
        } else if (!has_pattern && !has_video) {
            m_diag.error("/frames", "has neither \"pattern\" nor \"video\"",
                         "add \"pattern\": \"frames/%06d.png\" or \"video\": \"clip.mp4\"");
        } else if (has_pattern) {
            if (std::optional<std::string> pattern = frames->string("pattern")) {
                m_capture.frames.pattern = *pattern;
                if (!format_frame_pattern(*pattern, 1))
                    m_diag.error("/frames/pattern", "\"" + *pattern + "\" is not a frame pattern with one %d conversion",
                                 "write e.g. \"frames/%06d.png\" (%d, %Nd or %0Nd; %% for a literal %)");
            }
        } else if (std::optional<std::string> video = frames->string("video")) {
            m_capture.frames.video = *video;
            if (video->empty()) m_diag.error("/frames/video", "empty path", "name the video file, e.g. \"clip.mp4\"");
        }
        const std::int64_t min_first = has_video ? 1 : 0;
        if (std::optional<std::int64_t> first = frames->integer("first", min_first, kMaxFrameNumber))
            m_capture.frames.first = static_cast<int>(*first);
        if (std::optional<std::int64_t> count = frames->integer("count", 1, kMaxFrameCount))
            m_capture.frames.count = static_cast<int>(*count);
        m_frames_ok = count_errors(m_diag) == errors_before;
        if (!m_frames_ok) m_capture.frames.count = 0;  // nothing below checks a half-parsed range
    }

    std::optional<CameraModel> parse_camera(const JsonView& view, bool is_projector) {
        if (is_projector)
            view.check_known_keys({"width", "height", "K", "dist", "camera_from_world", "pattern"});
        else
            view.check_known_keys({"width", "height", "K", "dist", "camera_from_world"});
        const std::size_t errors_before = count_errors(m_diag);
        CameraModel camera;
        const std::optional<std::int64_t> width = view.integer("width", 1, kMaxImageSide);
        const std::optional<std::int64_t> height = view.integer("height", 1, kMaxImageSide);
        if (width) camera.width = static_cast<int>(*width);
        if (height) camera.height = static_cast<int>(*height);
        const std::string k_pointer = json_pointer_child(view.pointer(), "K");
        if (std::optional<Eigen::MatrixXd> K = read_matrix(view, "K", 3, 3)) {
            camera.K = *K;
            if (!(camera.K(0, 0) > 0.0))
                m_diag.error(k_pointer + "/0/0", "focal length fx = " + format_double(camera.K(0, 0)) + " must be > 0",
                             "write fx in pixels");
            if (!(camera.K(1, 1) > 0.0))
                m_diag.error(k_pointer + "/1/1", "focal length fy = " + format_double(camera.K(1, 1)) + " must be > 0",
                             "write fy in pixels");
            if (camera.K(1, 0) != 0.0)
                m_diag.error(k_pointer + "/1/0", "must be 0", "K is [[fx, skew, cx], [0, fy, cy], [0, 0, 1]]");
            if (camera.K(2, 0) != 0.0 || camera.K(2, 1) != 0.0 || camera.K(2, 2) != 1.0)
                m_diag.error(k_pointer + "/2", "the last row must be [0, 0, 1]",
                             "K is [[fx, skew, cx], [0, fy, cy], [0, 0, 1]]");
            if (width && height &&
                (camera.K(0, 2) < -0.5 || camera.K(0, 2) > double(*width) - 0.5 || camera.K(1, 2) < -0.5 ||
                 camera.K(1, 2) > double(*height) - 0.5))
                m_diag.warning(k_pointer, "the principal point (" + format_double(camera.K(0, 2)) + ", " +
                                              format_double(camera.K(1, 2)) + ") lies outside the image",
                               "check cx, cy (pixels, OpenCV convention: (0, 0) is the centre of the top-left pixel)");
        }
        if (std::optional<std::vector<double>> dist = view.numbers("dist", 5, NumberRange{}, !is_projector))
            std::copy(dist->begin(), dist->end(), camera.dist.begin());
        const std::string m_pointer = json_pointer_child(view.pointer(), "camera_from_world");
        if (std::optional<Eigen::MatrixXd> matrix = read_matrix(view, "camera_from_world", 4, 4)) {
            camera.camera_from_world = *matrix;
            const Eigen::Matrix4d& M = camera.camera_from_world;
            if (std::abs(M(3, 0)) > 1e-12 || std::abs(M(3, 1)) > 1e-12 || std::abs(M(3, 2)) > 1e-12 ||
                std::abs(M(3, 3) - 1.0) > 1e-12)
                m_diag.error(m_pointer + "/3", "the last row must be [0, 0, 0, 1]",
                             "write a rigid transform [[R, t], [0, 0, 0, 1]]");
            const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
            const double orthonormality = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
            const double det = R.determinant();
            if (orthonormality > kRotationTolerance)
                m_diag.error(m_pointer,
                             "the rotation part is not orthonormal (max |R^T R - I| = " + format_double(orthonormality) +
                                 ", tolerance 1e-6)",
                             "write a rotation matrix (orthonormal rows, det +1) with enough digits; scale belongs in K");
            else if (std::abs(det - 1.0) > kRotationTolerance)
                m_diag.error(m_pointer, "the rotation part has determinant " + format_double(det) + " (a reflection)",
                             "use a right-handed rotation (det +1): flip one axis of the calibration");
        }
        if (count_errors(m_diag) > errors_before) return std::nullopt;
        return camera;
    }

    void parse_world(const JsonView& view) {
        view.check_known_keys({"gravity", "note"});
        WorldSpec world;
        world.note = view.string("note", false).value_or("");
        if (!view.has("gravity")) {
            m_diag.error(json_pointer_child(view.pointer(), "gravity"), "missing",
                         "write \"gravity\": [0, 0, -9.81] (m/s^2, world frame) or null when unknown");
        } else if (!view.json()["gravity"].is_null()) {
            if (std::optional<Eigen::Vector3d> gravity = read_vector3(view, "gravity", NumberRange{})) {
                world.gravity_m_per_s2 = *gravity;
                const double norm = gravity->norm();
                if (norm < 9.7 || norm > 9.9)
                    m_diag.warning("/world/gravity", "|g| = " + format_double(norm) + " m/s^2 is not Earth's gravity",
                                   "gravity is in m/s^2 (e.g. [0, 0, -9.81]); write null when unknown");
            }
        }
        m_capture.world = world;
    }

    void parse_projector(const JsonView& view) {
        std::optional<CameraModel> camera = parse_camera(view, true);
        Projector projector;
        bool ok = camera.has_value();
        if (camera) projector.camera = *camera;
        if (std::optional<JsonView> pattern = view.object("pattern")) {
            pattern->check_known_keys({"type", "axis", "period_px"});
            if (std::optional<std::string> type = pattern->string("type")) {
                projector.pattern.type = *type;
                if (*type != "sine_stripes") {
                    m_diag.error("/projector/pattern/type", "unknown pattern type \"" + *type + "\"",
                                 "use \"sine_stripes\"");
                    ok = false;
                }
            } else ok = false;
            if (std::optional<std::string> axis = pattern->string("axis")) {
                projector.pattern.axis = *axis;
                if (*axis != "rows" && *axis != "columns") {
                    m_diag.error("/projector/pattern/axis", "unknown axis \"" + *axis + "\"",
                                 "use \"rows\" (stripes vary with the projector row) or \"columns\"");
                    ok = false;
                }
            } else ok = false;
            if (std::optional<double> period = pattern->number("period_px", NumberRange::positive("px"))) {
                projector.pattern.period_px = *period;
                if (*period < 2.0)
                    m_diag.warning("/projector/pattern/period_px", "a period below 2 projector pixels aliases",
                                   "check the period (projector pixels per stripe)");
            } else ok = false;
        } else ok = false;
        if (ok) m_capture.projector = projector;
    }

    void parse_tracks(const JsonView& view) {
        view.check_known_keys({"file", "rows", "cols"});
        TracksSpec tracks;
        const std::size_t errors_before = count_errors(m_diag);
        tracks.file = view.string("file").value_or("");
        if (view.has("file") && view.json()["file"].is_string() && tracks.file.empty())
            m_diag.error("/tracks/file", "empty path", "name the EXR file of the tracks, e.g. \"tracks.exr\"");
        const std::int64_t most = kMaxVertexAnimationVertices;
        tracks.rows = static_cast<int>(view.integer("rows", 2, most).value_or(0));
        tracks.cols = static_cast<int>(view.integer("cols", 2, most).value_or(0));
        if (tracks.rows > 0 && tracks.cols > 0 && std::int64_t(tracks.rows) * tracks.cols > most)
            m_diag.error("/tracks/rows",
                         "a " + std::to_string(tracks.rows) + " x " + std::to_string(tracks.cols) +
                             " grid has more points than a vertex-animation file may hold (" + std::to_string(most) + ")",
                         "give the grid the tracks were measured on");
        if (count_errors(m_diag) > errors_before) return;
        m_capture.tracks = tracks;
    }

    void parse_swatch(const JsonView& view) {
        view.check_known_keys({"width_m", "height_m", "mass_kg", "initial", "pins"});
        SwatchSpec swatch;
        const std::size_t errors_before = count_errors(m_diag);
        // A calibration swatch fits in a studio: bounded sizes keep a typo
        // (1e308) from reaching the mesh builder as "triangle has no area".
        const NumberRange side{0.0, kMaxSwatchSideM, true, "m"};
        swatch.width_m = view.number("width_m", side).value_or(0.0);
        swatch.height_m = view.number("height_m", side).value_or(0.0);
        swatch.mass_kg = view.number("mass_kg", NumberRange{0.0, kMaxSwatchMassKg, true, "kg"}).value_or(0.0);
        if (std::optional<std::string> initial = view.string("initial")) {
            swatch.initial = *initial;
            if (*initial != "equilibrium")
                m_diag.error("/swatch/initial", "unknown initial state \"" + *initial + "\"",
                             "version 1 knows \"equilibrium\" (hanging at rest under the pins at frame 'first')");
        }
        if (std::optional<JsonView> pins = view.array("pins")) {
            if (pins->size() == 0)
                m_diag.error(pins->pointer(), "no pins", "list the pinned points with their uv and positions");
            for (std::size_t i = 0; i < pins->size(); ++i) {
                JsonView item = pins->element(i);
                if (!item.json().is_object()) {
                    m_diag.error(item.pointer(), "expected an object", "write {\"uv\": [u, v], \"positions\": [[x, y, z], ...]}");
                    continue;
                }
                item.check_known_keys({"uv", "positions"});
                Pin pin;
                if (std::optional<std::vector<double>> uv = item.numbers("uv", 2, NumberRange::closed(0.0, 1.0)))
                    pin.uv = {(*uv)[0], (*uv)[1]};
                if (std::optional<JsonView> positions = item.array("positions")) {
                    const std::size_t expected = static_cast<std::size_t>(std::max(m_capture.frames.count, 0));
                    if (m_capture.frames.count > 0 && positions->size() != expected)
                        m_diag.error(positions->pointer(),
                                     "has " + std::to_string(positions->size()) + " positions but frames.count is " +
                                         std::to_string(expected),
                                     "write one world position [x, y, z] (m) per frame, frames first..first+count-1");
                    for (std::size_t f = 0; f < positions->size(); ++f) {
                        JsonView entry = positions->element(f);
                        if (!entry.json().is_array() || entry.size() != 3) {
                            m_diag.error(entry.pointer(), "expected [x, y, z] in metres", "write three numbers");
                            continue;
                        }
                        Eigen::Vector3d p;
                        bool ok = true;
                        for (int c = 0; c < 3; ++c) {
                            std::optional<double> value = entry.element(static_cast<std::size_t>(c)).as_number(NumberRange{});
                            if (!value) ok = false;
                            else p[c] = *value;
                        }
                        if (ok) pin.positions_m.push_back(p);
                    }
                }
                for (std::size_t j = 0; j < swatch.pins.size(); ++j)
                    if ((swatch.pins[j].uv - pin.uv).norm() < 1e-12)
                        m_diag.error(json_pointer_child(item.pointer(), "uv"),
                                     "same uv as /swatch/pins/" + std::to_string(j), "pin each point once");
                swatch.pins.push_back(std::move(pin));
            }
        }
        if (count_errors(m_diag) > errors_before) return;
        if (m_capture.kind == "cloth.static") {
            for (std::size_t i = 0; i < swatch.pins.size(); ++i) {
                double travel = 0.0;
                for (const Eigen::Vector3d& p : swatch.pins[i].positions_m)
                    travel = std::max(travel, (p - swatch.pins[i].positions_m.front()).norm());
                if (travel > 1e-3)
                    m_diag.warning("/swatch/pins/" + std::to_string(i) + "/positions",
                                   "the pin moves " + format_double(travel) + " m in a cloth.static capture",
                                   "use \"kind\": \"cloth.waving\" for moving pins");
            }
        }
        m_capture.swatch = std::move(swatch);
    }

    void parse_rigid(const JsonView& view) {
        view.check_known_keys({"mesh", "mass_kg", "center_of_mass", "inertia_body"});
        RigidSpec rigid;
        const std::size_t errors_before = count_errors(m_diag);
        rigid.mesh = view.string("mesh").value_or("");
        if (view.has("mesh") && view.json()["mesh"].is_string() && rigid.mesh.empty())
            m_diag.error("/rigid/mesh", "empty path", "name the body's .glb file");
        m_mesh = rigid.mesh;
        rigid.mass_kg = view.number("mass_kg", NumberRange::positive("kg")).value_or(0.0);
        if (std::optional<Eigen::Vector3d> com = read_vector3(view, "center_of_mass", NumberRange{}))
            rigid.center_of_mass_m = *com;
        if (std::optional<Eigen::MatrixXd> inertia = read_matrix(view, "inertia_body", 3, 3)) {
            const Eigen::Matrix3d I = *inertia;
            const double scale = std::max(I.cwiseAbs().maxCoeff(), 1e-300);
            const double asymmetry = (I - I.transpose()).cwiseAbs().maxCoeff();
            if (asymmetry > 1e-9 * scale + 1e-15) {
                m_diag.error("/rigid/inertia_body", "not symmetric (max |I - I^T| = " + format_double(asymmetry) + ")",
                             "write the symmetric inertia tensor [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] (kg m^2)");
            } else {
                Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(0.5 * (I + I.transpose()));
                const Eigen::Vector3d moments = solver.eigenvalues();  // ascending
                if (!(moments[0] > 0.0))
                    m_diag.error("/rigid/inertia_body",
                                 "not positive definite (principal moments " + format_double(moments[0]) + ", " +
                                     format_double(moments[1]) + ", " + format_double(moments[2]) + " kg m^2)",
                                 "every principal moment of a solid body is > 0: check signs and units (kg m^2)");
                else if (moments[2] > (moments[0] + moments[1]) * (1.0 + 1e-6))
                    m_diag.error("/rigid/inertia_body",
                                 "principal moments " + format_double(moments[0]) + ", " + format_double(moments[1]) +
                                     ", " + format_double(moments[2]) +
                                     " violate the triangle inequality (no physical body has them)",
                                 "check the inertia tensor: the largest moment is at most the sum of the other two");
                rigid.inertia_body_kg_m2 = I;
            }
        }
        if (count_errors(m_diag) > errors_before) return;
        m_capture.rigid = rigid;
    }

    // ---- referenced files -------------------------------------------------

    std::string resolve(const std::string& relative) const { return m_capture.resolve(relative); }

    // capture.md: every path resolves inside the capture folder, so that a
    // capture from elsewhere cannot make a command open (and quote in its
    // errors) files outside it.
    void check_paths_stay_inside() {
        if (capture_paths_outside_folder_allowed()) return;
        auto check = [&](const char* field, const std::string& path) {
            if (path.empty() || path_stays_inside_folder(path)) return;
            m_diag.error(field, "\"" + path + "\" leads outside the capture folder",
                         "copy the file into the capture folder and name it relative to it, or run "
                         "flowvid --allow-outside-paths to trust this capture");
        };
        check("/background", m_capture.background);
        check("/masks", m_capture.masks);
        check("/frames/pattern", m_capture.frames.pattern);
        check("/frames/video", m_capture.frames.video);
        check("/flowlines", m_capture.flowlines);
        if (m_capture.tracks) check("/tracks/file", m_capture.tracks->file);
        check("/rigid/mesh", m_mesh);
    }

    // Reports a missing or non-regular file; true when it is a readable file.
    bool check_file(const std::string& field, const std::string& what, const std::string& relative) {
        if (fs::path(relative).is_absolute())
            m_diag.warning(field, "absolute path \"" + relative + "\" makes the capture non-portable",
                           "use a path relative to the capture folder");
        const std::string path = resolve(relative);
        std::error_code ec;
        if (!fs::exists(path, ec)) {
            m_diag.error(field, what + " \"" + relative + "\" does not exist (looked for " + path + ")",
                         "put the file there or correct the path (relative to the capture folder)");
            return false;
        }
        if (!fs::is_regular_file(path, ec)) {
            m_diag.error(field, what + " \"" + relative + "\" is not a regular file (" + path + ")",
                         "name a file inside the capture folder");
            return false;
        }
        return true;
    }

    // First and last file of a numbered sequence, and every one in between
    // when there are not too many; one problem lists the missing ones.
    bool check_sequence(const std::string& field, const std::string& what, const std::string& pattern) {
        const FramesSpec& frames = m_capture.frames;
        // A pattern that names no file (its own error is reported where it is
        // read) has no sequence to look for.
        if (!format_frame_pattern(pattern, frames.first) || !format_frame_pattern(pattern, frames.last())) return false;
        auto exists = [&](int number) {
            std::error_code ec;
            return fs::is_regular_file(resolve(*format_frame_pattern(pattern, number)), ec);
        };
        std::vector<int> numbers;
        const bool first_ok = exists(frames.first), last_ok = exists(frames.last());
        if (frames.count <= kMaxFramesToScan && (first_ok || last_ok)) {
            for (int n = frames.first; n <= frames.last(); ++n) numbers.push_back(n);
        } else {
            numbers = {frames.first};
            if (frames.count > 1) numbers.push_back(frames.last());
        }
        std::vector<int> missing;
        for (int n : numbers)
            if (!(n == frames.first ? first_ok : n == frames.last() ? last_ok : exists(n))) missing.push_back(n);
        if (missing.empty()) return true;
        std::string names;
        for (std::size_t i = 0; i < missing.size() && i < 5; ++i)
            names += (i ? ", " : "") + std::string("\"") + *format_frame_pattern(pattern, missing[i]) + "\"";
        if (missing.size() > 5) names += ", ...";
        const std::string folder = fs::path(resolve(*format_frame_pattern(pattern, missing.front()))).parent_path().string();
        m_diag.error(field,
                     std::to_string(missing.size()) + " of the " + std::to_string(numbers.size()) + " " + what +
                         " files checked do not exist: " + names + " (in " + (folder.empty() ? "." : folder) + ")",
                     "put the " + what + " files there, or correct \"" + field.substr(field.rfind('/') + 1) +
                         "\", \"first\" or \"count\"");
        return false;
    }

    void check_image_size(const std::string& field, const std::string& what, const std::string& relative,
                          int expected_width, int expected_height, const std::string& expected_from) {
        const std::string path = resolve(relative);
        try {
            const ImageInfo info = read_image_info(path);
            if (expected_width > 0 && (info.width != expected_width || info.height != expected_height))
                m_diag.error(field,
                             what + " \"" + relative + "\" is " + std::to_string(info.width) + " x " +
                                 std::to_string(info.height) + " pixels but " + expected_from + " says " +
                                 std::to_string(expected_width) + " x " + std::to_string(expected_height),
                             "make every image the calibrated size, or correct the camera's width and height");
        } catch (const Error& error) {
            m_diag.error(field, what + " \"" + relative + "\" cannot be read as an image: " + error.message(),
                         error.fix().empty() ? "write a PNG, JPEG or EXR image" : error.fix());
        }
    }

    void check_files() {
        const bool content = m_checks == CaptureFileChecks::content;
        const FramesSpec& frames = m_capture.frames;
        const int width = m_capture.camera ? m_capture.camera->width : 0;
        const int height = m_capture.camera ? m_capture.camera->height : 0;
        if (!m_frames_ok) return check_other_files(content, width, height);
        if (!frames.pattern.empty()) {
            if (check_sequence("/frames/pattern", "frame", frames.pattern) && content) {
                check_image_size("/frames/pattern", "frame " + std::to_string(frames.first) + " file",
                                 *format_frame_pattern(frames.pattern, frames.first), width, height, "/camera");
                if (frames.count > 1)
                    check_image_size("/frames/pattern", "frame " + std::to_string(frames.last()) + " file",
                                     *format_frame_pattern(frames.pattern, frames.last()), width, height, "/camera");
            }
        }
        if (!frames.video.empty() && check_file("/frames/video", "video", frames.video) && content) check_video();
        if (!m_capture.masks.empty() && format_frame_pattern(m_capture.masks, 1)) {
            if (check_sequence("/masks", "mask", m_capture.masks) && content)
                check_image_size("/masks", "mask " + std::to_string(frames.first) + " file",
                                 *format_frame_pattern(m_capture.masks, frames.first), width, height, "/camera");
        }
        check_other_files(content, width, height);
    }

    // Files that do not depend on the frame range.
    void check_other_files(bool content, int width, int height) {
        if (!m_capture.background.empty() && check_file("/background", "background image", m_capture.background) &&
            content)
            check_image_size("/background", "background image", m_capture.background, width, height, "/camera");
        if (!m_mesh.empty() && check_file("/rigid/mesh", "mesh", m_mesh) && content) check_mesh();
        if (!m_capture.flowlines.empty()) check_file("/flowlines", "flow-line SVG", m_capture.flowlines);
        if (m_capture.tracks && check_file("/tracks/file", "tracks file", m_capture.tracks->file) && content)
            check_tracks();
    }

    // The tracks must be one row per frame and one column per grid point.
    void check_tracks() {
        const TracksSpec& tracks = *m_capture.tracks;
        const std::string path = resolve(tracks.file);
        std::vector<Problem> problems = validate_vertex_animation_file(path, Strictness::lenient, MissingPoints::allow_nan);
        const bool unreadable = std::any_of(problems.begin(), problems.end(),
                                            [](const Problem& p) { return p.severity == Problem::Severity::error; });
        m_diag.merge(problems);
        if (unreadable) {
            m_diag.error("/tracks/file", "tracks file \"" + tracks.file + "\" is not a valid positions EXR (problems listed for " +
                                             path + ")",
                         "write the tracks as float32 R, G, B: one row per frame, one column per point, NaN where unseen");
            return;
        }
        const VertexAnimation animation = read_vertex_animation(path, nullptr, MissingPoints::allow_nan);
        for (const Problem& p : tracks_shape_problems(animation, tracks, m_capture.frames, m_capture.json_path))
            m_diag.error(p.field, p.message, p.fix);
        const bool any_seen = std::any_of(animation.positions_m.begin(), animation.positions_m.end(),
                                          [](const Eigen::Vector3f& p) { return p.allFinite(); });
        if (!any_seen)
            m_diag.warning("/tracks/file", "tracks file \"" + tracks.file + "\" has no seen point (all NaN)",
                           "write the measured positions, or drop \"tracks\"");
    }

    void check_video() {
        const FramesSpec& frames = m_capture.frames;
        VideoInfo info;
        try {
            info = read_video_info(resolve(frames.video));
        } catch (const Error& error) {
            m_diag.error("/frames/video", "video \"" + frames.video + "\" cannot be decoded: " + error.message(),
                         "re-encode the clip with a codec ffmpeg decodes (e.g. H.264 in .mp4)");
            return;
        }
        if (info.frame_count > 0 && frames.last() > info.frame_count)
            m_diag.error("/frames/count",
                         "frames " + std::to_string(frames.first) + ".." + std::to_string(frames.last()) +
                             " are asked for but video \"" + frames.video + "\" has " +
                             std::to_string(info.frame_count) + " frames",
                         "lower \"count\" (or \"first\") to fit the clip");
        if (m_capture.camera && (info.width != m_capture.camera->width || info.height != m_capture.camera->height))
            m_diag.error("/camera/width",
                         "video \"" + frames.video + "\" is " + std::to_string(info.width) + " x " +
                             std::to_string(info.height) + " pixels but the camera says " +
                             std::to_string(m_capture.camera->width) + " x " + std::to_string(m_capture.camera->height),
                         "calibrate the camera at the clip's resolution");
        if (info.fps > 0.0 && m_capture.fps > 0.0 && std::abs(info.fps - m_capture.fps) > 1e-3 * m_capture.fps)
            m_diag.warning("/fps",
                           "capture.json says " + format_double(m_capture.fps) + " fps but video \"" + frames.video +
                               "\" says " + format_double(info.fps),
                           "check which frame rate the footage was recorded at");
    }

    void check_mesh() {
        const std::string path = resolve(m_mesh);
        Diagnostics mesh_diag(path);
        std::optional<TriangleMesh> mesh;
        try {
            mesh = parse_rigid_mesh_glb(read_text_file(path), mesh_diag);
        } catch (const Error& error) {
            mesh_diag.error(error.field(), error.message(), error.fix());
        }
        m_diag.merge(mesh_diag.problems());
        if (!mesh) {
            m_diag.error("/rigid/mesh", "mesh \"" + m_mesh + "\" is not a valid glTF binary (problems listed for " +
                                            path + ")",
                         "export the body again as glTF 2.0 binary (.glb), metres, no y-up conversion");
            return;
        }
        if (!m_capture.rigid) return;  // mass properties invalid: already reported
        RigidSpec& rigid = *m_capture.rigid;
        rigid.body_mesh = std::move(*mesh);
        Eigen::Vector3d lo = rigid.body_mesh.vertices_m.front(), hi = lo;
        for (const Eigen::Vector3d& v : rigid.body_mesh.vertices_m) {
            lo = lo.cwiseMin(v);
            hi = hi.cwiseMax(v);
        }
        const double margin = 1e-3 + 1e-3 * (hi - lo).norm();
        if ((rigid.center_of_mass_m.array() < lo.array() - margin).any() ||
            (rigid.center_of_mass_m.array() > hi.array() + margin).any())
            m_diag.warning("/rigid/center_of_mass", "lies outside the mesh's bounding box",
                           "the centre of mass is in the mesh's (body) frame, metres");
        const MeshVolume volume = mesh_volume(rigid.body_mesh);
        if (volume.volume_m3 > 0.0) {
            const double density = rigid.mass_kg / volume.volume_m3;
            if (density < 1.0 || density > 25000.0)
                m_diag.warning("/rigid/mass_kg",
                               "implies a density of " + format_double(density) + " kg/m^3 for the mesh's volume " +
                                   format_double(volume.volume_m3) + " m^3",
                               "check the mass (kg) and that the mesh is in metres");
        }
    }

    Diagnostics& m_diag;
    bool m_frames_ok = false;
    std::string m_mesh;
    Strictness m_strictness;
    CaptureFileChecks m_checks;
    Capture m_capture;
};

struct CaptureLocation {
    std::string folder;
    std::string json_path;
};

CaptureLocation locate_capture(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) return {path, (fs::path(path) / "capture.json").string()};
    std::string folder = fs::path(path).parent_path().string();
    return {folder.empty() ? "." : folder, path};
}

}  // namespace

std::optional<Capture> parse_capture(const nlohmann::json& document, const std::string& folder,
                                     Diagnostics& diagnostics, Strictness strictness, CaptureFileChecks checks) {
    CaptureParser parser(folder, diagnostics, strictness, checks);
    return parser.parse(document);
}

Capture read_capture_of_kind(const std::string& path, const std::vector<std::string>& kinds, const std::string& needed_by,
                             std::vector<Problem>* warnings) {
    Capture capture = read_capture(path, warnings);
    if (std::find(kinds.begin(), kinds.end(), capture.kind) == kinds.end()) {
        std::string wanted;
        for (const std::string& k : kinds) wanted += (wanted.empty() ? "" : " or ") + k;
        throw ValidationError({Problem{Problem::Severity::error, capture.json_path, "/kind",
                                       "the capture is a " + capture.kind + " capture; `" + needed_by + "` needs " + wanted,
                                       "give a " + wanted + " capture folder"}});
    }
    return capture;
}

Capture read_capture(const std::string& path, std::vector<Problem>* warnings) {
    const CaptureLocation location = locate_capture(path);
    const std::string text = read_text_file(location.json_path);
    Diagnostics diag(location.json_path);
    std::optional<Capture> capture;
    if (std::optional<nlohmann::json> document = parse_json_text(text, diag))
        capture = parse_capture(*document, location.folder, diag, Strictness::lenient, CaptureFileChecks::content);
    diag.throw_if_errors();
    if (warnings) *warnings = diag.warnings();
    capture->json_path = location.json_path;
    capture->capture_json_sha256 = sha256_hex(text);
    return std::move(*capture);
}

std::vector<Problem> validate_capture_folder(const std::string& path, Strictness strictness, CaptureFileChecks checks) {
    CaptureLocation location;
    try {
        location = locate_capture(path);
    } catch (const std::exception& error) {
        return {Problem{Problem::Severity::error, path, "", error.what(), "check the path"}};
    }
    Diagnostics diag(location.json_path);
    std::string text;
    try {
        text = read_text_file(location.json_path);
    } catch (const IoError& error) {
        diag.error("", error.message(), "a capture folder holds a capture.json (see the capture contract)");
        return diag.problems();
    }
    if (std::optional<nlohmann::json> document = parse_json_text(text, diag))
        parse_capture(*document, location.folder, diag, strictness, checks);
    return diag.problems();
}

std::optional<VertexAnimation> read_capture_tracks(const Capture& capture) {
    if (!capture.tracks) return std::nullopt;
    const TracksSpec& tracks = *capture.tracks;
    VertexAnimation animation = read_vertex_animation(capture.resolve(tracks.file), nullptr, MissingPoints::allow_nan);
    const std::vector<Problem> problems = tracks_shape_problems(animation, tracks, capture.frames, capture.json_path);
    if (!problems.empty()) throw ValidationError(problems);
    animation.grid_rows = tracks.rows;
    animation.grid_cols = tracks.cols;
    if (animation.fps == 0.0) animation.fps = capture.fps;
    return animation;
}

std::optional<VertexAnimation> read_capture_truth_positions(const Capture& capture) {
    const std::string path = capture.resolve("truth/positions.exr");
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    VertexAnimation truth = read_vertex_animation(path);
    if (truth.frame_count != capture.frames.count)
        throw ValidationError({Problem{Problem::Severity::error, path, "data window",
                                       std::to_string(truth.frame_count) + " rows (frames) but the capture has " +
                                           std::to_string(capture.frames.count) + " frames",
                                       "the truth must have one row per capture frame"}});
    const std::string truth_json = capture.resolve("truth/truth.json");
    if (fs::exists(truth_json, ec)) {
        Diagnostics diag(truth_json);
        if (std::optional<nlohmann::json> document = parse_json_text(read_text_file(truth_json), diag)) {
            JsonView root(*document, "", diag);
            if (!root.json().is_object()) {
                diag.error("/", std::string("truth.json holds ") + root.json().type_name() + ", not a JSON object",
                           "write {\"rows\": R, \"cols\": C, ...} as the capture rig does");
            } else if (root.has("rows") || root.has("cols")) {
                // Both or neither: one alone would leave the grid half-known.
                const std::optional<std::int64_t> rows = root.integer("rows", 1, kMaxVertexAnimationVertices);
                const std::optional<std::int64_t> cols = root.integer("cols", 1, kMaxVertexAnimationVertices);
                if (rows && cols) {
                    if (*rows * *cols != truth.vertex_count)
                        diag.error("/rows", "grid " + std::to_string(*rows) + " x " + std::to_string(*cols) +
                                                " does not match the " + std::to_string(truth.vertex_count) +
                                                " columns of positions.exr",
                                   "fix rows and cols");
                    else {
                        truth.grid_rows = static_cast<int>(*rows);
                        truth.grid_cols = static_cast<int>(*cols);
                    }
                }
            }
        }
        diag.throw_if_errors();
    }
    if (truth.fps == 0.0) truth.fps = capture.fps;
    return truth;
}

}  // namespace flowvid::formats
