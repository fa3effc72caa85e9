#include "flowvid/cloth/geometry.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace flowvid::cloth {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Vector9d = Eigen::Matrix<double, 9, 1>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;

Matrix3d cross_matrix(const Vector3d& a) {
    Matrix3d m;
    m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
    return m;
}

// The angle is atan2(Y, X) with, for e = x1 - x0, b = x2 - x0, c = x3 - x0,
//   X = (e.b)(e.c) - (e.e)(b.c)   = N_A . N_B  (N_A = e x b, N_B = c x e)
//   Y = -|e| e.(b x c)            = (N_A x N_B) . e / |e|
// Both are polynomials in (e, b, c) up to the factor |e|, which makes the
// derivatives short and exact at every angle (no acos, no division by sin).
struct HingeTerms {
    Vector3d e, b, c;
    double L, D, X, Y, r2;
    Vector9d gX, gY;
};

bool hinge_terms(const Vector3d& x0, const Vector3d& x1, const Vector3d& x2, const Vector3d& x3, HingeTerms& h) {
    h.e = x1 - x0;
    h.b = x2 - x0;
    h.c = x3 - x0;
    const double ee = h.e.squaredNorm(), eb = h.e.dot(h.b), ec = h.e.dot(h.c), bc = h.b.dot(h.c);
    h.L = std::sqrt(ee);
    const Vector3d bxc = h.b.cross(h.c);
    h.D = h.e.dot(bxc);
    h.X = eb * ec - ee * bc;
    h.Y = -h.L * h.D;
    h.r2 = h.X * h.X + h.Y * h.Y;
    const double scale = ee * ee * h.b.squaredNorm() * h.c.squaredNorm();
    if (!(h.L > 0.0) || !(h.r2 > 1e-24 * scale)) return false;
    const Vector3d ehat = h.e / h.L;
    h.gX.segment<3>(0) = h.b * ec + h.c * eb - 2.0 * h.e * bc;
    h.gX.segment<3>(3) = h.e * ec - h.c * ee;
    h.gX.segment<3>(6) = h.e * eb - h.b * ee;
    h.gY.segment<3>(0) = -(h.D * ehat + h.L * bxc);
    h.gY.segment<3>(3) = -h.L * h.c.cross(h.e);
    h.gY.segment<3>(6) = -h.L * h.e.cross(h.b);
    return true;
}

void expand_gradient(const Vector9d& g9, Vector12d& g) {
    g.segment<3>(3) = g9.segment<3>(0);
    g.segment<3>(6) = g9.segment<3>(3);
    g.segment<3>(9) = g9.segment<3>(6);
    g.segment<3>(0) = -(g9.segment<3>(0) + g9.segment<3>(3) + g9.segment<3>(6));
}

}  // namespace

double dihedral_angle(const Vector3d& x0, const Vector3d& x1, const Vector3d& x2, const Vector3d& x3) {
    const Vector3d e = x1 - x0, b = x2 - x0, c = x3 - x0;
    const double X = e.dot(b) * e.dot(c) - e.squaredNorm() * b.dot(c);
    const double Y = -e.norm() * e.dot(b.cross(c));
    return std::atan2(Y, X);
}

bool dihedral_angle_gradient(const Vector3d& x0, const Vector3d& x1, const Vector3d& x2, const Vector3d& x3,
                             double& theta, Vector12d& gradient) {
    // A wing vertex moving along its face normal turns the face about the
    // edge by (displacement / height); the edge vertices share the opposite
    // turn by where the heights' feet are (rotation and translation invariance).
    const Vector3d e = x1 - x0, b = x2 - x0, c = x3 - x0;
    const Vector3d NA = e.cross(b), NB = c.cross(e);
    const double nA2 = NA.squaredNorm(), nB2 = NB.squaredNorm(), ee = e.squaredNorm();
    if (!(ee > 0.0) || !(nA2 > 1e-24 * ee * b.squaredNorm()) || !(nB2 > 1e-24 * ee * c.squaredNorm())) return false;
    const double L = std::sqrt(ee);
    theta = std::atan2(-L * e.dot(b.cross(c)), NA.dot(NB));
    const Vector3d g2 = (-L / nA2) * NA, g3 = (-L / nB2) * NB;
    const double tA = e.dot(b) / ee, tB = e.dot(c) / ee;
    gradient.segment<3>(0) = -(1.0 - tA) * g2 - (1.0 - tB) * g3;
    gradient.segment<3>(3) = -tA * g2 - tB * g3;
    gradient.segment<3>(6) = g2;
    gradient.segment<3>(9) = g3;
    return true;
}

bool dihedral_angle_hessian(const Vector3d& x0, const Vector3d& x1, const Vector3d& x2, const Vector3d& x3,
                            double& theta, Vector12d& gradient, Matrix12d& hessian) {
    HingeTerms h;
    if (!hinge_terms(x0, x1, x2, x3, h)) return false;
    theta = std::atan2(h.Y, h.X);
    const Vector9d g9 = (h.X * h.gY - h.Y * h.gX) / h.r2;
    expand_gradient(g9, gradient);

    const Vector3d& e = h.e;
    const Vector3d& b = h.b;
    const Vector3d& c = h.c;
    const Matrix3d I = Matrix3d::Identity();
    const double ee = e.squaredNorm(), eb = e.dot(b), ec = e.dot(c), bc = b.dot(c);

    Matrix9d HX = Matrix9d::Zero();
    HX.block<3, 3>(0, 0) = b * c.transpose() + c * b.transpose() - 2.0 * bc * I;
    HX.block<3, 3>(0, 3) = ec * I + c * e.transpose() - 2.0 * e * c.transpose();
    HX.block<3, 3>(0, 6) = eb * I + b * e.transpose() - 2.0 * e * b.transpose();
    HX.block<3, 3>(3, 6) = e * e.transpose() - ee * I;
    HX.block<3, 3>(3, 0) = HX.block<3, 3>(0, 3).transpose();
    HX.block<3, 3>(6, 0) = HX.block<3, 3>(0, 6).transpose();
    HX.block<3, 3>(6, 3) = HX.block<3, 3>(3, 6).transpose();

    // Y = -L D
    const Vector3d ehat = e / h.L;
    Vector9d gD;
    gD << b.cross(c), c.cross(e), e.cross(b);
    Vector9d gL = Vector9d::Zero();
    gL.segment<3>(0) = ehat;
    Matrix9d HD = Matrix9d::Zero();
    HD.block<3, 3>(0, 3) = -cross_matrix(c);
    HD.block<3, 3>(0, 6) = cross_matrix(b);
    HD.block<3, 3>(3, 6) = -cross_matrix(e);
    HD.block<3, 3>(3, 0) = HD.block<3, 3>(0, 3).transpose();
    HD.block<3, 3>(6, 0) = HD.block<3, 3>(0, 6).transpose();
    HD.block<3, 3>(6, 3) = HD.block<3, 3>(3, 6).transpose();
    Matrix9d HY = -(gL * gD.transpose() + gD * gL.transpose() + h.L * HD);
    HY.block<3, 3>(0, 0) -= h.D * (I - ehat * ehat.transpose()) / h.L;

    // d2 atan2(Y, X), written in its symmetric form.
    const double r4 = h.r2 * h.r2;
    const Matrix9d cross_terms = h.gY * h.gX.transpose() + h.gX * h.gY.transpose();
    const Matrix9d H9 = (h.X * HY - h.Y * HX) / h.r2 -
                        ((h.X * h.X - h.Y * h.Y) * cross_terms +
                         2.0 * h.X * h.Y * (h.gY * h.gY.transpose() - h.gX * h.gX.transpose())) /
                            r4;

    // x1 = x0 + e etc.: block (0, *) is minus the sum of the others.
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) hessian.block<3, 3>(3 + 3 * i, 3 + 3 * j) = H9.block<3, 3>(3 * i, 3 * j);
    for (int j = 0; j < 3; ++j) {
        const Matrix3d col = H9.block<3, 3>(0, 3 * j) + H9.block<3, 3>(3, 3 * j) + H9.block<3, 3>(6, 3 * j);
        hessian.block<3, 3>(0, 3 + 3 * j) = -col;
        hessian.block<3, 3>(3 + 3 * j, 0) = -col.transpose();
    }
    Matrix3d all = Matrix3d::Zero();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) all += H9.block<3, 3>(3 * i, 3 * j);
    hessian.block<3, 3>(0, 0) = all;
    return true;
}

ClosestFeature closest_point_on_segment(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
    ClosestFeature f;
    const Vector3d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? (p - a).dot(ab) / len2 : 0.0;
    if (t <= 0.0) {
        f.size = 1;
        f.local[0] = 0;
        f.weights[0] = 1.0;
        f.point = a;
    } else if (t >= 1.0) {
        f.size = 1;
        f.local[0] = 1;
        f.weights[0] = 1.0;
        f.point = b;
    } else {
        f.size = 2;
        f.local[0] = 0;
        f.local[1] = 1;
        f.weights[0] = 1.0 - t;
        f.weights[1] = t;
        f.point = a + t * ab;
    }
    return f;
}

ClosestFeature closest_point_on_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
    // Voronoi regions of the vertices, then of the edges, else the face.
    ClosestFeature f;
    auto vertex = [&](int k, const Vector3d& q) {
        f.size = 1;
        f.local[0] = k;
        f.weights[0] = 1.0;
        f.point = q;
        return f;
    };
    auto edge = [&](int i, int j, const Vector3d& qi, const Vector3d& qj, double t) {
        f.size = 2;
        f.local[0] = i;
        f.local[1] = j;
        f.weights[0] = 1.0 - t;
        f.weights[1] = t;
        f.point = qi + t * (qj - qi);
        return f;
    };
    const Vector3d ab = b - a, ac = c - a;
    const Vector3d ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) return vertex(0, a);
    const Vector3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) return vertex(1, b);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return edge(0, 1, a, b, d1 / (d1 - d3));
    const Vector3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) return vertex(2, c);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return edge(0, 2, a, c, d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
        return edge(1, 2, b, c, (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, w = vc * denom;
    f.size = 3;
    f.local[0] = 0;
    f.local[1] = 1;
    f.local[2] = 2;
    f.weights[0] = 1.0 - v - w;
    f.weights[1] = v;
    f.weights[2] = w;
    f.point = a + v * ab + w * ac;
    return f;
}

bool feature_distance(const Vector3d& p, const Vector3d* y, int size, bool with_hessian, FeatureDistance& out) {
    // r = p - y0 - E t with E^T r = 0; see docs/cloth_model.md for the Hessian.
    const int k = size - 1;
    const int n = 3 * (size + 1);
    Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 2> E(3, k);
    for (int j = 0; j < k; ++j) E.col(j) = y[j + 1] - y[0];
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 2, 2> Ginv(k, k);
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 2, 1> t(k);
    if (k > 0) {
        const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 2, 2> G = E.transpose() * E;
        const double det = k == 1 ? G(0, 0) : G(0, 0) * G(1, 1) - G(0, 1) * G(1, 0);
        if (!(std::abs(det) > 0.0)) return false;
        if (k == 1) {
            Ginv(0, 0) = 1.0 / G(0, 0);
        } else {
            Ginv(0, 0) = G(1, 1) / det;
            Ginv(1, 1) = G(0, 0) / det;
            Ginv(0, 1) = -G(0, 1) / det;
            Ginv(1, 0) = -G(1, 0) / det;
        }
        t = Ginv * (E.transpose() * (p - y[0]));
    }
    const Vector3d r = p - y[0] - E * t;
    const double d = r.norm();
    if (!(d > 0.0)) return false;
    out.distance = d;
    double w[3] = {1.0, 0.0, 0.0};
    for (int j = 0; j < k; ++j) {
        w[j + 1] = t(j);
        w[0] -= t(j);
    }
    out.gradient.resize(n);
    const Vector3d rhat = r / d;
    out.gradient.segment<3>(0) = rhat;
    for (int j = 0; j < size; ++j) out.gradient.segment<3>(3 + 3 * j) = -w[j] * rhat;
    if (!with_hessian) return true;

    Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 12> B(3, n);
    B.block<3, 3>(0, 0).setIdentity();
    for (int j = 0; j < size; ++j) B.block<3, 3>(0, 3 + 3 * j) = -w[j] * Matrix3d::Identity();
    Matrix3d Pi = Matrix3d::Identity();
    if (k > 0) Pi -= E * Ginv * E.transpose();
    FeatureDistance::Hessian H = B.transpose() * Pi * B;
    if (k > 0) {
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 2, 12> R(k, n);
        R.setZero();
        for (int j = 0; j < k; ++j) {
            R.block<1, 3>(j, 3 + 3 * (j + 1)) = r.transpose();
            R.block<1, 3>(j, 3) = -r.transpose();
        }
        const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 12, 2> BtEG = B.transpose() * E * Ginv;
        H -= BtEG * R + R.transpose() * BtEG.transpose() + R.transpose() * Ginv * R;
    }
    out.hessian = (H - out.gradient * out.gradient.transpose()) / d;
    return true;
}

}  // namespace flowvid::cloth
