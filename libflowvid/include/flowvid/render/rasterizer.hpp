#pragma once
// A small deterministic software rasterizer for triangle meshes seen through a
// capture camera (formats::CameraModel). It produces, per pixel: coverage (the
// silhouette, optionally anti-aliased by supersampling), the camera depth of
// the nearest surface, the index of that triangle and perspective-correct
// barycentric weights of its three vertices, so a caller can interpolate any
// vertex attribute (world position for projector stripes, uv, normals).
//
// Conventions (OpenCV, as the capture contract): pixel (x, y) is the *centre*
// of column x, row y; the pixel covers [x - 0.5, x + 0.5] x [y - 0.5, y + 0.5].
// A pixel's attributes come from its centre sample. Coverage is exact point
// sampling with a top-left fill rule: two triangles sharing an edge never both
// cover, nor both miss, a sample on that edge (watertight, no double counting).
//
// Distortion: vertices are projected with the camera's full OpenCV model, and
// triangles are then filled as straight-edged triangles in the distorted image
// (the usual approximation; its error grows with the projected triangle size
// times the local curvature of the distortion, so subdivide large triangles
// when the lens distortion is strong). Barycentrics are perspective-corrected
// with the vertex depths, which is exact without distortion.
//
// Triangles crossing the near plane are clipped in camera space (barycentrics
// stay relative to the original triangle). Results are identical whatever the
// thread calling, and for the same inputs bit for bit.

#include "flowvid/formats/capture.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace flowvid::render {

// A rectangle of pixels, half-open: columns [x0, x1), rows [y0, y1).
struct PixelRect {
    int x0 = 0;
    int y0 = 0;
    int x1 = 0;
    int y1 = 0;

    static PixelRect image(int width, int height) { return {0, 0, width, height}; }
    int width() const { return x1 > x0 ? x1 - x0 : 0; }
    int height() const { return y1 > y0 ? y1 - y0 : 0; }
    bool empty() const { return width() == 0 || height() == 0; }
    bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
    PixelRect intersected(const PixelRect& other) const;
    PixelRect united(const PixelRect& other) const;  // bounding rectangle of both (an empty one is ignored)
    PixelRect expanded(int margin_px) const;
    // The pixels whose centres lie in [min, max] (pixel coordinates), rounded outwards.
    static PixelRect around(const Eigen::Vector2d& min, const Eigen::Vector2d& max);
};

// Where the vertices are given: world coordinates (camera_from_world applied
// first) or already camera coordinates (OpenCV: x right, y down, z forward).
enum class VertexSpace { world, camera };

// A mesh seen by the rasterizer (not owned). Triangles index into vertices;
// for back-face culling, front faces wind counter-clockwise seen from outside
// (glTF), i.e. (v1 - v0) x (v2 - v0) points towards the viewer.
struct MeshView {
    const std::vector<Eigen::Vector3d>* vertices_m = nullptr;
    const std::vector<std::array<int, 3>>* triangles = nullptr;
};

struct RasterSettings {
    // s: coverage uses s x s samples per pixel on a regular grid (1..8); 1 is
    // the pixel centre only (a binary silhouette).
    int supersampling = 1;
    bool cull_back_faces = false;
    double near_m = 1e-3;  // camera-space clip plane z = near_m
    // Rasterize only this part of the image (clipped to the image); the
    // framebuffer then holds just this rectangle. Default: the whole image.
    std::optional<PixelRect> region;
    // Fill depth, triangle and barycentrics (turn off for silhouettes only: faster).
    bool attributes = true;
};

struct Framebuffer {
    int image_width = 0;   // pixels of the camera image
    int image_height = 0;
    PixelRect region;      // the pixels held below, row-major within the region

    // Per pixel of the region (index with index_of):
    std::vector<float> coverage;             // fraction of the s*s samples covered by any triangle, [0, 1]
    std::vector<float> depth_m;              // camera z of the nearest surface at the centre; +inf when none
    std::vector<std::int32_t> triangle;      // its triangle index; -1 when none
    std::vector<std::array<float, 3>> barycentric;  // weights of its vertices 0, 1, 2 (sum 1); zeros when none

    bool holds(int x, int y) const { return region.contains(x, y); }
    std::size_t index_of(int x, int y) const {
        return static_cast<std::size_t>(y - region.y0) * static_cast<std::size_t>(region.width()) +
               static_cast<std::size_t>(x - region.x0);
    }
    // Coverage at an image pixel (0 outside the region).
    float coverage_at(int x, int y) const { return holds(x, y) ? coverage[index_of(x, y)] : 0.0f; }
    bool covered(int x, int y, float threshold = 0.5f) const { return coverage_at(x, y) >= threshold; }
    std::int32_t triangle_at(int x, int y) const { return holds(x, y) ? triangle[index_of(x, y)] : -1; }
    // Sum of coverage over the region: the silhouette area in pixels.
    double covered_area_px() const;
    // Whole-image binary mask (row-major, 1 = coverage >= threshold).
    std::vector<std::uint8_t> silhouette(float threshold = 0.5f) const;
};

// Rasterizes `mesh` into `out` (its buffers are reused: no allocation once
// they are large enough). Throws std::invalid_argument for a camera without
// a size, out-of-range triangle indices or supersampling outside 1..8.
void rasterize(const MeshView& mesh, VertexSpace space, const formats::CameraModel& camera,
               const RasterSettings& settings, Framebuffer& out);

// Convenience overload returning a new framebuffer.
Framebuffer rasterize(const std::vector<Eigen::Vector3d>& vertices_m, const std::vector<std::array<int, 3>>& triangles,
                      VertexSpace space, const formats::CameraModel& camera, const RasterSettings& settings = {});

// Interpolates a per-vertex attribute at pixel (x, y) with the stored
// barycentrics; nullopt where no triangle covers the pixel centre.
template <typename T>
std::optional<T> interpolate(const Framebuffer& framebuffer, const std::vector<std::array<int, 3>>& triangles,
                             const std::vector<T>& per_vertex, int x, int y) {
    if (!framebuffer.holds(x, y)) return std::nullopt;
    const std::size_t i = framebuffer.index_of(x, y);
    const std::int32_t t = framebuffer.triangle[i];
    if (t < 0) return std::nullopt;
    const std::array<int, 3>& tri = triangles[static_cast<std::size_t>(t)];
    const std::array<float, 3>& b = framebuffer.barycentric[i];
    return T(per_vertex[static_cast<std::size_t>(tri[0])] * static_cast<double>(b[0]) +
             per_vertex[static_cast<std::size_t>(tri[1])] * static_cast<double>(b[1]) +
             per_vertex[static_cast<std::size_t>(tri[2])] * static_cast<double>(b[2]));
}

// Projects camera-space points to pixels with the camera's model (distortion
// included); NaN for points at or behind z = 0. Faster than calling
// CameraModel::project_camera_point per point when there is no distortion.
void project_camera_points(const formats::CameraModel& camera, const std::vector<Eigen::Vector3d>& points_camera_m,
                           std::vector<Eigen::Vector2d>& pixels);

}  // namespace flowvid::render
