#pragma once
// Helpers the cloth model's source files share (model.cpp, membrane.cpp,
// bending.cpp, drag.cpp, collision.cpp); not part of the public interface.

#include <Eigen/Core>

#include <cmath>

namespace flowvid::cloth::detail {

using Eigen::Matrix3d;
using Eigen::Vector3d;

inline Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

// The matrix of a x (cross product).
inline Matrix3d cross_matrix(const Vector3d& a) {
    Matrix3d m;
    m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
    return m;
}

// theta - theta0 in (-pi, pi]: a fold that passes through +-pi stays continuous
// against a rest fold.
inline double fold_difference(double theta, double theta0) {
    double d = theta - theta0;
    if (d > M_PI)
        d -= 2.0 * M_PI;
    else if (d <= -M_PI)
        d += 2.0 * M_PI;
    return d;
}

}  // namespace flowvid::cloth::detail
