#pragma once
// Geometric building blocks of the cloth forces with their first and second
// derivatives: the signed dihedral angle of two triangles, and the distance
// from a point to a vertex, segment or triangle. Exposed for the tests.

#include <Eigen/Core>

namespace flowvid::cloth {

using Vector12d = Eigen::Matrix<double, 12, 1>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;

// Signed dihedral angle between triangle A = (x0, x1, x2) and triangle
// B = (x1, x0, x3) across their shared edge x0-x1: 0 when flat, +-pi when
// folded onto itself, computed with atan2 so it is accurate at every angle.
// Gradient and Hessian are with respect to (x0, x1, x2, x3).
double dihedral_angle(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                      const Eigen::Vector3d& x3);
// Returns false (and leaves outputs untouched) for a degenerate hinge, where
// a triangle has no area and the angle is undefined.
bool dihedral_angle_gradient(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                             const Eigen::Vector3d& x3, double& theta, Vector12d& gradient);
bool dihedral_angle_hessian(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                            const Eigen::Vector3d& x3, double& theta, Vector12d& gradient, Matrix12d& hessian);

// Closest point of triangle (a, b, c) to p: the feature it lies on (1 = a
// vertex, 2 = an edge, 3 = the face) given as local vertex indices, and its
// barycentric weights over those vertices.
struct ClosestFeature {
    int size = 1;                    // number of feature vertices
    int local[3] = {0, 1, 2};        // triangle-local indices of the feature's vertices
    double weights[3] = {1, 0, 0};   // barycentric weights over local[0..size)
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
};
ClosestFeature closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                         const Eigen::Vector3d& c);
ClosestFeature closest_point_on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Distance from p to the affine hull of the feature's vertices y (1, 2 or 3 of
// them; the closest point must be inside the feature, which the caller found
// with closest_point_on_*), with gradient and Hessian with respect to
// (p, y0, ..., y_{k}). Sizes 3(k+2). Returns false when the distance is ~0.
struct FeatureDistance {
    using Gradient = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 12, 1>;
    using Hessian = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 12, 12>;
    double distance = 0.0;
    Gradient gradient;  // 3(k+2), no heap allocation
    Hessian hessian;    // 3(k+2) square, only when requested
};
bool feature_distance(const Eigen::Vector3d& p, const Eigen::Vector3d* feature_vertices, int feature_size,
                      bool with_hessian, FeatureDistance& out);

}  // namespace flowvid::cloth
