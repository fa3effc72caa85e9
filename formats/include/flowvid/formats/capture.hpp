#pragma once
// Capture folders: one recorded experiment (frames, camera and projector
// calibration, what is known about the swatch or rigid body), as described by
// ../shared/spec/capture.md, capture.json version 1. Our reader's notes are in
// formats/specs/capture.md.
//
// Conventions: SI units; world frame metres, right-handed, +z up; cameras
// follow OpenCV (pixel (0,0) is the centre of the top-left pixel, x right,
// y down, the camera looks along +z; distortion k1, k2, p1, p2, k3).
// Frame numbers are 1-based as in capture.json: first .. first + count - 1.
//
// Public headers do not expose OpenCV: images come back as flowvid::formats::Image.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/formats/rigid_mesh.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kCaptureFormatName = "flowvid.capture";
inline constexpr int kCaptureFormatVersion = 1;  // an integer in capture.json, unlike other flowvid files

// The kinds of capture.json version 1.
inline constexpr const char* kCaptureKinds[] = {"cloth.static", "cloth.waving", "rigid.toss", "video.flow"};

// How far validation goes beyond capture.json itself.
enum class CaptureFileChecks {
    none,     // capture.json only (fuzzing the JSON, tests of the schema)
    exist,    // + every referenced file exists (first and last frame, masks, background, mesh, video, flow lines)
    content,  // + image and video sizes match the camera, the video has enough frames, the mesh parses
};

// A pinhole camera with OpenCV's distortion model.
struct CameraModel {
    int width = 0;   // pixels
    int height = 0;  // pixels
    Eigen::Matrix3d K = Eigen::Matrix3d::Identity();   // [[fx, s, cx], [0, fy, cy], [0, 0, 1]], pixels
    std::array<double, 5> dist{};                      // k1, k2, p1, p2, k3 (all zero = no distortion)
    Eigen::Matrix4d camera_from_world = Eigen::Matrix4d::Identity();  // rigid, metres

    // World point (m) -> camera coordinates (m, OpenCV: x right, y down, z forward).
    Eigen::Vector3d to_camera(const Eigen::Vector3d& world) const;
    // World point (m) -> pixel (x, y), distortion applied. Points at or behind
    // the camera plane (z <= 0) give NaN.
    Eigen::Vector2d project(const Eigen::Vector3d& world) const;
    // The same for a point already in camera coordinates.
    Eigen::Vector2d project_camera_point(const Eigen::Vector3d& camera_point) const;
    // Pixel (x, y) -> the normalised camera ray (x_n, y_n, 1) through it:
    // the inverse of project_camera_point, distortion removed by fixed-point
    // iteration (exact to ~1e-12 for the distortions real lenses have).
    Eigen::Vector3d ray_camera(const Eigen::Vector2d& pixel) const;
    // The optical centre in world coordinates (m).
    Eigen::Vector3d centre_world() const;
    bool has_distortion() const;
};

// The stripe pattern a projector casts on cloth.
struct StripePattern {
    std::string type = "sine_stripes";  // the only type of version 1
    std::string axis = "rows";          // "rows": intensity varies with the projector row; "columns": with the column
    double period_px = 0.0;             // projector pixels per stripe period
};

struct Projector {
    CameraModel camera;  // same model as the camera; dist optional in capture.json (zero when absent)
    StripePattern pattern;
};

// A pinned point of the swatch: its uv on the swatch and its world position
// at every frame (positions_m[i] is frame first + i; linear in between).
struct Pin {
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // (0,0) bottom-left as hung, (1,1) top-right
    std::vector<Eigen::Vector3d> positions_m;
};

struct SwatchSpec {
    double width_m = 0.0;   // along u (warp)
    double height_m = 0.0;  // along v (weft)
    double mass_kg = 0.0;
    std::string initial = "equilibrium";  // at frame 'first' the swatch hangs at rest under the pins
    std::vector<Pin> pins;
};

// cloth.*, optional: 3D positions of swatch points measured by other means
// (motion-capture markers, a multi-view or structured-light reconstruction).
// The file has the layout of truth/positions.exr: one row per frame, one
// column per point of a rows x cols uv grid (point r*cols + c at
// u = c/(cols-1), v = r/(rows-1)), world metres, NaN where a point was not seen.
struct TracksSpec {
    std::string file;  // relative to the capture folder
    int rows = 0;
    int cols = 0;
};

struct RigidSpec {
    std::string mesh;  // path as written in capture.json, relative to the capture folder
    double mass_kg = 0.0;
    Eigen::Vector3d center_of_mass_m = Eigen::Vector3d::Zero();          // body (mesh) frame
    Eigen::Matrix3d inertia_body_kg_m2 = Eigen::Matrix3d::Identity();   // about the centre of mass, mesh axes
    // The mesh itself, filled by read_capture (and by parse_capture with
    // CaptureFileChecks::content); empty otherwise.
    TriangleMesh body_mesh;
};

struct WorldSpec {
    // Metres per second squared in world coordinates; nullopt = unknown (e.g.
    // rigid.toss captures, where world = camera frame and the fit finds gravity).
    std::optional<Eigen::Vector3d> gravity_m_per_s2;
    std::string note;  // free text ("note" key), kept for round trips
};

struct FramesSpec {
    std::string pattern;  // printf-style, one integer conversion, e.g. "frames/%06d.png" ...
    std::string video;    // ... or one video file, e.g. "clip.mp4" (first = 1 is its first frame)
    int first = 1;
    int count = 0;

    bool is_video() const { return !video.empty(); }
    int last() const { return first + count - 1; }
};

struct Capture {
    std::string folder;     // the capture folder (as given, without capture.json)
    std::string json_path;  // folder/capture.json
    int version = kCaptureFormatVersion;
    std::string kind;       // one of kCaptureKinds
    double fps = 0.0;
    FramesSpec frames;
    std::string background;  // relative path, empty when absent
    std::string masks;       // pattern like frames.pattern, empty when absent
    std::optional<CameraModel> camera;     // required except for video.flow
    std::optional<WorldSpec> world;        // required except for video.flow
    std::optional<Projector> projector;    // cloth.*
    std::optional<SwatchSpec> swatch;      // cloth.*
    std::optional<TracksSpec> tracks;      // cloth.*, optional
    std::optional<RigidSpec> rigid;        // rigid.toss
    std::string flowlines;                 // video.flow: SVG path, relative
    nlohmann::json source;                 // free-form object, null when absent
    std::string capture_json_sha256;       // of capture.json's bytes, 64 lower-case hex digits

    bool is_cloth() const { return kind == "cloth.static" || kind == "cloth.waving"; }
    bool is_rigid() const { return kind == "rigid.toss"; }
    bool is_video() const { return kind == "video.flow"; }

    // A path of capture.json resolved against the folder (absolute paths stay).
    std::string resolve(const std::string& relative) const;
    // Where the clip can be opened again (what a particle bank records): the
    // folder of a capture read from capture.json, else the video file or the
    // frame pattern.
    std::string clip_path() const;
    // Full path of frame `number` (pattern captures) and of its mask (when masks).
    std::string frame_path(int number) const;
    std::string mask_path(int number) const;
};

// Formats a printf-style frame pattern ("frames/%06d.png", 7 -> "frames/000007.png").
// Accepts exactly one %d, %Nd or %0Nd (N <= 32) and %% escapes; nullopt otherwise.
std::optional<std::string> format_frame_pattern(const std::string& pattern, int number);
// The number a frame pattern's sequence starts at: 0 or 1, whichever file
// exists (0 first); nullopt when neither does or the pattern is not one.
std::optional<int> first_frame_of_pattern(const std::string& pattern);

// Validates a parsed capture.json whose folder is `folder`; every problem goes
// to `diagnostics` (whose file should be the capture.json path).
std::optional<Capture> parse_capture(const nlohmann::json& document, const std::string& folder,
                                     Diagnostics& diagnostics, Strictness strictness = Strictness::lenient,
                                     CaptureFileChecks checks = CaptureFileChecks::content);

// The parsed content as capture.json (version 1): parse_capture of it gives
// the same capture. No writer is provided: captures are made by capture rigs.
nlohmann::json capture_to_json(const Capture& capture);

// Paths in capture.json must stay inside the capture folder (capture.md); a
// reader refuses "../x" and absolute paths unless the process allows them
// (`flowvid --allow-outside-paths`, for captures the user trusts). Frame
// patterns are checked as written ("frames/%06d.png").
void allow_capture_paths_outside_folder(bool allowed);
bool capture_paths_outside_folder_allowed();
bool path_stays_inside_folder(const std::string& relative);

// `path` is the capture folder or its capture.json. Checks everything
// (CaptureFileChecks::content) and throws ValidationError listing every problem,
// or IoError when capture.json cannot be read. Warnings go to `warnings`.
Capture read_capture(const std::string& path, std::vector<Problem>* warnings = nullptr);
// read_capture that also checks the kind: throws ValidationError naming
// capture.json and /kind when it is not one of `kinds` (`needed_by`, e.g.
// "flowvid diagnose", says who needs it in the message).
Capture read_capture_of_kind(const std::string& path, const std::vector<std::string>& kinds,
                             const std::string& needed_by, std::vector<Problem>* warnings = nullptr);

// Every problem of a capture folder (or capture.json), for `flowvid validate`
// and the fuzz targets; never throws on bad content.
std::vector<Problem> validate_capture_folder(const std::string& path, Strictness strictness = Strictness::strict,
                                             CaptureFileChecks checks = CaptureFileChecks::content);

// For `flowvid info --json`.
nlohmann::json summarize_capture(const Capture& capture);

// EVALUATION ONLY: the ground-truth vertex positions truth/positions.exr of a
// cloth capture, with the grid from truth/truth.json and the capture's fps.
// A fit must never call this: truth/ is not part of what a fit reads (see the
// capture contract). Returns nullopt when the capture has no truth/positions.exr;
// throws ValidationError when it is invalid or its row count is not frames.count.
std::optional<VertexAnimation> read_capture_truth_positions(const Capture& capture);

// A cloth capture's measured 3D tracks (`tracks` in capture.json), with the
// grid and the capture's fps set; NaN points are gaps. nullopt when the
// capture declares none. Throws IoError / ValidationError naming the file and
// the capture.json field when the file is unreadable or does not match the
// grid or the frame count. Unlike truth/, a fit may read these.
std::optional<VertexAnimation> read_capture_tracks(const Capture& capture);

// ---- Frames -----------------------------------------------------------------

// Pixels of one image, row-major from the top row, channels interleaved (RGB
// or 1 channel). Values in [0, 1] *as stored*: 8- and 16-bit files (PNG, JPEG,
// video) are divided by 255 / 65535 and stay sRGB-encoded (no linearisation);
// float EXR values are copied unchanged (linear, not clamped).
struct Image {
    enum class Encoding { srgb, linear };
    int width = 0;
    int height = 0;
    int channels = 0;
    Encoding encoding = Encoding::srgb;
    std::vector<float> pixels;  // width * height * channels

    float at(int x, int y, int channel = 0) const {
        return pixels[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) *
                          static_cast<std::size_t>(channels) +
                      static_cast<std::size_t>(channel)];
    }
};

// Image size from the file header only (PNG, JPEG, EXR, anything OpenImageIO
// reads). Throws IoError naming the file when it cannot be read.
struct ImageInfo {
    int width = 0;
    int height = 0;
    int channels = 0;
};
ImageInfo read_image_info(const std::string& path);

// Decodes an image: RGB when `channels` is 3 (gray is replicated, alpha
// dropped), one channel when 1 (RGB averaged). Throws IoError naming the file.
Image load_image(const std::string& path, int channels = 3);

struct VideoInfo {
    int width = 0;
    int height = 0;
    int frame_count = 0;  // as the container reports it
    double fps = 0.0;
};
VideoInfo read_video_info(const std::string& path);

// Loads the frames, masks and background of a capture. Video frames are
// decoded sequentially (exact, whatever the codec's key-frame spacing); going
// back re-opens the file, and the last few frames decoded are cached, so
// playing forward or re-reading neighbours is cheap. Not thread-safe: use one
// FrameSource per thread.
class FrameSource {
public:
    explicit FrameSource(const Capture& capture);
    ~FrameSource();
    FrameSource(FrameSource&&) noexcept;
    FrameSource& operator=(FrameSource&&) noexcept;
    FrameSource(const FrameSource&) = delete;
    FrameSource& operator=(const FrameSource&) = delete;

    int first() const;
    int count() const;
    int last() const;
    // Expected size: the camera's, or for a video without camera the clip's.
    int width() const;
    int height() const;

    // Frame `number` (first..last) as RGB. Throws std::out_of_range for a number
    // outside the capture, IoError when the file cannot be decoded, and
    // ValidationError when its size is not the expected one.
    Image frame(int number);
    bool has_masks() const;
    // Mask of frame `number`, one channel, 1 = object.
    Image mask(int number);
    bool has_background() const;
    Image background();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

}  // namespace flowvid::formats
