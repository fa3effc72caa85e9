#pragma once
// Simulated motion export (*.glb): a swatch or garment animation (triangle
// mesh + per-frame vertex positions) as glTF 2.0 binary, for Blender's glTF
// importer and any other glTF viewer. Every frame is one morph target and a
// STEP-interpolated weights animation switches exactly one target on per
// frame. flowvid's world is +z up, glTF's is +y up: a flowvid point (x, y, z)
// is stored as glTF (x, z, -y). The file says what it is in
// asset.extras.flowvid ("format": "flowvid.motion", "version": "1.0").
// See formats/specs/motion_gltf.md.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kMotionGltfFormatName = "flowvid.motion";
inline constexpr FormatVersion kMotionGltfFormatVersion{1, 0};

// One-hot weights grow with frames^2 (every key lists every target), so long
// sequences belong in the vertex-animation EXR instead.
inline constexpr int kMaxMotionGltfFrames = 4096;
inline constexpr long long kMaxMotionGltfVertexFrames = 1LL << 26;  // vertices x frames

struct MeshAnimation {
    std::string name = "flowvid_motion";  // node, mesh and animation name in the file
    double fps = 30.0;                    // frames per second; frame k is at time k / fps
    // #F triangles, vertex indices, counter-clockwise seen from the front.
    std::vector<std::array<int, 3>> triangles;
    // #frames x #V world positions, metres, flowvid convention (+z up).
    std::vector<std::vector<Eigen::Vector3f>> frames_positions_m;
    // #V texture coordinates or empty; (0, 0) is the bottom-left corner of the
    // swatch as hung, u along the warp (capture.md). Stored as glTF (u, 1 - v).
    std::vector<Eigen::Vector2f> uv;

    int frame_count() const { return static_cast<int>(frames_positions_m.size()); }
    int vertex_count() const { return frames_positions_m.empty() ? 0 : static_cast<int>(frames_positions_m[0].size()); }
    bool operator==(const MeshAnimation&) const = default;
};

// flowvid world (+z up) <-> glTF (+y up); exact (only a swap and a negation).
inline Eigen::Vector3f flowvid_to_gltf(const Eigen::Vector3f& p) { return {p.x(), p.z(), -p.y()}; }
inline Eigen::Vector3f gltf_to_flowvid(const Eigen::Vector3f& p) { return {p.x(), -p.z(), p.y()}; }

// Every problem of an in-memory animation (the writer's check), fields named
// after the struct members, e.g. "frames_positions_m[3][17]".
void check_mesh_animation(const MeshAnimation& animation, Diagnostics& diagnostics);

// Reads and validates a .glb written by write_motion_gltf; throws
// ValidationError (every problem, fields are JSON pointers into the glTF such
// as "/accessors/4" or "/asset/extras/flowvid/fps") or IoError. Positions come
// back within float32 rounding of the written ones: each coordinate within
// 2^-24 * (|p| + |p - p0|), where p0 is the vertex at frame 0 (<= 1e-6 m for
// coordinates within 5 m of the origin); frame 0 and triangles are exact, uv
// within 2^-24.
MeshAnimation read_motion_gltf(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates, then writes atomically. Throws ValidationError (NaN, bad indices,
// ragged frames, too large) leaving any previous file untouched, or IoError.
void write_motion_gltf(const std::string& path, const MeshAnimation& animation);
// Every problem of a file, for `flowvid validate` and the fuzz targets (never
// throws on bad content). Strict: unknown keys in asset.extras.flowvid are errors.
std::vector<Problem> validate_motion_gltf_file(const std::string& path, Strictness strictness);
// For `flowvid info --json`: counts, fps, duration, bounding box (m, flowvid
// axes) and the largest displacement of any vertex from frame 0 (m).
nlohmann::json summarize_motion_gltf(const MeshAnimation& animation);

}  // namespace flowvid::formats
