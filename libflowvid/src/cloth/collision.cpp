// Contacts of the cloth model (the colliders and settings of
// collision.hpp): penalty layers against bodies (plane, sphere, capsule,
// static mesh) with optional friction, and vertex-triangle self contact
// (docs/cloth_model.md, "Contacts").

#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include "flowvid/cloth/geometry.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <variant>

namespace flowvid::cloth {

using detail::at;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// Signed distance to a simple body, its gradient (unit) and Hessian at p.
struct BodyDistance {
    double d;
    Vector3d n;
    Matrix3d H;
};

BodyDistance plane_distance(const PlaneCollider& c, const Vector3d& p) {
    const Vector3d n = c.normal.normalized();
    return {(p - c.point_m).dot(n), n, Matrix3d::Zero()};
}

bool sphere_distance(const Vector3d& center, double radius, const Vector3d& p, BodyDistance& out) {
    const Vector3d r = p - center;
    const double dist = r.norm();
    if (!(dist > 0.0)) return false;
    out.n = r / dist;
    out.d = dist - radius;
    out.H = (Matrix3d::Identity() - out.n * out.n.transpose()) / dist;
    return true;
}

bool capsule_distance(const CapsuleCollider& c, const Vector3d& p, BodyDistance& out) {
    const ClosestFeature f = closest_point_on_segment(p, c.a_m, c.b_m);
    if (f.size == 1) return sphere_distance(f.point, c.radius_m, p, out);
    const Vector3d r = p - f.point;
    const double dist = r.norm();
    if (!(dist > 0.0)) return false;
    const Vector3d axis = (c.b_m - c.a_m).normalized();
    out.n = r / dist;
    out.d = dist - c.radius_m;
    out.H = (Matrix3d::Identity() - out.n * out.n.transpose() - axis * axis.transpose()) / dist;
    return true;
}

// Signed distance to one triangle of a mesh collider; outside is the side of
// the counter-clockwise normal.
bool mesh_triangle_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                            BodyDistance& out) {
    const ClosestFeature f = closest_point_on_triangle(p, a, b, c);
    const Vector3d normal = (b - a).cross(c - a);
    const double nn = normal.norm();
    if (!(nn > 0.0)) return false;
    const Vector3d nf = normal / nn;
    if (f.size == 3) {
        out.d = (p - f.point).dot(nf);
        out.n = nf;
        out.H.setZero();
        return true;
    }
    const Vector3d r = p - f.point;
    const double dist = r.norm();
    if (!(dist > 0.0)) return false;
    const double sign = r.dot(nf) >= 0.0 ? 1.0 : -1.0;
    const Vector3d rhat = r / dist;
    Matrix3d Pi = Matrix3d::Identity();
    if (f.size == 2) {
        const Vector3d* v[3] = {&a, &b, &c};
        const Vector3d t = (*v[f.local[1]] - *v[f.local[0]]).normalized();
        Pi -= t * t.transpose();
    }
    out.d = sign * dist;
    out.n = sign * rhat;
    out.H = sign * (Pi - rhat * rhat.transpose()) / dist;
    return true;
}

std::int64_t cell_key(std::int64_t ix, std::int64_t iy, std::int64_t iz) {
    const std::int64_t offset = 1 << 20, mask = (1 << 21) - 1;
    return ((ix + offset) & mask) | (((iy + offset) & mask) << 21) | (((iz + offset) & mask) << 42);
}

double max_displacement(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    double m = 0.0;
    for (Eigen::Index i = 0; i < a.size(); i += 3) m = std::max(m, (a.segment<3>(i) - b.segment<3>(i)).squaredNorm());
    return std::sqrt(m);
}
}  // namespace


void ClothModel::update_body_candidates(const Eigen::VectorXd& x) {
    const ContactSettings& cs = m_environment.contact;
    const double margin = cs.thickness_m;
    if (m_body_built && max_displacement(x, m_body_build_x) < 0.5 * margin) return;
    m_body_built = true;
    m_body_build_x = x;
    ++m_contact_stats.body_rebuilds;
    m_body_candidates.clear();
    m_body_mesh_offsets.clear();
    const double radius = cs.thickness_m + margin;
    int offset = 0;
    for (const Collider& collider : m_environment.colliders) {
        m_body_mesh_offsets.push_back(offset);
        const MeshCollider* mesh = std::get_if<MeshCollider>(&collider);
        if (!mesh) continue;
        // Uniform grid over the collider's triangles (static: built per rebuild, small).
        double edge = 0.0;
        for (const auto& tri : mesh->triangles)
            edge = std::max(edge, (mesh->vertices_m[static_cast<size_t>(tri[1])] - mesh->vertices_m[static_cast<size_t>(tri[0])]).norm());
        const double cell = std::max(radius, 1e-6);
        std::vector<std::pair<std::int64_t, int>> cells;
        for (int ti = 0; ti < static_cast<int>(mesh->triangles.size()); ++ti) {
            const auto& tri = mesh->triangles[static_cast<size_t>(ti)];
            Vector3d lo = mesh->vertices_m[static_cast<size_t>(tri[0])], hi = lo;
            for (int k = 1; k < 3; ++k) {
                lo = lo.cwiseMin(mesh->vertices_m[static_cast<size_t>(tri[static_cast<size_t>(k)])]);
                hi = hi.cwiseMax(mesh->vertices_m[static_cast<size_t>(tri[static_cast<size_t>(k)])]);
            }
            lo.array() -= radius;
            hi.array() += radius;
            const Eigen::Array3d l = (lo / cell).array().floor(), h = (hi / cell).array().floor();
            for (double ix = l.x(); ix <= h.x(); ++ix)
                for (double iy = l.y(); iy <= h.y(); ++iy)
                    for (double iz = l.z(); iz <= h.z(); ++iz)
                        cells.push_back({cell_key(static_cast<std::int64_t>(ix), static_cast<std::int64_t>(iy),
                                                  static_cast<std::int64_t>(iz)),
                                         ti});
        }
        std::sort(cells.begin(), cells.end());
        for (int i = 0; i < vertex_count(); ++i) {
            const Vector3d p = at(x, i);
            const Eigen::Array3d c = (p / cell).array().floor();
            const std::int64_t key =
                cell_key(static_cast<std::int64_t>(c.x()), static_cast<std::int64_t>(c.y()), static_cast<std::int64_t>(c.z()));
            auto it = std::lower_bound(cells.begin(), cells.end(), std::make_pair(key, -1));
            for (; it != cells.end() && it->first == key; ++it) {
                const auto& tri = mesh->triangles[static_cast<size_t>(it->second)];
                const ClosestFeature f =
                    closest_point_on_triangle(p, mesh->vertices_m[static_cast<size_t>(tri[0])],
                                              mesh->vertices_m[static_cast<size_t>(tri[1])],
                                              mesh->vertices_m[static_cast<size_t>(tri[2])]);
                if ((p - f.point).norm() < radius) m_body_candidates.push_back({i, offset + it->second});
            }
        }
        offset += static_cast<int>(mesh->triangles.size());
    }
    m_contact_stats.body_candidates = static_cast<int>(m_body_candidates.size());
}

void ClothModel::add_body_contact(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd* f,
                                  double* energy, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode,
                                  Linearization* lin, const Eigen::VectorXd* product_of) {
    if (lin) lin->has_vertex = true;
    const ContactSettings& cs = m_environment.contact;
    const bool exact = mode == JacobianMode::exact;
    const bool penalty = terms & ForceTerm::body_contact;
    const bool friction = (terms & ForceTerm::friction) && cs.friction_coefficient > 0.0 && f != nullptr;
    const double tau = cs.thickness_m, kappa = cs.stiffness_per_m_s2;
    const Matrix3d I = Matrix3d::Identity();

    auto apply = [&](int i, const BodyDistance& bd) {
        const double delta = tau - bd.d;
        if (!(delta > 0.0)) return;
        const double m = m_mass(i);
        const double fn = m * kappa * delta * delta;
        if (energy && penalty) *energy += m * kappa * delta * delta * delta / 3.0;
        if (f && penalty) f->segment<3>(3 * i) += fn * bd.n;
        if ((dfdx || lin) && penalty) {
            Matrix3d K = -2.0 * m * kappa * delta * bd.n * bd.n.transpose();
            if (exact) K += fn * bd.H;
            if (lin) {
                lin->vertex_block[static_cast<size_t>(i)] += lin->sx * K;
                if (product_of) lin->dfdx_product.segment<3>(3 * i) += K * at(*product_of, i);
            } else {
                dfdx->block(dfdx->diagonal_slot(i)) += K;
            }
        }
        if (friction) {
            const Vector3d vi = at(v, i);
            const Vector3d vt = vi - bd.n.dot(vi) * bd.n;
            const double eps = cs.friction_smoothing_m_per_s;
            const double s = std::sqrt(vt.squaredNorm() + eps * eps);
            const double mu = cs.friction_coefficient;
            f->segment<3>(3 * i) -= mu * fn * vt / s;
            const Matrix3d Jphi = I / s - vt * vt.transpose() / (s * s * s);
            const Matrix3d Dv = -mu * fn * Jphi * (I - bd.n * bd.n.transpose());
            if (lin) lin->vertex_block[static_cast<size_t>(i)] += lin->sv * Dv;
            if (dfdv) dfdv->block(dfdv->diagonal_slot(i)) += Dv;
            if (dfdx && exact) {
                const Matrix3d dvt_dx = -(bd.n * vi.transpose() + bd.n.dot(vi) * I) * bd.H;
                const Matrix3d K = -mu * ((vt / s) * (-2.0 * m * kappa * delta * bd.n).transpose() + fn * Jphi * dvt_dx);
                dfdx->block(dfdx->diagonal_slot(i)) += K;
            }
        }
    };

    bool any_mesh = false;
    for (const Collider& c : m_environment.colliders) any_mesh |= std::holds_alternative<MeshCollider>(c);
    if (any_mesh) update_body_candidates(x);

    for (size_t ci = 0; ci < m_environment.colliders.size(); ++ci) {
        const Collider& collider = m_environment.colliders[ci];
        if (const auto* plane = std::get_if<PlaneCollider>(&collider)) {
            for (int i = 0; i < vertex_count(); ++i) apply(i, plane_distance(*plane, at(x, i)));
        } else if (const auto* sphere = std::get_if<SphereCollider>(&collider)) {
            BodyDistance bd;
            for (int i = 0; i < vertex_count(); ++i)
                if (sphere_distance(sphere->center_m, sphere->radius_m, at(x, i), bd)) apply(i, bd);
        } else if (const auto* capsule = std::get_if<CapsuleCollider>(&collider)) {
            BodyDistance bd;
            for (int i = 0; i < vertex_count(); ++i)
                if (capsule_distance(*capsule, at(x, i), bd)) apply(i, bd);
        } else if (const auto* mesh = std::get_if<MeshCollider>(&collider)) {
            // One contact per vertex: the nearest candidate triangle of this mesh.
            const int first = m_body_mesh_offsets[ci];
            const int last = first + static_cast<int>(mesh->triangles.size());
            size_t k = 0;
            while (k < m_body_candidates.size()) {
                const int i = m_body_candidates[k].first;
                BodyDistance best{};
                double best_abs = std::numeric_limits<double>::infinity();
                for (; k < m_body_candidates.size() && m_body_candidates[k].first == i; ++k) {
                    const int packed = m_body_candidates[k].second;
                    if (packed < first || packed >= last) continue;
                    const auto& tri = mesh->triangles[static_cast<size_t>(packed - first)];
                    BodyDistance bd;
                    if (!mesh_triangle_distance(at(x, i), mesh->vertices_m[static_cast<size_t>(tri[0])],
                                                mesh->vertices_m[static_cast<size_t>(tri[1])],
                                                mesh->vertices_m[static_cast<size_t>(tri[2])], bd))
                        continue;
                    if (std::abs(bd.d) < best_abs) {
                        best_abs = std::abs(bd.d);
                        best = bd;
                    }
                }
                if (best_abs < std::numeric_limits<double>::infinity()) apply(i, best);
            }
        }
    }
}

void ClothModel::update_self_candidates(const Eigen::VectorXd& x) {
    const SelfContactSettings& sc = m_environment.self_contact;
    const double margin = sc.thickness_m;
    if (m_self_built && max_displacement(x, m_self_build_x) < 0.5 * margin) return;
    m_self_built = true;
    m_self_build_x = x;
    ++m_contact_stats.self_rebuilds;
    m_self_candidates.clear();
    const double radius = sc.thickness_m + margin;
    const double cell = radius;
    std::vector<std::pair<std::int64_t, int>> cells;
    for (int ti = 0; ti < static_cast<int>(m_triangles.size()); ++ti) {
        const auto& tv = m_triangles[static_cast<size_t>(ti)].v;
        Vector3d lo = at(x, tv[0]), hi = lo;
        for (int k = 1; k < 3; ++k) {
            lo = lo.cwiseMin(at(x, tv[static_cast<size_t>(k)]));
            hi = hi.cwiseMax(at(x, tv[static_cast<size_t>(k)]));
        }
        lo.array() -= radius;
        hi.array() += radius;
        const Eigen::Array3d l = (lo / cell).array().floor(), h = (hi / cell).array().floor();
        if (((h - l) > 64.0).any()) continue;  // absurdly stretched triangle: the blow-up check will catch it
        for (double ix = l.x(); ix <= h.x(); ++ix)
            for (double iy = l.y(); iy <= h.y(); ++iy)
                for (double iz = l.z(); iz <= h.z(); ++iz)
                    cells.push_back({cell_key(static_cast<std::int64_t>(ix), static_cast<std::int64_t>(iy),
                                              static_cast<std::int64_t>(iz)),
                                     ti});
    }
    std::sort(cells.begin(), cells.end());
    const double exclusion = sc.rest_exclusion_factor * sc.thickness_m;
    for (int i = 0; i < vertex_count(); ++i) {
        const Vector3d p = at(x, i);
        const Eigen::Array3d c = (p / cell).array().floor();
        const std::int64_t key =
            cell_key(static_cast<std::int64_t>(c.x()), static_cast<std::int64_t>(c.y()), static_cast<std::int64_t>(c.z()));
        auto it = std::lower_bound(cells.begin(), cells.end(), std::make_pair(key, -1));
        const Eigen::Vector2d& uvp = m_mesh.material_uv_m[static_cast<size_t>(i)];
        for (; it != cells.end() && it->first == key; ++it) {
            const auto& tv = m_triangles[static_cast<size_t>(it->second)].v;
            if (tv[0] == i || tv[1] == i || tv[2] == i) continue;
            const ClosestFeature f = closest_point_on_triangle(p, at(x, tv[0]), at(x, tv[1]), at(x, tv[2]));
            if ((p - f.point).norm() >= radius) continue;
            auto lift = [&](int k) {
                const Eigen::Vector2d& uv = m_mesh.material_uv_m[static_cast<size_t>(tv[static_cast<size_t>(k)])];
                return Vector3d(uv.x(), uv.y(), 0.0);
            };
            const ClosestFeature rest = closest_point_on_triangle(Vector3d(uvp.x(), uvp.y(), 0.0), lift(0), lift(1), lift(2));
            if ((rest.point - Vector3d(uvp.x(), uvp.y(), 0.0)).norm() < exclusion) continue;
            m_self_candidates.push_back({i, it->second});
        }
    }
    m_contact_stats.self_candidates = static_cast<int>(m_self_candidates.size());
}

void ClothModel::add_self_contact(const Eigen::VectorXd& x, Eigen::VectorXd* f, double* energy, BlockSparseMatrix* dfdx,
                                  JacobianMode mode, Linearization* lin, const Eigen::VectorXd* product_of) {
    const SelfContactSettings& sc = m_environment.self_contact;
    update_self_candidates(x);
    const double tau = sc.thickness_m, kappa = sc.stiffness_per_m_s2;
    const bool exact = mode == JacobianMode::exact;
    FeatureDistance fd;
    for (const auto& [i, ti] : m_self_candidates) {
        const auto& tv = m_triangles[static_cast<size_t>(ti)].v;
        const Vector3d p = at(x, i);
        const Vector3d y[3] = {at(x, tv[0]), at(x, tv[1]), at(x, tv[2])};
        const ClosestFeature cf = closest_point_on_triangle(p, y[0], y[1], y[2]);
        if ((p - cf.point).squaredNorm() >= tau * tau) continue;
        Vector3d fy[3];
        int idx[4] = {i, 0, 0, 0};
        for (int k = 0; k < cf.size; ++k) {
            fy[k] = y[cf.local[k]];
            idx[k + 1] = tv[static_cast<size_t>(cf.local[k])];
        }
        if (!feature_distance(p, fy, cf.size, dfdx != nullptr && exact, fd)) continue;
        const double delta = tau - fd.distance;
        if (!(delta > 0.0)) continue;
        const double m = m_mass(i);
        if (energy) *energy += m * kappa * delta * delta * delta / 3.0;
        const double fn = m * kappa * delta * delta;
        const int count = cf.size + 1;
        if (f)
            for (int a = 0; a < count; ++a) f->segment<3>(3 * idx[a]) += fn * fd.gradient.segment<3>(3 * a);
        if (dfdx || lin) {
            FeatureDistance::Hessian K = (-2.0 * m * kappa * delta) * (fd.gradient * fd.gradient.transpose());
            if (exact) K += fn * fd.hessian;
            for (int a = 0; a < count; ++a)
                for (int b = 0; b < count; ++b) {
                    if (lin) {
                        lin->pair_blocks.push_back({idx[a], idx[b], lin->sx * K.block<3, 3>(3 * a, 3 * b)});
                        if (product_of)
                            lin->dfdx_product.segment<3>(3 * idx[a]) += K.block<3, 3>(3 * a, 3 * b) * at(*product_of, idx[b]);
                    } else {
                        dfdx->add(idx[a], idx[b], K.block<3, 3>(3 * a, 3 * b));
                    }
                }
        }
    }
}

}  // namespace flowvid::cloth
