#pragma once
// Swatch runs as files and numbers: regular-uv-grid samples of a run written
// as a motion glTF or a vertex-animation EXR (the captures' truth layout), and
// RMS vertex distances between two such grids (prediction vs truth).

#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/motion_gltf.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace flowvid::cloth {

// #frames grids of rows*cols x 3 world positions, metres, vertex r*cols + c,
// row 0 at v = 0 and column 0 at u = 0 (truth/positions.exr layout).
using GridFrames = std::vector<Eigen::MatrixX3d>;

// Samples every simulated frame of a run at the uv grid.
GridFrames sample_run(const SwatchRun& run, int rows, int cols);

// The grid as a vertex-animation EXR (grid size and fps recorded).
formats::VertexAnimation grid_vertex_animation(const GridFrames& frames, int rows, int cols, double fps);
// The grid as a triangle mesh animation: two triangles per cell, counter-
// clockwise seen from the swatch's front (u x v), uv from the grid.
formats::MeshAnimation grid_mesh_animation(const GridFrames& frames, int rows, int cols, double fps,
                                           const std::string& name);
// Back from a vertex animation (e.g. a capture's truth) to grids.
GridFrames grid_frames_of(const formats::VertexAnimation& animation);

// Per-frame RMS over vertices of |a - b| (m), for the first min(#a, #b)
// frames. Throws std::invalid_argument when the grids differ in size.
std::vector<double> rms_distance_per_frame_m(const GridFrames& a, const GridFrames& b);
// RMS over every vertex of frames [first, last] (0-based, inclusive, clamped
// to what both have) -- the pooled RMS, not a mean of per-frame RMS values.
double rms_distance_m(const GridFrames& a, const GridFrames& b, int first, int last);

}  // namespace flowvid::cloth
