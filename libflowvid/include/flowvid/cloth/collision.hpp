#pragma once
// Contact forces, applied inside the integrator (as the thesis does) so that
// the adaptive step control sees them: smooth penalty forces against simple
// bodies (plane, sphere, capsule, triangle mesh) and vertex-triangle
// self-repulsion. All penalties are C1 in the positions (cubic energy), so an
// embedded error estimate copes with them.

#include <Eigen/Core>

#include <array>
#include <variant>
#include <vector>

namespace flowvid::cloth {

// Half-space below the plane; `normal` points out of the solid (need not be unit).
struct PlaneCollider {
    Eigen::Vector3d point_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
};
struct SphereCollider {
    Eigen::Vector3d center_m = Eigen::Vector3d::Zero();
    double radius_m = 0.1;
};
// Segment a-b swept by a sphere of radius_m.
struct CapsuleCollider {
    Eigen::Vector3d a_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d b_m = Eigen::Vector3d::UnitZ();
    double radius_m = 0.05;
};
// A static triangle mesh (e.g. a body under a garment). Outside is where the
// counter-clockwise face normals point. Only the layer within the contact
// thickness of the surface pushes; a vertex deep inside is not pulled out.
struct MeshCollider {
    std::vector<Eigen::Vector3d> vertices_m;
    std::vector<std::array<int, 3>> triangles;
};
using Collider = std::variant<PlaneCollider, SphereCollider, CapsuleCollider, MeshCollider>;

// Penalty for a cloth vertex of mass m at signed distance d from a surface,
// with penetration delta = thickness - d > 0:
//   E = m * stiffness * delta^3 / 3,   f = m * stiffness * delta^2 * grad d.
// Scaling by the vertex mass makes the penetration depth independent of the
// fabric's density and of the mesh resolution: a vertex resting on a surface
// sinks delta = sqrt(g / stiffness) into the layer (0.1 mm with the default),
// and a fall at 2 m/s stops within ~2 mm.
struct ContactSettings {
    double thickness_m = 0.004;
    double stiffness_per_m_s2 = 1e9;  // units 1/(m s^2)
    // Smooth Coulomb friction: f_t = -mu |f_n| v_t / sqrt(|v_t|^2 + eps^2).
    double friction_coefficient = 0.0;
    double friction_smoothing_m_per_s = 1e-3;
};

// Self-repulsion between a cloth vertex and cloth triangles (Bridson-style
// proximity), same penalty as above. Pairs whose rest (material) distance is
// below `rest_exclusion_factor * thickness_m` are skipped: those points are
// neighbours in the fabric and being close is not a collision.
struct SelfContactSettings {
    bool enabled = false;
    double thickness_m = 0.003;
    double stiffness_per_m_s2 = 1e9;
    double rest_exclusion_factor = 2.0;
};

}  // namespace flowvid::cloth
