#pragma once
// Vertex-animation textures (*.exr): the positions of every vertex of a mesh at
// every frame, as a float32 RGB OpenEXR image with one row per frame and one
// column per vertex; R, G, B = world x, y, z in metres. This is the layout of
// the captures' truth/positions.exr and of flowvid's simulated sequences, so a
// result and its ground truth compare column by column. See
// formats/specs/vertex_animation.md.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kVertexAnimationFormatName = "flowvid.vertex_animation";
inline constexpr FormatVersion kVertexAnimationFormatVersion{1, 0};

// Sizes above these are refused before anything is allocated: a corrupt or
// hostile header must not make the reader ask for gigabytes.
inline constexpr std::int64_t kMaxVertexAnimationFrames = 1'000'000;
inline constexpr std::int64_t kMaxVertexAnimationVertices = 16'000'000;
inline constexpr std::int64_t kMaxVertexAnimationSamples = std::int64_t(1) << 28;  // frames x vertices

// Simulated positions are complete; measured ones (a capture's tracks) may
// have gaps: NaN in all three channels where a point was not seen.
enum class MissingPoints { refuse, allow_nan };

struct VertexAnimation {
    int frame_count = 0;
    int vertex_count = 0;
    // `frame_count * vertex_count` positions, metres, frame-major:
    // positions_m[f * vertex_count + v] is vertex v at the f-th stored frame.
    std::vector<Eigen::Vector3f> positions_m;
    // Set when the vertices are a regular uv grid: vertex r * grid_cols + c,
    // row 0 at v = 0, column 0 at u = 0 (the captures' swatch layout).
    std::optional<int> grid_rows;
    std::optional<int> grid_cols;
    // Frames per second; 0 when the file does not say (the captures' truth
    // files do not: take the capture's fps).
    double fps = 0.0;

    const Eigen::Vector3f& position(int frame, int vertex) const {
        return positions_m[static_cast<std::size_t>(frame) * static_cast<std::size_t>(vertex_count) +
                           static_cast<std::size_t>(vertex)];
    }
    Eigen::Vector3f& position(int frame, int vertex) {
        return positions_m[static_cast<std::size_t>(frame) * static_cast<std::size_t>(vertex_count) +
                           static_cast<std::size_t>(vertex)];
    }
    bool operator==(const VertexAnimation& other) const;
};

// Reads and validates a file; throws flowvid::IoError (cannot open) or
// ValidationError (every problem: missing or non-float R/G/B, NaN or infinite
// values, implausible size, another major flowvid.version, corrupt data).
// Files without flowvid attributes (e.g. a capture's truth/positions.exr) are
// accepted. Warnings (newer minor version, extra channels) go to `warnings`.
// With MissingPoints::allow_nan a point that is NaN in R, G and B is a gap
// (infinite values and partly-NaN points are still refused).
VertexAnimation read_vertex_animation(const std::string& path, std::vector<Problem>* warnings = nullptr,
                                      MissingPoints missing = MissingPoints::refuse);

// The same from bytes in memory (fuzz targets, embedded data); `name` is used
// as the file name in problems.
VertexAnimation read_vertex_animation_from_memory(const std::string& bytes, const std::string& name,
                                                  std::vector<Problem>* warnings = nullptr);

// Validates, then writes atomically: float32 R, G, B, ZIP compression
// (lossless), header attributes flowvid.format, flowvid.version, flowvid.fps
// (when fps > 0) and flowvid.grid_rows / flowvid.grid_cols (when set).
// Throws ValidationError (sizes disagree, NaN, bad grid) leaving any previous
// file untouched, or IoError.
void write_vertex_animation(const std::string& path, const VertexAnimation& animation,
                            MissingPoints missing = MissingPoints::refuse);

// Every problem of the animation itself (sizes, finiteness, grid), reported
// against `file`. Used by the writer; useful before handing data to others.
std::vector<Problem> check_vertex_animation(const VertexAnimation& animation, const std::string& file,
                                            MissingPoints missing = MissingPoints::refuse);

// Every problem of a file, for `flowvid validate` and the fuzz targets (never
// throws on bad content). Strict: unknown flowvid.* attributes and extra
// channels are errors instead of warnings.
std::vector<Problem> validate_vertex_animation_file(const std::string& path, Strictness strictness,
                                                    MissingPoints missing = MissingPoints::refuse);
std::vector<Problem> validate_vertex_animation_bytes(const std::string& bytes, const std::string& name,
                                                     Strictness strictness);

// For `flowvid info --json`: counts, fps, grid, bounding box (m) and the
// largest displacement of any vertex from its first-frame position (m).
nlohmann::json summarize_vertex_animation(const VertexAnimation& animation);

}  // namespace flowvid::formats
