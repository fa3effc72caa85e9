#include "flowvid/cloth/model.hpp"

#include "flowvid/cloth/geometry.hpp"
#include "flowvid/error.hpp"
#include "flowvid/cloth/worker_pool.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <variant>
#include <string>

namespace flowvid::cloth {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

Matrix3d cross_matrix(const Vector3d& a) {
    Matrix3d m;
    m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
    return m;
}

inline Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

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

// Coefficients of the warp and weft tangents w_u = sum alpha_a x_a,
// w_v = sum beta_a x_a of a triangle with material coordinates u0, u1, u2,
// from [w_u w_v] = [x1-x0, x2-x0] * inverse([[du1, du2], [dv1, dv2]]). A bias
// angle b turns the warp to (cos b, sin b) in uv: w_warp = cos b w_u + sin b
// w_v, w_weft = -sin b w_u + cos b w_v (the uv frame rotated by -b). At b = 0
// exactly the rotation is skipped, so the neutral value changes no bit.
void frame_coefficients(const Eigen::Vector2d& u0, const Eigen::Vector2d& u1, const Eigen::Vector2d& u2,
                        double bias_rad, std::array<double, 3>& alpha, std::array<double, 3>& beta) {
    const double du1 = u1.x() - u0.x(), dv1 = u1.y() - u0.y();
    const double du2 = u2.x() - u0.x(), dv2 = u2.y() - u0.y();
    const double det = du1 * dv2 - du2 * dv1;
    alpha = {(dv1 - dv2) / det, dv2 / det, -dv1 / det};
    beta = {(du2 - du1) / det, -du2 / det, du1 / det};
    if (bias_rad == 0.0) return;
    const double c = std::cos(bias_rad), s = std::sin(bias_rad);
    for (size_t a = 0; a < 3; ++a) {
        const double al = alpha[a], be = beta[a];
        alpha[a] = c * al + s * be;
        beta[a] = -s * al + c * be;
    }
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

double max_displacement(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    double m = 0.0;
    for (Eigen::Index i = 0; i < a.size(); i += 3) m = std::max(m, (a.segment<3>(i) - b.segment<3>(i)).squaredNorm());
    return std::sqrt(m);
}

}  // namespace

ClothModel::ClothModel(ClothMesh mesh, ClothMaterial material, Environment environment)
    : m_mesh(std::move(mesh)), m_material(material), m_environment(std::move(environment)) {
    validate_and_precompute();
}

ClothModel::~ClothModel() = default;
ClothModel::ClothModel(ClothModel&&) noexcept = default;
ClothModel& ClothModel::operator=(ClothModel&&) noexcept = default;

void ClothModel::set_material(const ClothMaterial& material) {
    std::vector<Problem> problems = check_material(material);
    if (!problems.empty()) throw ValidationError(std::move(problems));
    m_material = material;
    if (m_material.bias_angle_rad != m_frame_bias_rad) compute_material_frames();
    m_total_mass = 0.0;
    for (int i = 0; i < vertex_count(); ++i) {
        m_mass(i) = m_material.areal_density_kg_per_m2 * m_vertex_area(i);
        m_total_mass += m_mass(i);
    }
}

void ClothModel::set_environment(Environment environment) {
    m_environment = std::move(environment);
    m_body_built = false;
    m_self_built = false;
}

void ClothModel::validate_and_precompute() {
    Diagnostics diagnostics("<mesh>");
    for (Problem& p : check_material(m_material)) diagnostics.merge({p});
    const int n = vertex_count();
    if (n == 0 || m_mesh.triangle_count() == 0)
        diagnostics.error("triangles", "the cloth mesh has no triangles", "give at least one triangle");
    diagnostics.throw_if_errors();

    m_stencils = cloth::bending_stencils(m_mesh);  // throws on bad indices / non-manifold edges
    m_vertex_area = Eigen::VectorXd::Zero(n);
    m_vertex_triangles.assign(static_cast<size_t>(n), {});
    m_triangles.clear();
    m_triangles.reserve(static_cast<size_t>(m_mesh.triangle_count()));
    m_total_area = 0.0;
    double uv_extent = 0.0;
    for (const Eigen::Vector2d& uv : m_mesh.material_uv_m) uv_extent = std::max(uv_extent, uv.cwiseAbs().maxCoeff());
    for (int t = 0; t < m_mesh.triangle_count(); ++t) {
        const auto& tri = m_mesh.triangles[static_cast<size_t>(t)];
        const Eigen::Vector2d& u0 = m_mesh.material_uv_m[static_cast<size_t>(tri[0])];
        const Eigen::Vector2d& u1 = m_mesh.material_uv_m[static_cast<size_t>(tri[1])];
        const Eigen::Vector2d& u2 = m_mesh.material_uv_m[static_cast<size_t>(tri[2])];
        const double du1 = u1.x() - u0.x(), dv1 = u1.y() - u0.y();
        const double du2 = u2.x() - u0.x(), dv2 = u2.y() - u0.y();
        const double det = du1 * dv2 - du2 * dv1;
        if (!(std::abs(det) > 1e-14 * uv_extent * uv_extent) || !std::isfinite(det)) {
            diagnostics.error("triangles[" + std::to_string(t) + "]",
                              "has no area in material coordinates (degenerate rest triangle)",
                              "remove the triangle or fix its vertices' uv");
            continue;
        }
        TriangleData d;
        d.v = tri;
        frame_coefficients(u0, u1, u2, m_material.bias_angle_rad, d.alpha, d.beta);
        d.rest_area_m2 = 0.5 * std::abs(det);
        d.slots.fill(-1);
        m_total_area += d.rest_area_m2;
        for (int k = 0; k < 3; ++k) {
            m_vertex_area(tri[static_cast<size_t>(k)]) += d.rest_area_m2 / 3.0;
            m_vertex_triangles[static_cast<size_t>(tri[static_cast<size_t>(k)])].push_back(t);
        }
        m_triangles.push_back(d);
    }
    for (int i = 0; i < n; ++i)
        if (!(m_vertex_area(i) > 0.0))
            diagnostics.error("material_uv_m[" + std::to_string(i) + "]", "vertex belongs to no triangle (it has no mass)",
                              "remove unused vertices");
    diagnostics.throw_if_errors();

    m_frame_bias_rad = m_material.bias_angle_rad;
    m_rest_fold_rad.clear();
    m_mass.resize(n);
    set_material(m_material);

    m_edges.clear();
    m_pattern_pairs.clear();
    for (const TriangleData& t : m_triangles)
        for (int a = 0; a < 3; ++a)
            for (int b = a + 1; b < 3; ++b) m_pattern_pairs.push_back({t.v[static_cast<size_t>(a)], t.v[static_cast<size_t>(b)]});
    for (const BendingStencil& s : m_stencils) {
        EdgeData e;
        e.v = s.vertices;
        e.weight = s.rest_edge_length_m * s.rest_edge_length_m / s.rest_area_sum_m2;
        e.slots.fill(-1);
        m_edges.push_back(e);
        m_pattern_pairs.push_back({s.vertices[2], s.vertices[3]});
    }
    m_vertex_triangle_local.assign(static_cast<size_t>(n), {});
    m_vertex_edge_local.assign(static_cast<size_t>(n), {});
    for (size_t t = 0; t < m_triangles.size(); ++t)
        for (int a = 0; a < 3; ++a)
            m_vertex_triangle_local[static_cast<size_t>(m_triangles[t].v[static_cast<size_t>(a)])].push_back({static_cast<int>(t), a});
    for (size_t e = 0; e < m_edges.size(); ++e)
        for (int a = 0; a < 4; ++a)
            m_vertex_edge_local[static_cast<size_t>(m_edges[e].v[static_cast<size_t>(a)])].push_back({static_cast<int>(e), a});
    m_chunk_force.assign(kChunks, Eigen::VectorXd::Zero(3 * n));
    m_chunk_product.assign(kChunks, Eigen::VectorXd::Zero(3 * n));
    const BlockSparseMatrix pattern = make_jacobian_matrix();
    for (TriangleData& t : m_triangles)
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
                t.slots[static_cast<size_t>(3 * a + b)] = pattern.slot(t.v[static_cast<size_t>(a)], t.v[static_cast<size_t>(b)]);
    for (EdgeData& e : m_edges)
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b)
                e.slots[static_cast<size_t>(4 * a + b)] = pattern.slot(e.v[static_cast<size_t>(a)], e.v[static_cast<size_t>(b)]);
}

void ClothModel::compute_material_frames() {
    for (TriangleData& t : m_triangles)
        frame_coefficients(m_mesh.material_uv_m[static_cast<size_t>(t.v[0])],
                           m_mesh.material_uv_m[static_cast<size_t>(t.v[1])],
                           m_mesh.material_uv_m[static_cast<size_t>(t.v[2])], m_material.bias_angle_rad, t.alpha, t.beta);
    m_frame_bias_rad = m_material.bias_angle_rad;
}

Eigen::VectorXd ClothModel::rest_fold_angles_rad() const {
    if (m_rest_fold_rad.empty()) return Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m_edges.size()));
    return Eigen::Map<const Eigen::VectorXd>(m_rest_fold_rad.data(), static_cast<Eigen::Index>(m_rest_fold_rad.size()));
}

void ClothModel::set_rest_fold_angles_rad(const Eigen::VectorXd& angles_rad) {
    if (angles_rad.size() != static_cast<Eigen::Index>(m_edges.size()))
        throw std::invalid_argument("set_rest_fold_angles_rad: " + std::to_string(angles_rad.size()) +
                                    " angles for " + std::to_string(m_edges.size()) + " interior edges");
    if (!angles_rad.allFinite()) throw std::invalid_argument("set_rest_fold_angles_rad: non-finite angle");
    m_rest_fold_rad.assign(angles_rad.data(), angles_rad.data() + angles_rad.size());
}

void ClothModel::reset_rest_fold_angles() { m_rest_fold_rad.clear(); }

void ClothModel::update_rest_fold_angles(const Eigen::VectorXd& x, double dt_s, Eigen::VectorXd* bending_force_change) {
    const double rate = m_material.bend_memory_rate_per_s;
    if (!(rate > 0.0) || !(dt_s > 0.0)) return;
    if (m_rest_fold_rad.empty()) m_rest_fold_rad.assign(m_edges.size(), 0.0);
    // Exact for a held fold over any sequence of steps: the factors e^{-r dt} multiply.
    const double fraction = -std::expm1(-rate * dt_s);
    const double kb = m_material.bend_N_m;
    const bool correct = bending_force_change != nullptr && kb != 0.0;
    Vector12d g;
    for (size_t ei = 0; ei < m_edges.size(); ++ei) {
        const EdgeData& e = m_edges[ei];
        double theta = 0.0;
        // Degenerate hinges exert no bending force and keep their memory.
        if (!dihedral_angle_gradient(at(x, e.v[0]), at(x, e.v[1]), at(x, e.v[2]), at(x, e.v[3]), theta, g)) continue;
        double& theta0 = m_rest_fold_rad[ei];
        const double step = fraction * fold_difference(theta, theta0);
        theta0 = std::remainder(theta0 + step, 2.0 * M_PI);
        // f = -k w (theta - theta0) g: raising theta0 by `step` adds k w step g.
        if (correct)
            for (int a = 0; a < 4; ++a)
                bending_force_change->segment<3>(3 * e.v[static_cast<size_t>(a)]) += (kb * e.weight * step) * g.segment<3>(3 * a);
    }
}

BlockSparseMatrix ClothModel::make_jacobian_matrix() const { return BlockSparseMatrix(vertex_count(), m_pattern_pairs); }

void ClothModel::evaluate(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms,
                          Eigen::VectorXd& force, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode) {
    evaluate_terms(x, v, time_s, terms, force, dfdx, dfdv, mode, nullptr);
}

void ClothModel::linearize(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms,
                           double sx, double sv, Eigen::VectorXd& force, Linearization& lin,
                           const Eigen::VectorXd* product_of) {
    const int n = vertex_count();
    lin.sx = sx;
    lin.sv = sv;
    lin.has_membrane = lin.has_bending = lin.has_drag = lin.has_vertex = false;
    lin.membrane_blocks.resize(6 * m_triangles.size());
    lin.hinge_gradient.resize(m_edges.size());
    lin.hinge_coefficient.assign(m_edges.size(), 0.0);
    lin.drag_block.resize(m_triangles.size());
    lin.vertex_block.assign(static_cast<size_t>(n), Matrix3d::Zero());
    lin.pair_blocks.clear();
    if (product_of) lin.dfdx_product.setZero(3 * n);
    evaluate_terms(x, v, time_s, terms, force, nullptr, nullptr, JacobianMode::definite, &lin, product_of);
}

void ClothModel::evaluate_terms(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms,
                                Eigen::VectorXd& force, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv,
                                JacobianMode mode, Linearization* lin, const Eigen::VectorXd* product_of) {
    const int n = vertex_count();
    if (dfdx) dfdx->set_zero();
    if (dfdv) dfdv->set_zero();
    const bool membrane =
        terms & (ForceTerm::stretch | ForceTerm::shear | ForceTerm::stretch_damping | ForceTerm::shear_damping);
    const bool bending = terms & (ForceTerm::bending | ForceTerm::bending_damping);
    const bool drag = (terms & ForceTerm::drag) &&
                      (m_material.drag_normal_kg_per_m3 != 0.0 || m_material.drag_tangential_kg_per_m2_s != 0.0 ||
                       m_material.drag_linear_normal_kg_per_m2_s != 0.0);
    if (lin) {
        lin->has_membrane = membrane;
        lin->has_bending = bending && (m_material.bend_N_m != 0.0 || m_material.bend_damping_N_m_s != 0.0);
        lin->has_drag = drag;
    }
    if (dfdx || dfdv) {
        // Assembled Jacobians (tests, equilibrium): one pass, no threads.
        force.setZero(3 * n);
        if (membrane) add_membrane(x, v, terms, force, dfdx, dfdv, mode, lin, 0, m_triangles.size());
        if (bending) add_bending(x, v, terms, force, dfdx, dfdv, mode, lin, 0, m_edges.size());
        if (drag) add_drag(x, v, time_s, force, dfdx, dfdv, mode, lin, 0, m_triangles.size());
    } else {
        // The element loops in a fixed number of chunks, each into its own
        // buffer, summed in chunk order: the same bits with any thread count.
        const std::function<void(int)> chunk = [&](int c) {
            Eigen::VectorXd& fc = m_chunk_force[static_cast<size_t>(c)];
            fc.setZero(3 * n);
            Eigen::VectorXd* pc = nullptr;
            if (product_of) {
                pc = &m_chunk_product[static_cast<size_t>(c)];
                pc->setZero(3 * n);
            }
            const size_t t0 = m_triangles.size() * static_cast<size_t>(c) / kChunks;
            const size_t t1 = m_triangles.size() * static_cast<size_t>(c + 1) / kChunks;
            const size_t e0 = m_edges.size() * static_cast<size_t>(c) / kChunks;
            const size_t e1 = m_edges.size() * static_cast<size_t>(c + 1) / kChunks;
            if (membrane) add_membrane(x, v, terms, fc, nullptr, nullptr, mode, lin, t0, t1, product_of, pc);
            if (bending) add_bending(x, v, terms, fc, nullptr, nullptr, mode, lin, e0, e1, product_of, pc);
            if (drag) add_drag(x, v, time_s, fc, nullptr, nullptr, mode, lin, t0, t1);
        };
        if (m_pool)
            m_pool->run(kChunks, chunk);
        else
            for (int c = 0; c < kChunks; ++c) chunk(c);
        force = m_chunk_force[0];
        for (int c = 1; c < kChunks; ++c) force += m_chunk_force[static_cast<size_t>(c)];
        if (lin && product_of)
            for (int c = 0; c < kChunks; ++c) lin->dfdx_product += m_chunk_product[static_cast<size_t>(c)];
    }
    if (terms & ForceTerm::gravity)
        for (int i = 0; i < n; ++i) force.segment<3>(3 * i) += m_mass(i) * m_environment.gravity_m_per_s2;
    if ((terms & (ForceTerm::body_contact | ForceTerm::friction)) && !m_environment.colliders.empty())
        add_body_contact(x, v, terms, &force, nullptr, dfdx, dfdv, mode, lin, product_of);
    if ((terms & ForceTerm::self_contact) && m_environment.self_contact.enabled)
        add_self_contact(x, &force, nullptr, dfdx, mode, lin, product_of);
}

void ClothModel::set_threads(int threads) {
    if (threads <= 1)
        m_pool.reset();
    else if (!m_pool || m_pool->threads() != threads)
        m_pool = std::make_unique<detail::WorkerPool>(threads);
}

int ClothModel::threads() const { return m_pool ? m_pool->threads() : 1; }


void ClothModel::apply_product(const Linearization& lin, const Eigen::VectorXd& p, Eigen::VectorXd& out) const {
    out.setZero(p.size());
    if (lin.has_membrane) {
        for (size_t t = 0; t < m_triangles.size(); ++t) {
            const TriangleData& tri = m_triangles[t];
            const Matrix3d* B = &lin.membrane_blocks[6 * t];
            Vector3d qu = Vector3d::Zero(), qv = Vector3d::Zero();
            for (int b = 0; b < 3; ++b) {
                const Vector3d pb = at(p, tri.v[static_cast<size_t>(b)]);
                qu += B[b] * pb;
                qv += B[3 + b] * pb;
            }
            for (int a = 0; a < 3; ++a)
                out.segment<3>(3 * tri.v[static_cast<size_t>(a)]) +=
                    tri.alpha[static_cast<size_t>(a)] * qu + tri.beta[static_cast<size_t>(a)] * qv;
        }
    }
    if (lin.has_bending) {
        for (size_t e = 0; e < m_edges.size(); ++e) {
            const double c = lin.hinge_coefficient[e];
            if (c == 0.0) continue;
            const EdgeData& ed = m_edges[e];
            const Vector12d& g = lin.hinge_gradient[e];
            double s = 0.0;
            for (int a = 0; a < 4; ++a) s += g.segment<3>(3 * a).dot(at(p, ed.v[static_cast<size_t>(a)]));
            s *= c;
            for (int a = 0; a < 4; ++a) out.segment<3>(3 * ed.v[static_cast<size_t>(a)]) += s * g.segment<3>(3 * a);
        }
    }
    if (lin.has_drag) {
        for (size_t t = 0; t < m_triangles.size(); ++t) {
            const TriangleData& tri = m_triangles[t];
            const Vector3d q = lin.drag_block[t] * (at(p, tri.v[0]) + at(p, tri.v[1]) + at(p, tri.v[2]));
            for (int a = 0; a < 3; ++a) out.segment<3>(3 * tri.v[static_cast<size_t>(a)]) += q;
        }
    }
    if (lin.has_vertex)
        for (int i = 0; i < vertex_count(); ++i) out.segment<3>(3 * i) += lin.vertex_block[static_cast<size_t>(i)] * at(p, i);
    for (const auto& e : lin.pair_blocks) out.segment<3>(3 * e.row) += e.value * at(p, e.col);
}

void ClothModel::assemble_product(const Linearization& lin, BlockSparseMatrix& J) {
    J.set_zero();
    // Row by row (each row gathers from its incident elements), so that rows
    // can be split between threads without two writing the same block.
    const std::function<void(int)> rows = [&](int c) {
        const int r0 = vertex_count() * c / kChunks, r1 = vertex_count() * (c + 1) / kChunks;
        for (int i = r0; i < r1; ++i) {
            if (lin.has_membrane || lin.has_drag)
                for (const auto& [t, a] : m_vertex_triangle_local[static_cast<size_t>(i)]) {
                    const TriangleData& tri = m_triangles[static_cast<size_t>(t)];
                    const double al = tri.alpha[static_cast<size_t>(a)], be = tri.beta[static_cast<size_t>(a)];
                    const Matrix3d* B = lin.has_membrane ? &lin.membrane_blocks[6 * static_cast<size_t>(t)] : nullptr;
                    for (int b = 0; b < 3; ++b) {
                        Matrix3d& block = J.block(tri.slots[static_cast<size_t>(3 * a + b)]);
                        if (B) block += al * B[b] + be * B[3 + b];
                        if (lin.has_drag) block += lin.drag_block[static_cast<size_t>(t)];
                    }
                }
            if (lin.has_bending)
                for (const auto& [e, a] : m_vertex_edge_local[static_cast<size_t>(i)]) {
                    const double c = lin.hinge_coefficient[static_cast<size_t>(e)];
                    if (c == 0.0) continue;
                    const Vector12d& g = lin.hinge_gradient[static_cast<size_t>(e)];
                    const Vector3d ga = c * g.segment<3>(3 * a);
                    const EdgeData& ed = m_edges[static_cast<size_t>(e)];
                    for (int b = 0; b < 4; ++b)
                        J.block(ed.slots[static_cast<size_t>(4 * a + b)]).noalias() += ga * g.segment<3>(3 * b).transpose();
                }
            if (lin.has_vertex) J.block(J.diagonal_slot(i)) += lin.vertex_block[static_cast<size_t>(i)];
        }
    };
    if (m_pool)
        m_pool->run(kChunks, rows);
    else
        for (int c = 0; c < kChunks; ++c) rows(c);
    for (const auto& e : lin.pair_blocks) J.add(e.row, e.col, e.value);
}

void ClothModel::add_membrane(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd& f,
                              BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                              size_t begin, size_t end, const Eigen::VectorXd* product_of,
                              Eigen::VectorXd* product) const {
    const bool exact = mode == JacobianMode::exact;
    const bool stretch = terms & ForceTerm::stretch, shear = terms & ForceTerm::shear;
    const bool stretch_damp = (terms & ForceTerm::stretch_damping) &&
                              (m_material.stretch_warp_damping_N_s_per_m != 0.0 ||
                               m_material.stretch_weft_damping_N_s_per_m != 0.0);
    const bool shear_damp = (terms & ForceTerm::shear_damping) && m_material.shear_damping_N_s_per_m != 0.0;
    const bool need_v = stretch_damp || shear_damp;
    const double ku = m_material.stretch_warp_N_per_m, kv = m_material.stretch_weft_N_per_m;
    const double ks = m_material.shear_N_per_m;
    const double cu = m_material.stretch_warp_damping_N_s_per_m, cv = m_material.stretch_weft_damping_N_s_per_m;
    const double cs = m_material.shear_damping_N_s_per_m;
    const Matrix3d I = Matrix3d::Identity();

    if (!dfdx && !dfdv && !lin) {
        // Forces only (explicit integration): the same formulas without the
        // matrices, which is most of the cost of the hot loop.
        const double ku_on = stretch ? ku : 0.0, kv_on = stretch ? kv : 0.0, ks_on = shear ? ks : 0.0;
        const double cu_on = stretch_damp ? cu : 0.0, cv_on = stretch_damp ? cv : 0.0, cs_on = shear_damp ? cs : 0.0;
        for (size_t ti = begin; ti < end; ++ti) {
            const TriangleData& t = m_triangles[ti];
            const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
            const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
            const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
            const double A = t.rest_area_m2;
            const double lu = wu.norm(), lv = wv.norm();
            double su = ku_on * (lu - 1.0), sv = kv_on * (lv - 1.0), sh = ks_on * wu.dot(wv);
            if (need_v) {
                const Vector3d v0 = at(v, t.v[0]), v1 = at(v, t.v[1]), v2 = at(v, t.v[2]);
                const Vector3d wu_dot = t.alpha[0] * v0 + t.alpha[1] * v1 + t.alpha[2] * v2;
                const Vector3d wv_dot = t.beta[0] * v0 + t.beta[1] * v1 + t.beta[2] * v2;
                if (lu > 0.0) su += cu_on * wu.dot(wu_dot) / lu;
                if (lv > 0.0) sv += cv_on * wv.dot(wv_dot) / lv;
                sh += cs_on * (wu_dot.dot(wv) + wu.dot(wv_dot));
            }
            // f_a = -A (su w_u/|w_u| + sh w_v) alpha_a - A (sv w_v/|w_v| + sh w_u) beta_a
            const Vector3d fu = -A * ((lu > 0.0 ? su / lu : 0.0) * wu + sh * wv);
            const Vector3d fv = -A * ((lv > 0.0 ? sv / lv : 0.0) * wv + sh * wu);
            for (int a = 0; a < 3; ++a)
                f.segment<3>(3 * t.v[static_cast<size_t>(a)]) +=
                    t.alpha[static_cast<size_t>(a)] * fu + t.beta[static_cast<size_t>(a)] * fv;
        }
        return;
    }

    if (lin) {
        // Definite blocks for the implicit integrator, written out directly:
        //   Kuu = -A (ku (w w^T + c' P) + ks wv wv^T),  Duu = -A (cu w w^T + cs wv wv^T)
        // (w = unit w_u, P = I - w w^T, c' = max(|w_u| - 1, 0) / |w_u|), the
        // same with u and v swapped, and Kuv = -A ks wv wu^T = Kvu^T,
        // Duv = -A cs wv wu^T. Combined as J = sx K + sv D.
        const double sx = lin->sx, sv = lin->sv;
        const double ku_on = stretch ? ku : 0.0, kv_on = stretch ? kv : 0.0, ks_on = shear ? ks : 0.0;
        const double cu_on = stretch_damp ? cu : 0.0, cv_on = stretch_damp ? cv : 0.0, cs_on = shear_damp ? cs : 0.0;
        for (size_t ti = begin; ti < end; ++ti) {
            const TriangleData& t = m_triangles[ti];
            const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
            const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
            const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
            const double A = t.rest_area_m2;
            const double lu = wu.norm(), lv = wv.norm();
            const Vector3d hu = lu > 0.0 ? Vector3d(wu / lu) : Vector3d::Zero();
            const Vector3d hv = lv > 0.0 ? Vector3d(wv / lv) : Vector3d::Zero();
            const double cpu = lu > 0.0 ? std::max(lu - 1.0, 0.0) / lu : 0.0;
            const double cpv = lv > 0.0 ? std::max(lv - 1.0, 0.0) / lv : 0.0;
            // Forces (as the force-only path).
            double su = ku_on * (lu - 1.0), svv = kv_on * (lv - 1.0), sh = ks_on * wu.dot(wv);
            if (need_v) {
                const Vector3d v0 = at(v, t.v[0]), v1 = at(v, t.v[1]), v2 = at(v, t.v[2]);
                const Vector3d wu_dot = t.alpha[0] * v0 + t.alpha[1] * v1 + t.alpha[2] * v2;
                const Vector3d wv_dot = t.beta[0] * v0 + t.beta[1] * v1 + t.beta[2] * v2;
                if (lu > 0.0) su += cu_on * hu.dot(wu_dot);
                if (lv > 0.0) svv += cv_on * hv.dot(wv_dot);
                sh += cs_on * (wu_dot.dot(wv) + wu.dot(wv_dot));
            }
            const Vector3d fu = -A * (su * hu + sh * wv);
            const Vector3d fv = -A * (svv * hv + sh * wu);
            for (int a = 0; a < 3; ++a)
                f.segment<3>(3 * t.v[static_cast<size_t>(a)]) +=
                    t.alpha[static_cast<size_t>(a)] * fu + t.beta[static_cast<size_t>(a)] * fv;
            // J blocks.
            const double ju_ww = -A * (sx * ku_on * (1.0 - cpu) + sv * cu_on), ju_i = -A * sx * ku_on * cpu;
            const double jv_ww = -A * (sx * kv_on * (1.0 - cpv) + sv * cv_on), jv_i = -A * sx * kv_on * cpv;
            const double js = -A * (sx * ks_on + sv * cs_on);
            Matrix3d C0 = ju_ww * hu * hu.transpose() + js * wv * wv.transpose();
            C0.diagonal().array() += ju_i;
            Matrix3d C1 = jv_ww * hv * hv.transpose() + js * wu * wu.transpose();
            C1.diagonal().array() += jv_i;
            const Matrix3d C2 = js * wv * wu.transpose();  // alpha_a beta_b
            Matrix3d* B = &lin->membrane_blocks[6 * ti];
            for (int b = 0; b < 3; ++b) {
                const double ab = t.alpha[static_cast<size_t>(b)], bb = t.beta[static_cast<size_t>(b)];
                B[b] = ab * C0 + bb * C2;
                B[3 + b] = ab * C2.transpose() + bb * C1;
            }
            if (product_of && product) {
                // df/dx p with sx = 1, sv = 0, as vector operations.
                Vector3d pu = Vector3d::Zero(), pv = Vector3d::Zero();
                for (int b = 0; b < 3; ++b) {
                    pu += t.alpha[static_cast<size_t>(b)] * at(*product_of, t.v[static_cast<size_t>(b)]);
                    pv += t.beta[static_cast<size_t>(b)] * at(*product_of, t.v[static_cast<size_t>(b)]);
                }
                const double wvpu = wv.dot(pu), wupv = wu.dot(pv);
                const Vector3d qu = -A * (ku_on * ((1.0 - cpu) * hu.dot(pu) * hu + cpu * pu) + ks_on * (wvpu + wupv) * wv);
                const Vector3d qv = -A * (kv_on * ((1.0 - cpv) * hv.dot(pv) * hv + cpv * pv) + ks_on * (wvpu + wupv) * wu);
                for (int a = 0; a < 3; ++a)
                    product->segment<3>(3 * t.v[static_cast<size_t>(a)]) +=
                        t.alpha[static_cast<size_t>(a)] * qu + t.beta[static_cast<size_t>(a)] * qv;
            }
        }
        return;
    }

    const bool want_dx = dfdx != nullptr, want_dv = dfdv != nullptr;
    for (size_t ti = begin; ti < end; ++ti) {
        const TriangleData& t = m_triangles[ti];
        const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
        const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
        const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
        Vector3d wu_dot = Vector3d::Zero(), wv_dot = Vector3d::Zero();
        if (need_v) {
            const Vector3d v0 = at(v, t.v[0]), v1 = at(v, t.v[1]), v2 = at(v, t.v[2]);
            wu_dot = t.alpha[0] * v0 + t.alpha[1] * v1 + t.alpha[2] * v2;
            wv_dot = t.beta[0] * v0 + t.beta[1] * v1 + t.beta[2] * v2;
        }
        const double A = t.rest_area_m2;
        // Force = coefficient_u * alpha_a + coefficient_v * beta_a (vectors).
        Vector3d fu = Vector3d::Zero(), fv = Vector3d::Zero();
        // Jacobian blocks: K_ab = alpha_a alpha_b Kuu + beta_a beta_b Kvv
        //   + alpha_a beta_b Kuv + beta_a alpha_b Kvu (same for D with v).
        Matrix3d Kuu = Matrix3d::Zero(), Kvv = Matrix3d::Zero(), Kuv = Matrix3d::Zero(), Kvu = Matrix3d::Zero();
        Matrix3d Duu = Matrix3d::Zero(), Dvv = Matrix3d::Zero(), Duv = Matrix3d::Zero(), Dvu = Matrix3d::Zero();

        auto axis_term = [&](const Vector3d& w, const Vector3d& w_dot, double k, double c, Vector3d& fw, Matrix3d& Kww,
                             Matrix3d& Dww) {
            const double len = w.norm();
            if (!(len > 0.0)) return;
            const Vector3d what = w / len;
            const double C = len - 1.0;
            const Matrix3d ww = what * what.transpose();
            const Matrix3d P = I - ww;
            if (stretch) {
                fw -= k * A * C * what;
                if (want_dx) Kww -= k * A * (ww + (exact ? C : std::max(C, 0.0)) / len * P);
            }
            if (stretch_damp && c != 0.0) {
                const double C_dot = what.dot(w_dot);
                fw -= c * A * C_dot * what;
                if (want_dv) Dww -= c * A * ww;
                if (want_dx && exact) Kww -= c * A / len * (C_dot * P + what * (P * w_dot).transpose());
            }
        };
        axis_term(wu, wu_dot, ku, cu, fu, Kuu, Duu);
        axis_term(wv, wv_dot, kv, cv, fv, Kvv, Dvv);

        // Shear: C = wu . wv, dC/dx_a = alpha_a wv + beta_a wu.
        double shear_coef = 0.0;  // force = -shear_coef * grad C
        double shear_curv = 0.0;  // coefficient of (alpha_a beta_b + beta_a alpha_b) I in K
        if (shear || shear_damp) {
            const double C = wu.dot(wv);
            if (shear) {
                shear_coef += ks * A * C;
                if (want_dx) {
                    // -ks A grad C grad C^T
                    Kuu -= ks * A * wv * wv.transpose();
                    Kvv -= ks * A * wu * wu.transpose();
                    Kuv -= ks * A * wv * wu.transpose();
                    Kvu -= ks * A * wu * wv.transpose();
                    if (exact) shear_curv -= ks * A * C;
                }
            }
            if (shear_damp) {
                const double C_dot = wu_dot.dot(wv) + wu.dot(wv_dot);
                shear_coef += cs * A * C_dot;
                if (want_dv) {
                    Duu -= cs * A * wv * wv.transpose();
                    Dvv -= cs * A * wu * wu.transpose();
                    Duv -= cs * A * wv * wu.transpose();
                    Dvu -= cs * A * wu * wv.transpose();
                }
                if (want_dx && exact) {
                    shear_curv -= cs * A * C_dot;
                    // -cs A grad C (beta_b wu_dot + alpha_b wv_dot)^T
                    Kuu -= cs * A * wv * wv_dot.transpose();
                    Kuv -= cs * A * wv * wu_dot.transpose();
                    Kvu -= cs * A * wu * wv_dot.transpose();
                    Kvv -= cs * A * wu * wu_dot.transpose();
                }
            }
            fu -= shear_coef * wv;
            fv -= shear_coef * wu;
        }

        for (int a = 0; a < 3; ++a)
            f.segment<3>(3 * t.v[static_cast<size_t>(a)]) += t.alpha[static_cast<size_t>(a)] * fu + t.beta[static_cast<size_t>(a)] * fv;

        if (dfdx) {
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) {
                    const double aa = t.alpha[static_cast<size_t>(a)], ab = t.alpha[static_cast<size_t>(b)];
                    const double ba = t.beta[static_cast<size_t>(a)], bb = t.beta[static_cast<size_t>(b)];
                    Matrix3d K = aa * ab * Kuu + ba * bb * Kvv + aa * bb * Kuv + ba * ab * Kvu;
                    K.diagonal().array() += shear_curv * (aa * bb + ba * ab);
                    dfdx->block(t.slots[static_cast<size_t>(3 * a + b)]) += K;
                }
        }
        if (dfdv && need_v) {
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) {
                    const double aa = t.alpha[static_cast<size_t>(a)], ab = t.alpha[static_cast<size_t>(b)];
                    const double ba = t.beta[static_cast<size_t>(a)], bb = t.beta[static_cast<size_t>(b)];
                    dfdv->block(t.slots[static_cast<size_t>(3 * a + b)]) +=
                        aa * ab * Duu + ba * bb * Dvv + aa * bb * Duv + ba * ab * Dvu;
                }
        }
    }
}

void ClothModel::add_bending(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd& f,
                             BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                             size_t begin, size_t end, const Eigen::VectorXd* product_of,
                             Eigen::VectorXd* product) const {
    const bool exact = mode == JacobianMode::exact;
    const double kb = (terms & ForceTerm::bending) ? m_material.bend_N_m : 0.0;
    const double cb = (terms & ForceTerm::bending_damping) ? m_material.bend_damping_N_m_s : 0.0;
    if (kb == 0.0 && cb == 0.0) return;
    // The definite Jacobian keeps only the Gauss-Newton term g g^T: no Hessian.
    const bool need_hessian = dfdx != nullptr && exact;
    // Bending memory: the elastic part acts on theta - theta0 (null: flat rest).
    const double* rest = m_rest_fold_rad.empty() ? nullptr : m_rest_fold_rad.data();
    Vector12d g;
    Matrix12d H;
    for (size_t ei = begin; ei < end; ++ei) {
        const EdgeData& e = m_edges[ei];
        const Vector3d x0 = at(x, e.v[0]), x1 = at(x, e.v[1]), x2 = at(x, e.v[2]), x3 = at(x, e.v[3]);
        double theta = 0.0;
        const bool ok = need_hessian ? dihedral_angle_hessian(x0, x1, x2, x3, theta, g, H)
                                     : dihedral_angle_gradient(x0, x1, x2, x3, theta, g);
        if (!ok && lin) {
            lin->hinge_coefficient[ei] = 0.0;
            continue;
        }
        if (ok && !dfdx && !dfdv && !lin) {
            // Forces only (explicit integration).
            double coef = kb * (rest ? fold_difference(theta, rest[ei]) : theta);
            if (cb != 0.0)
                for (int a = 0; a < 4; ++a) coef += cb * g.segment<3>(3 * a).dot(at(v, e.v[static_cast<size_t>(a)]));
            coef *= e.weight;
            for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[static_cast<size_t>(a)]) -= coef * g.segment<3>(3 * a);
            continue;
        }
        if (!ok) continue;
        double theta_dot = 0.0;
        Vector12d vl;
        if (cb != 0.0) {
            for (int a = 0; a < 4; ++a) vl.segment<3>(3 * a) = at(v, e.v[static_cast<size_t>(a)]);
            theta_dot = g.dot(vl);
        }
        const double w = e.weight;
        const double bend = rest ? fold_difference(theta, rest[ei]) : theta;
        const double coef = w * (kb * bend + cb * theta_dot);
        for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[static_cast<size_t>(a)]) -= coef * g.segment<3>(3 * a);
        if (lin) {
            lin->hinge_gradient[ei] = g;
            lin->hinge_coefficient[ei] = -w * (lin->sx * kb + lin->sv * cb);
            if (product_of && product && kb != 0.0) {
                double s = 0.0;
                for (int a = 0; a < 4; ++a) s += g.segment<3>(3 * a).dot(at(*product_of, e.v[static_cast<size_t>(a)]));
                s *= -w * kb;
                for (int a = 0; a < 4; ++a) product->segment<3>(3 * e.v[static_cast<size_t>(a)]) += s * g.segment<3>(3 * a);
            }
            continue;
        }
        if (dfdx && !exact) {
            // Only the 3x3 blocks of -w kb g g^T.
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdx->block(e.slots[static_cast<size_t>(4 * a + b)]).noalias() -=
                        (w * kb) * g.segment<3>(3 * a) * g.segment<3>(3 * b).transpose();
        } else if (dfdx) {
            Matrix12d K = -(w * kb) * (g * g.transpose());
            {
                K -= (w * kb * bend) * H;
                if (cb != 0.0) K -= (w * cb) * (theta_dot * H + g * (H * vl).transpose());
            }
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdx->block(e.slots[static_cast<size_t>(4 * a + b)]) += K.block<3, 3>(3 * a, 3 * b);
        }
        if (dfdv && cb != 0.0) {
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    dfdv->block(e.slots[static_cast<size_t>(4 * a + b)]) -=
                        (w * cb) * g.segment<3>(3 * a) * g.segment<3>(3 * b).transpose();
        }
    }
}

void ClothModel::add_drag(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& f,
                          BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                          size_t begin, size_t end) const {
    const double kN = m_material.drag_normal_kg_per_m3, kf = m_material.drag_degradation_s2_per_m2;
    const double kT = m_material.drag_tangential_kg_per_m2_s;
    const double kL = m_material.drag_linear_normal_kg_per_m2_s;
    const bool field = static_cast<bool>(m_environment.wind_field);
    const Matrix3d I = Matrix3d::Identity();
    for (size_t ti = begin; ti < end; ++ti) {
        const TriangleData& t = m_triangles[ti];
        const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
        const Vector3d N = (x1 - x0).cross(x2 - x0);
        const double Nn = N.norm();
        if (lin) lin->drag_block[ti].setZero();
        if (!(Nn > 0.0)) continue;
        const Vector3d n = N / Nn;
        const double a = 0.5 * Nn;
        const Vector3d wind = field ? m_environment.wind_field((x0 + x1 + x2) / 3.0, time_s) : m_environment.wind_m_per_s;
        const Vector3d vrel = (at(v, t.v[0]) + at(v, t.v[1]) + at(v, t.v[2])) / 3.0 - wind;
        const double s = vrel.dot(n);
        const double q = 1.0 + kf * s * s;
        const double h = kN * s * std::abs(s) / q + kL * s;       // signed normal drag magnitude
        const double hp = 2.0 * kN * std::abs(s) / (q * q) + kL;  // dh/ds
        const Vector3d ftri = -a * ((h - kT * s) * n + kT * vrel);
        for (int k = 0; k < 3; ++k) f.segment<3>(3 * t.v[static_cast<size_t>(k)]) += ftri / 3.0;
        if (lin) {
            lin->drag_block[ti] = (-lin->sv * a / 9.0) * ((hp - kT) * n * n.transpose() + kT * I);
            continue;
        }
        if (dfdv) {
            const Matrix3d D = (-a / 9.0) * ((hp - kT) * n * n.transpose() + kT * I);
            for (int s9 = 0; s9 < 9; ++s9) dfdv->block(t.slots[static_cast<size_t>(s9)]) += D;
        }
        if (dfdx && mode == JacobianMode::exact) {
            const Vector3d vT = vrel - s * n;
            const Matrix3d dF_dN = -0.5 * ((hp - kT) * n * vT.transpose() + (h - kT * s) * I + kT * vrel * n.transpose());
            const Matrix3d dN[3] = {cross_matrix(x2 - x1), -cross_matrix(x2 - x0), cross_matrix(x1 - x0)};
            for (int b = 0; b < 3; ++b) {
                const Matrix3d K = dF_dN * dN[b] / 3.0;
                for (int a2 = 0; a2 < 3; ++a2) dfdx->block(t.slots[static_cast<size_t>(3 * a2 + b)]) += K;
            }
        }
    }
}

// ---------------------------------------------------------------- contacts

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

// ---------------------------------------------------------------- energies

double ClothModel::potential_energy(const Eigen::VectorXd& x, unsigned terms) {
    double energy = 0.0;
    const double ku = (terms & ForceTerm::stretch) ? m_material.stretch_warp_N_per_m : 0.0;
    const double kv = (terms & ForceTerm::stretch) ? m_material.stretch_weft_N_per_m : 0.0;
    const double ks = (terms & ForceTerm::shear) ? m_material.shear_N_per_m : 0.0;
    for (const TriangleData& t : m_triangles) {
        const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
        const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
        const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
        const double cu = wu.norm() - 1.0, cv = wv.norm() - 1.0, cs = wu.dot(wv);
        energy += 0.5 * t.rest_area_m2 * (ku * cu * cu + kv * cv * cv + ks * cs * cs);
    }
    if ((terms & ForceTerm::bending) && m_material.bend_N_m != 0.0)
        for (size_t ei = 0; ei < m_edges.size(); ++ei) {
            const EdgeData& e = m_edges[ei];
            double theta = dihedral_angle(at(x, e.v[0]), at(x, e.v[1]), at(x, e.v[2]), at(x, e.v[3]));
            if (!m_rest_fold_rad.empty()) theta = fold_difference(theta, m_rest_fold_rad[ei]);
            energy += 0.5 * m_material.bend_N_m * e.weight * theta * theta;
        }
    if (terms & ForceTerm::gravity)
        for (int i = 0; i < vertex_count(); ++i) energy -= m_mass(i) * m_environment.gravity_m_per_s2.dot(at(x, i));
    if ((terms & ForceTerm::body_contact) && !m_environment.colliders.empty()) {
        const Eigen::VectorXd zero = Eigen::VectorXd::Zero(x.size());
        add_body_contact(x, zero, ForceTerm::body_contact, nullptr, &energy, nullptr, nullptr, JacobianMode::exact, nullptr);
    }
    if ((terms & ForceTerm::self_contact) && m_environment.self_contact.enabled)
        add_self_contact(x, nullptr, &energy, nullptr, JacobianMode::exact);
    return energy;
}

double ClothModel::kinetic_energy(const Eigen::VectorXd& v) const {
    double energy = 0.0;
    for (int i = 0; i < vertex_count(); ++i) energy += 0.5 * m_mass(i) * v.segment<3>(3 * i).squaredNorm();
    return energy;
}

double ClothModel::max_stretch_ratio(const Eigen::VectorXd& x) const {
    double worst = 0.0;
    for (const TriangleData& t : m_triangles) {
        const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
        const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
        const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
        const double r = std::max(wu.norm(), wv.norm());
        if (!(r <= worst)) worst = r;  // NaN propagates
    }
    return worst;
}

}  // namespace flowvid::cloth
