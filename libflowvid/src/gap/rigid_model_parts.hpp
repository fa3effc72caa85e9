#pragma once
// Helpers the rigid gap model (rigid_model.cpp) and its bench cases
// (rigid_bench.cpp) share. Not part of the public interface.

#include "flowvid/formats/capture.hpp"
#include "flowvid/random.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/rigid/dynamics.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace flowvid::gap::rigid_parts {

inline bool finite_state(const rigid::RigidState& s) {
    return s.com_m.allFinite() && s.orientation.coeffs().allFinite() && s.com_velocity_m_per_s.allFinite() &&
           s.angular_velocity_body_rad_per_s.allFinite();
}

inline render::PixelRect projected_region(const formats::CameraModel& camera, const std::vector<Eigen::Vector3d>& points) {
    const render::PixelRect image = render::PixelRect::image(camera.width, camera.height);
    std::vector<Eigen::Vector2d> pixels;
    render::project_camera_points(camera, points, pixels);
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Eigen::Vector2d& p : pixels) {
        if (!p.allFinite()) return image;
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    return render::PixelRect::around(lo, hi).expanded(2).intersected(image);
}

inline std::vector<Eigen::Vector3d> camera_points(const rigid::RigidBody& body, const rigid::RigidState& state) {
    std::vector<Eigen::Vector3d> out;
    out.reserve(body.mesh.vertices_m.size());
    for (const Eigen::Vector3d& v : body.mesh.vertices_m) out.push_back(state.to_camera(body, v));
    return out;
}

}  // namespace flowvid::gap::rigid_parts
