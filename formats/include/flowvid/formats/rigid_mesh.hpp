#pragma once
// The shape of a tossed rigid body: a triangle mesh read from a glTF 2.0
// binary (.glb), in metres, in the body frame. Vertex coordinates are taken as
// stored: no glTF y-up to z-up conversion (the capture contract says the mesh
// frame *is* the body frame). Node transforms of the default scene are applied,
// so a mesh exported under a translated or rotated node lands where the file
// places it; the captures' meshes have identity nodes.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

struct TriangleMesh {
    std::vector<Eigen::Vector3d> vertices_m;      // #V positions, metres, body frame
    std::vector<std::array<int, 3>> triangles;    // #F triangles, indices into vertices_m (glTF winding)

    bool operator==(const TriangleMesh& other) const {
        return vertices_m == other.vertices_m && triangles == other.triangles;
    }
};

// Reads a .glb: checks the GLB container (magic, version 2, chunk lengths), lets
// tinygltf parse it, then checks every accessor used (in range of its buffer
// view and buffer, float VEC3 positions, integer scalar indices below the
// vertex count, finite values) and merges the triangle primitives of every mesh
// node of the default scene (every root node when no scene is given; every
// mesh when there are no nodes). Throws IoError (cannot read) or
// ValidationError naming the glTF field (JSON pointer such as
// "/accessors/1") of every problem.
TriangleMesh read_rigid_mesh(const std::string& path, std::vector<Problem>* warnings = nullptr);

// The same from bytes in memory (fuzz targets); `name` names the file in problems.
std::optional<TriangleMesh> parse_rigid_mesh_glb(const std::string& bytes, Diagnostics& diagnostics);

// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_rigid_mesh_file(const std::string& path, Strictness strictness);

// Volume (m^3, signed: positive for outward-facing closed meshes) and centroid
// of the enclosed solid, by the divergence theorem. Meaningful for closed meshes.
struct MeshVolume {
    double volume_m3 = 0.0;
    Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
};
MeshVolume mesh_volume(const TriangleMesh& mesh);

// For `flowvid info --json`: counts, bounding box, volume, centroid.
nlohmann::json summarize_rigid_mesh(const TriangleMesh& mesh);

}  // namespace flowvid::formats
