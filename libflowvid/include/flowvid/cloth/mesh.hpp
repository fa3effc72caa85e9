#pragma once
// Cloth meshes: triangles with rest-state material coordinates (uv in metres),
// the rectangular swatch of the captures, and sampling of a simulated surface
// at a regular uv grid.

#include <Eigen/Core>

#include <array>
#include <vector>

namespace flowvid::cloth {

// A triangle mesh in its rest state. Material coordinates are lengths in the
// flat fabric: u along the warp, v along the weft, metres. Triangles may be
// wound either way in uv.
struct ClothMesh {
    std::vector<Eigen::Vector2d> material_uv_m;  // #V rest coordinates, metres
    std::vector<std::array<int, 3>> triangles;   // #F vertex indices
    int vertex_count() const { return static_cast<int>(material_uv_m.size()); }
    int triangle_count() const { return static_cast<int>(triangles.size()); }
};

// One interior edge and its two wings: triangle A = (v0, v1, v2) and
// triangle B = (v1, v0, v3) share the edge v0-v1.
struct BendingStencil {
    std::array<int, 4> vertices;  // v0, v1 (edge), v2 (wing of A), v3 (wing of B)
    double rest_edge_length_m = 0.0;
    double rest_area_sum_m2 = 0.0;  // A_A + A_B
};

// Interior edges of a manifold mesh (edges with exactly two triangles).
// Throws flowvid::Error (field "triangles") for an edge with three or more
// triangles or an out-of-range index.
std::vector<BendingStencil> bending_stencils(const ClothMesh& mesh);

// A rows x cols vertex grid of width_m x height_m: vertex r*cols + c at
// material uv (c/(cols-1) * width_m, r/(rows-1) * height_m), so row 0 is v = 0
// (the bottom as hung) and column 0 is u = 0. Each grid cell is split along
// alternating diagonals (checkerboard), so the swatch has no preferred
// diagonal; bending along u or v costs what it costs on an equilateral mesh.
ClothMesh make_swatch_mesh(double width_m, double height_m, int rows, int cols);

// Samples a surface at a regular grid of normalised uv: sample r*cols + c is at
// uv (c/(cols-1), r/(rows-1)) of the mesh's material bounding box (row 0 at
// v = 0). Returns rows*cols by 3 world positions, barycentric interpolation in
// the triangle that contains the uv point (the nearest triangle for points
// that fall in no triangle, e.g. on a non-rectangular outline).
class UvSampler {
public:
    UvSampler(const ClothMesh& mesh, int rows, int cols);
    // `positions` is 3*#V (x0 y0 z0 x1 ...), metres.
    Eigen::MatrixX3d sample(const Eigen::VectorXd& positions) const;
    int rows() const { return m_rows; }
    int cols() const { return m_cols; }

private:
    struct Sample {
        std::array<int, 3> vertices;
        std::array<double, 3> weights;
    };
    int m_rows = 0;
    int m_cols = 0;
    std::vector<Sample> m_samples;
};

}  // namespace flowvid::cloth
