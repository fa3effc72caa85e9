#pragma once
// Pinned vertices that follow prescribed trajectories. A capture gives one
// world position per frame; between frames the path is a cubic Hermite spline
// with Catmull-Rom tangents, so position and velocity are continuous and the
// velocity is exactly the derivative of the position.

#include <Eigen/Core>

#include <vector>

namespace flowvid::cloth {

class PinPath {
public:
    PinPath() = default;
    // positions_m[k] is the position at time start_time_s + k / fps. Before the
    // first and after the last sample the pin holds still.
    PinPath(std::vector<Eigen::Vector3d> positions_m, double fps, double start_time_s = 0.0);
    // A pin that never moves.
    static PinPath fixed(const Eigen::Vector3d& position_m);

    Eigen::Vector3d position(double time_s) const;
    Eigen::Vector3d velocity(double time_s) const;
    bool empty() const { return m_positions.empty(); }
    const std::vector<Eigen::Vector3d>& samples() const { return m_positions; }

private:
    void segment(double time_s, int& k, double& s) const;
    Eigen::Vector3d tangent(int k) const;  // dp/dt at sample k, m/s

    std::vector<Eigen::Vector3d> m_positions;
    double m_fps = 30.0;
    double m_start_s = 0.0;
};

struct PinnedVertex {
    int vertex = 0;
    PinPath path;
};

}  // namespace flowvid::cloth
