#include "flowvid/cloth/swatch_output.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::cloth {

GridFrames sample_run(const SwatchRun& run, int rows, int cols) {
    return sample_frames(run.swatch.mesh, run.simulation.frames, rows, cols);
}

formats::VertexAnimation grid_vertex_animation(const GridFrames& frames, int rows, int cols, double fps) {
    formats::VertexAnimation animation;
    animation.frame_count = static_cast<int>(frames.size());
    animation.vertex_count = rows * cols;
    animation.grid_rows = rows;
    animation.grid_cols = cols;
    animation.fps = fps;
    animation.positions_m.reserve(frames.size() * static_cast<std::size_t>(rows * cols));
    for (const Eigen::MatrixX3d& grid : frames)
        for (Eigen::Index v = 0; v < grid.rows(); ++v) animation.positions_m.push_back(grid.row(v).transpose().cast<float>());
    return animation;
}

formats::MeshAnimation grid_mesh_animation(const GridFrames& frames, int rows, int cols, double fps,
                                           const std::string& name) {
    formats::MeshAnimation animation;
    animation.name = name;
    animation.fps = fps;
    const auto vertex = [cols](int r, int c) { return r * cols + c; };
    for (int r = 0; r + 1 < rows; ++r) {
        for (int c = 0; c + 1 < cols; ++c) {
            // u to the right, v up: (r,c) -> (r,c+1) -> (r+1,c+1) turns counter-clockwise about u x v.
            animation.triangles.push_back({vertex(r, c), vertex(r, c + 1), vertex(r + 1, c + 1)});
            animation.triangles.push_back({vertex(r, c), vertex(r + 1, c + 1), vertex(r + 1, c)});
        }
    }
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c)
            animation.uv.emplace_back(cols > 1 ? static_cast<float>(c) / static_cast<float>(cols - 1) : 0.0f,
                                      rows > 1 ? static_cast<float>(r) / static_cast<float>(rows - 1) : 0.0f);
    for (const Eigen::MatrixX3d& grid : frames) {
        std::vector<Eigen::Vector3f> positions;
        positions.reserve(static_cast<std::size_t>(grid.rows()));
        for (Eigen::Index v = 0; v < grid.rows(); ++v) positions.push_back(grid.row(v).transpose().cast<float>());
        animation.frames_positions_m.push_back(std::move(positions));
    }
    return animation;
}

GridFrames grid_frames_of(const formats::VertexAnimation& animation) {
    GridFrames frames(static_cast<std::size_t>(animation.frame_count));
    for (int f = 0; f < animation.frame_count; ++f) {
        frames[static_cast<std::size_t>(f)].resize(animation.vertex_count, 3);
        for (int v = 0; v < animation.vertex_count; ++v)
            frames[static_cast<std::size_t>(f)].row(v) = animation.position(f, v).cast<double>().transpose();
    }
    return frames;
}

namespace {
void check_same_grid(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
    if (a.rows() != b.rows())
        throw std::invalid_argument("grids of " + std::to_string(a.rows()) + " and " + std::to_string(b.rows()) +
                                    " vertices cannot be compared; sample both at the same --grid");
}
}  // namespace

std::vector<double> rms_distance_per_frame_m(const GridFrames& a, const GridFrames& b) {
    const std::size_t count = std::min(a.size(), b.size());
    std::vector<double> rms(count, 0.0);
    for (std::size_t f = 0; f < count; ++f) {
        check_same_grid(a[f], b[f]);
        rms[f] = a[f].rows() ? std::sqrt((a[f] - b[f]).rowwise().squaredNorm().mean()) : 0.0;
    }
    return rms;
}

double rms_distance_m(const GridFrames& a, const GridFrames& b, int first, int last) {
    const int count = static_cast<int>(std::min(a.size(), b.size()));
    first = std::max(first, 0);
    last = std::min(last, count - 1);
    double sum = 0.0;
    long long n = 0;
    for (int f = first; f <= last; ++f) {
        check_same_grid(a[static_cast<std::size_t>(f)], b[static_cast<std::size_t>(f)]);
        sum += (a[static_cast<std::size_t>(f)] - b[static_cast<std::size_t>(f)]).rowwise().squaredNorm().sum();
        n += a[static_cast<std::size_t>(f)].rows();
    }
    return n ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

}  // namespace flowvid::cloth
