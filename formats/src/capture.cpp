// capture.json version 1: the camera model, paths inside the capture folder,
// the round trip to JSON and the summary. Parsing and validation are in
// capture_read.cpp, loading frames in capture_frames.cpp.

#include "flowvid/formats/capture.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include "capture_json.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>

namespace flowvid::formats {
namespace fs = std::filesystem;

using namespace capture_json;

// ---- CameraModel ------------------------------------------------------------

Eigen::Vector3d CameraModel::to_camera(const Eigen::Vector3d& world) const {
    return camera_from_world.topLeftCorner<3, 3>() * world + camera_from_world.topRightCorner<3, 1>();
}

Eigen::Vector2d CameraModel::project_camera_point(const Eigen::Vector3d& p) const {
    if (!(p.z() > 0.0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
    const double x = p.x() / p.z();
    const double y = p.y() / p.z();
    const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    const double yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    return {K(0, 0) * xd + K(0, 1) * yd + K(0, 2), K(1, 1) * yd + K(1, 2)};
}

Eigen::Vector2d CameraModel::project(const Eigen::Vector3d& world) const {
    return project_camera_point(to_camera(world));
}

Eigen::Vector3d CameraModel::ray_camera(const Eigen::Vector2d& pixel) const {
    // Distorted normalised coordinates (K^-1 with skew).
    const double yd = (pixel.y() - K(1, 2)) / K(1, 1);
    const double xd = (pixel.x() - K(0, 2) - K(0, 1) * yd) / K(0, 0);
    if (!has_distortion()) return {xd, yd, 1.0};
    const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
    double x = xd, y = yd;
    for (int iteration = 0; iteration < 50; ++iteration) {
        const double r2 = x * x + y * y;
        const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        const double dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        const double dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        const double next_x = (xd - dx) / radial, next_y = (yd - dy) / radial;
        const bool settled = std::abs(next_x - x) + std::abs(next_y - y) < 1e-14;
        x = next_x;
        y = next_y;
        if (settled) break;
    }
    return {x, y, 1.0};
}

Eigen::Vector3d CameraModel::centre_world() const {
    const Eigen::Matrix3d R = camera_from_world.topLeftCorner<3, 3>();
    const Eigen::Vector3d centre = -R.transpose() * camera_from_world.topRightCorner<3, 1>();
    return centre + Eigen::Vector3d::Zero();  // turns -0 into 0 for readable summaries
}

bool CameraModel::has_distortion() const {
    return std::any_of(dist.begin(), dist.end(), [](double d) { return d != 0.0; });
}

// ---- Capture paths ----------------------------------------------------------

namespace {
std::atomic<bool> g_outside_paths_allowed{false};  // set once from the command line
}  // namespace

void allow_capture_paths_outside_folder(bool allowed) { g_outside_paths_allowed = allowed; }
bool capture_paths_outside_folder_allowed() { return g_outside_paths_allowed; }

bool path_stays_inside_folder(const std::string& relative) {
    const fs::path path(relative);
    if (path.is_absolute() || path.has_root_name() || path.has_root_directory()) return false;
    int depth = 0;
    for (const fs::path& part : path.lexically_normal()) {
        if (part == "..") {
            if (--depth < 0) return false;
        } else if (part != "." && !part.empty()) {
            ++depth;
        }
    }
    return true;
}

std::string Capture::resolve(const std::string& relative) const {
    const fs::path path(relative);
    if (path.is_absolute()) return path.string();
    return (fs::path(folder.empty() ? "." : folder) / path).string();
}

std::string Capture::clip_path() const {
    if (!json_path.empty()) return folder;
    return resolve(frames.is_video() ? frames.video : frames.pattern);
}

std::string Capture::frame_path(int number) const {
    if (frames.is_video()) return resolve(frames.video);
    std::optional<std::string> name = format_frame_pattern(frames.pattern, number);
    return name ? resolve(*name) : std::string();
}

std::string Capture::mask_path(int number) const {
    if (masks.empty()) return {};
    std::optional<std::string> name = format_frame_pattern(masks, number);
    return name ? resolve(*name) : std::string();
}

std::optional<std::string> format_frame_pattern(const std::string& pattern, int number) {
    std::string out;
    int conversions = 0;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        const char c = pattern[i];
        if (c != '%') {
            out += c;
            continue;
        }
        if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
            out += '%';
            ++i;
            continue;
        }
        std::size_t j = i + 1;
        bool zero_pad = false;
        if (j < pattern.size() && pattern[j] == '0') {
            zero_pad = true;
            ++j;
        }
        int width = 0, digits = 0;
        while (j < pattern.size() && pattern[j] >= '0' && pattern[j] <= '9') {
            width = width * 10 + (pattern[j] - '0');
            if (++digits > 2) return std::nullopt;
            ++j;
        }
        if (j >= pattern.size() || pattern[j] != 'd' || width > 32) return std::nullopt;
        std::string digits_text = std::to_string(number < 0 ? -static_cast<long long>(number) : number);
        const std::string sign = number < 0 ? "-" : "";
        const std::size_t used = digits_text.size() + sign.size();
        if (used < static_cast<std::size_t>(width)) {
            const std::size_t pad = static_cast<std::size_t>(width) - used;
            out += zero_pad ? sign + std::string(pad, '0') + digits_text : std::string(pad, ' ') + sign + digits_text;
        } else {
            out += sign + digits_text;
        }
        ++conversions;
        i = j;
    }
    if (conversions != 1) return std::nullopt;
    return out;
}

std::optional<int> first_frame_of_pattern(const std::string& pattern) {
    std::error_code ec;
    for (int first : {0, 1}) {
        const std::optional<std::string> frame = format_frame_pattern(pattern, first);
        if (frame && fs::is_regular_file(*frame, ec)) return first;
    }
    return std::nullopt;
}

nlohmann::json capture_to_json(const Capture& capture) {
    auto camera_json = [](const CameraModel& camera, bool always_dist) {
        nlohmann::json json = {{"width", camera.width},
                               {"height", camera.height},
                               {"K", matrix_json(camera.K)},
                               {"camera_from_world", matrix_json(camera.camera_from_world)}};
        if (always_dist || camera.has_distortion())
            json["dist"] = nlohmann::json(std::vector<double>(camera.dist.begin(), camera.dist.end()));
        return json;
    };
    nlohmann::json document = {{"format", kCaptureFormatName}, {"version", capture.version}, {"kind", capture.kind},
                               {"fps", capture.fps}};
    nlohmann::json frames = {{"first", capture.frames.first}, {"count", capture.frames.count}};
    if (capture.frames.is_video()) frames["video"] = capture.frames.video;
    else frames["pattern"] = capture.frames.pattern;
    document["frames"] = frames;
    if (!capture.background.empty()) document["background"] = capture.background;
    if (!capture.masks.empty()) document["masks"] = capture.masks;
    if (capture.camera) document["camera"] = camera_json(*capture.camera, true);
    if (capture.world) {
        nlohmann::json world = {{"gravity", nullptr}};
        if (capture.world->gravity_m_per_s2) world["gravity"] = vector_json(*capture.world->gravity_m_per_s2);
        if (!capture.world->note.empty()) world["note"] = capture.world->note;
        document["world"] = world;
    }
    if (capture.projector) {
        nlohmann::json projector = camera_json(capture.projector->camera, false);
        projector["pattern"] = {{"type", capture.projector->pattern.type},
                                {"axis", capture.projector->pattern.axis},
                                {"period_px", capture.projector->pattern.period_px}};
        document["projector"] = projector;
    }
    if (capture.swatch) {
        nlohmann::json pins = nlohmann::json::array();
        for (const Pin& pin : capture.swatch->pins) {
            nlohmann::json positions = nlohmann::json::array();
            for (const Eigen::Vector3d& p : pin.positions_m) positions.push_back(vector_json(p));
            pins.push_back({{"uv", vector_json(pin.uv)}, {"positions", positions}});
        }
        document["swatch"] = {{"width_m", capture.swatch->width_m},
                              {"height_m", capture.swatch->height_m},
                              {"mass_kg", capture.swatch->mass_kg},
                              {"initial", capture.swatch->initial},
                              {"pins", pins}};
    }
    if (capture.tracks)
        document["tracks"] = {{"file", capture.tracks->file}, {"rows", capture.tracks->rows}, {"cols", capture.tracks->cols}};
    if (capture.rigid)
        document["rigid"] = {{"mesh", capture.rigid->mesh},
                             {"mass_kg", capture.rigid->mass_kg},
                             {"center_of_mass", vector_json(capture.rigid->center_of_mass_m)},
                             {"inertia_body", matrix_json(capture.rigid->inertia_body_kg_m2)}};
    if (!capture.flowlines.empty()) document["flowlines"] = capture.flowlines;
    if (!capture.source.is_null()) document["source"] = capture.source;
    return document;
}

nlohmann::json summarize_capture(const Capture& capture) {
    nlohmann::json summary = {{"format", kCaptureFormatName},
                              {"version", capture.version},
                              {"kind", capture.kind},
                              {"folder", capture.folder},
                              {"fps", capture.fps},
                              {"capture_json_sha256", capture.capture_json_sha256}};
    nlohmann::json frames = {{"first", capture.frames.first},
                             {"last", capture.frames.last()},
                             {"count", capture.frames.count},
                             {"duration_s", capture.fps > 0.0 ? capture.frames.count / capture.fps : 0.0}};
    if (capture.frames.is_video()) frames["video"] = capture.frames.video;
    else frames["pattern"] = capture.frames.pattern;
    summary["frames"] = frames;
    summary["background"] = !capture.background.empty();
    summary["masks"] = !capture.masks.empty();
    if (capture.camera) {
        const CameraModel& c = *capture.camera;
        summary["camera"] = {{"width", c.width},
                             {"height", c.height},
                             {"fx_px", c.K(0, 0)},
                             {"fy_px", c.K(1, 1)},
                             {"cx_px", c.K(0, 2)},
                             {"cy_px", c.K(1, 2)},
                             {"distortion", c.has_distortion()},
                             {"centre_world_m", vector_json(c.centre_world())}};
    }
    if (capture.world)
        summary["gravity_m_per_s2"] =
            capture.world->gravity_m_per_s2 ? vector_json(*capture.world->gravity_m_per_s2) : nlohmann::json(nullptr);
    if (capture.projector)
        summary["projector"] = {{"width", capture.projector->camera.width},
                                {"height", capture.projector->camera.height},
                                {"pattern", capture.projector->pattern.type},
                                {"axis", capture.projector->pattern.axis},
                                {"period_px", capture.projector->pattern.period_px}};
    if (capture.swatch) {
        nlohmann::json pins = nlohmann::json::array();
        for (const Pin& pin : capture.swatch->pins) {
            double travel = 0.0;
            for (const Eigen::Vector3d& p : pin.positions_m)
                travel = std::max(travel, (p - pin.positions_m.front()).norm());
            pins.push_back({{"uv", vector_json(pin.uv)}, {"max_travel_m", travel}});
        }
        summary["swatch"] = {{"width_m", capture.swatch->width_m},
                             {"height_m", capture.swatch->height_m},
                             {"mass_kg", capture.swatch->mass_kg},
                             {"areal_density_kg_per_m2",
                              capture.swatch->mass_kg / (capture.swatch->width_m * capture.swatch->height_m)},
                             {"initial", capture.swatch->initial},
                             {"pins", pins}};
    }
    if (capture.rigid) {
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(capture.rigid->inertia_body_kg_m2);
        nlohmann::json rigid = {{"mesh", capture.rigid->mesh},
                                {"mass_kg", capture.rigid->mass_kg},
                                {"center_of_mass_m", vector_json(capture.rigid->center_of_mass_m)},
                                {"principal_moments_kg_m2", vector_json(solver.eigenvalues())}};
        if (!capture.rigid->body_mesh.triangles.empty())
            rigid["mesh_summary"] = summarize_rigid_mesh(capture.rigid->body_mesh);
        summary["rigid"] = rigid;
    }
    if (!capture.flowlines.empty()) summary["flowlines"] = capture.flowlines;
    if (capture.tracks) {
        nlohmann::json tracks = {{"file", capture.tracks->file}, {"rows", capture.tracks->rows}, {"cols", capture.tracks->cols}};
        try {
            const VertexAnimation animation = *read_capture_tracks(capture);
            const auto seen = std::count_if(animation.positions_m.begin(), animation.positions_m.end(),
                                            [](const Eigen::Vector3f& p) { return p.allFinite(); });
            tracks["seen_share"] = animation.positions_m.empty()
                                       ? 0.0
                                       : static_cast<double>(seen) / static_cast<double>(animation.positions_m.size());
        } catch (const Error&) {
            // validate reports why; the summary just lacks the share.
        }
        summary["tracks"] = tracks;
    }
    if (!capture.source.is_null()) summary["source"] = capture.source;
    std::error_code ec;
    summary["has_truth"] = fs::is_directory(capture.resolve("truth"), ec);
    return summary;
}

}  // namespace flowvid::formats
