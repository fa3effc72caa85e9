#pragma once
// A garment or swatch as polygons (quads stay quads), for mapping a fabric
// preset onto a mesh's cloth settings (flowvid convert --mesh). Read from
// Wavefront OBJ (v and f lines; coordinates in metres, as Blender imports OBJ
// at scale 1) or from a glTF binary (.glb, through read_rigid_mesh: glTF
// stores triangles, so its faces are triangles).

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

struct PolygonMesh {
    std::vector<Eigen::Vector3d> vertices_m;  // #V positions, metres
    std::vector<std::vector<int>> faces;      // #F polygons (3 or more corners), indices into vertices_m
};

// OBJ text: `v x y z`, `f a b c ...` (also a/t/n forms, negative indices
// counting back from the last vertex); vt, vn, o, g, s, usemtl, mtllib are
// ignored, lines (`l`) are ignored with a warning. Problems name the line.
std::optional<PolygonMesh> parse_obj_mesh(const std::string& text, Diagnostics& diagnostics);

// .obj or .glb by extension (content for .glb: its magic). Throws IoError or
// ValidationError naming the file, line or glTF field.
PolygonMesh read_polygon_mesh(const std::string& path, std::vector<Problem>* warnings = nullptr);

}  // namespace flowvid::formats
