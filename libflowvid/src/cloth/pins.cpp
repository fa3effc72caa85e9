#include "flowvid/cloth/pins.hpp"

#include <cmath>

namespace flowvid::cloth {

PinPath::PinPath(std::vector<Eigen::Vector3d> positions_m, double fps, double start_time_s)
    : m_positions(std::move(positions_m)), m_fps(fps > 0.0 ? fps : 30.0), m_start_s(start_time_s) {}

PinPath PinPath::fixed(const Eigen::Vector3d& position_m) { return PinPath({position_m}, 30.0, 0.0); }

void PinPath::segment(double time_s, int& k, double& s) const {
    const double f = (time_s - m_start_s) * m_fps;
    const int last = static_cast<int>(m_positions.size()) - 1;
    if (!(f > 0.0)) {
        k = 0;
        s = 0.0;
    } else if (f >= last) {
        k = last;
        s = 0.0;
    } else {
        k = static_cast<int>(std::floor(f));
        s = f - k;
    }
}

// Catmull-Rom tangent; zero at both ends, where the pin holds still (a
// capture starts at rest, in equilibrium), so the velocity is continuous.
Eigen::Vector3d PinPath::tangent(int k) const {
    const int last = static_cast<int>(m_positions.size()) - 1;
    if (k <= 0 || k >= last) return Eigen::Vector3d::Zero();
    return (m_positions[static_cast<size_t>(k + 1)] - m_positions[static_cast<size_t>(k - 1)]) * (0.5 * m_fps);
}

Eigen::Vector3d PinPath::position(double time_s) const {
    if (m_positions.empty()) return Eigen::Vector3d::Zero();
    int k;
    double s;
    segment(time_s, k, s);
    if (s == 0.0) return m_positions[static_cast<size_t>(k)];
    const double dt = 1.0 / m_fps;
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * m_positions[static_cast<size_t>(k)] + (s3 - 2 * s2 + s) * dt * tangent(k) +
           (-2 * s3 + 3 * s2) * m_positions[static_cast<size_t>(k + 1)] + (s3 - s2) * dt * tangent(k + 1);
}

Eigen::Vector3d PinPath::velocity(double time_s) const {
    if (m_positions.size() < 2) return Eigen::Vector3d::Zero();
    int k;
    double s;
    segment(time_s, k, s);
    if (k >= static_cast<int>(m_positions.size()) - 1) return Eigen::Vector3d::Zero();
    const double dt = 1.0 / m_fps;
    const double s2 = s * s;
    return ((6 * s2 - 6 * s) * m_positions[static_cast<size_t>(k)] + (3 * s2 - 4 * s + 1) * dt * tangent(k) +
            (-6 * s2 + 6 * s) * m_positions[static_cast<size_t>(k + 1)] + (3 * s2 - 2 * s) * dt * tangent(k + 1)) *
           m_fps;
}

}  // namespace flowvid::cloth
