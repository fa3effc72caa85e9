#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include "flowvid/cloth/geometry.hpp"
#include "flowvid/error.hpp"
#include "flowvid/thread_pool.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

// The cloth model's construction, the evaluation that dispatches to the
// energy terms (membrane.cpp, bending.cpp, drag.cpp, collision.cpp), the
// implicit integrator's linearisation and the energies.

namespace flowvid::cloth {

using detail::at;
using detail::fold_difference;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

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
    if (m_material.bias_angle_rad != m_frame_bias_rad) {
        compute_material_frames();  // the cells too
    } else if (m_material.shear_cell_fraction != m_cells_fraction) {
        refresh_cells();
    }
    m_total_mass = 0.0;
    const double hem = m_material.hem_line_density_kg_per_m;
    for (int i = 0; i < vertex_count(); ++i) {
        m_mass(i) = m_material.areal_density_kg_per_m2 * m_vertex_area(i);
        if (hem != 0.0) m_mass(i) += hem * m_vertex_boundary_length(i);  // skipped at 0: no bit changes
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
    compute_diagonal_fibre_weights();
    for (int i = 0; i < n; ++i)
        if (!(m_vertex_area(i) > 0.0))
            diagnostics.error("material_uv_m[" + std::to_string(i) + "]", "vertex belongs to no triangle (it has no mass)",
                              "remove unused vertices");
    diagnostics.throw_if_errors();

    // The free boundary: edges with one incident triangle (for the hem).
    {
        std::map<std::pair<int, int>, int> incident;
        for (const TriangleData& t : m_triangles)
            for (int a = 0; a < 3; ++a) {
                const int i = t.v[static_cast<size_t>(a)], j = t.v[static_cast<size_t>((a + 1) % 3)];
                ++incident[{std::min(i, j), std::max(i, j)}];
            }
        m_vertex_boundary_length = Eigen::VectorXd::Zero(n);
        m_boundary_length = 0.0;
        for (const auto& [edge, count] : incident) {
            if (count != 1) continue;
            const double length = (m_mesh.material_uv_m[static_cast<size_t>(edge.first)] -
                                   m_mesh.material_uv_m[static_cast<size_t>(edge.second)]).norm();
            m_vertex_boundary_length(edge.first) += 0.5 * length;
            m_vertex_boundary_length(edge.second) += 0.5 * length;
            m_boundary_length += length;
        }
    }

    m_frame_bias_rad = m_material.bias_angle_rad;
    m_rest_fold_rad.clear();
    m_mass.resize(n);
    set_material(m_material);

    compute_cells();
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
    index_cells(pattern);
}

void ClothModel::refresh_cells() {
    compute_cells();
    // Before validate_and_precompute has built the pattern there is nothing to index.
    if (m_cells.empty())
        m_vertex_cell_local.clear();
    else if (!m_pattern_pairs.empty())
        index_cells(make_jacobian_matrix());
}

void ClothModel::index_cells(const BlockSparseMatrix& pattern) {
    // A cell's vertices are a triangle's or a hinge's wings: all in the pattern.
    m_vertex_cell_local.clear();
    if (m_cells.empty()) return;
    m_vertex_cell_local.assign(static_cast<size_t>(vertex_count()), {});
    for (size_t c = 0; c < m_cells.size(); ++c) {
        CellData& cell = m_cells[c];
        for (int a = 0; a < 4; ++a) {
            m_vertex_cell_local[static_cast<size_t>(cell.v[static_cast<size_t>(a)])].push_back({static_cast<int>(c), a});
            for (int b = 0; b < 4; ++b)
                cell.slots[static_cast<size_t>(4 * a + b)] = pattern.slot(cell.v[static_cast<size_t>(a)], cell.v[static_cast<size_t>(b)]);
        }
    }
}

void ClothModel::compute_material_frames() {
    for (TriangleData& t : m_triangles)
        frame_coefficients(m_mesh.material_uv_m[static_cast<size_t>(t.v[0])],
                           m_mesh.material_uv_m[static_cast<size_t>(t.v[1])],
                           m_mesh.material_uv_m[static_cast<size_t>(t.v[2])], m_material.bias_angle_rad, t.alpha, t.beta);
    compute_diagonal_fibre_weights();
    refresh_cells();
    m_frame_bias_rad = m_material.bias_angle_rad;
}

void ClothModel::compute_diagonal_fibre_weights() {
    // A fibre measured from a triangle's deformation gradient alone runs along
    // one of the triangle's edges (the cell's diagonal) or across the
    // triangle to a point that only exists in its plane. Such a virtual fibre
    // is stretched whenever the cell folds along its other diagonal, so a
    // coarse mesh cannot make the folds a fabric with tension-only bias
    // fibres makes freely (docs/cloth_model.md, "Diagonal fibres on the mesh's
    // own diagonals"). Where the mesh has real edges along a fibre, the
    // fibre is measured on them instead.
    const double c = std::cos(m_material.bias_angle_rad), s = std::sin(m_material.bias_angle_rad);
    const Eigen::Vector2d warp(c, s), weft(-s, c);
    const std::array<Eigen::Vector2d, 2> fibre = {(warp + weft).normalized(), (warp - weft).normalized()};
    std::array<double, 2> along_area = {0.0, 0.0};
    std::vector<std::array<bool, 2>> along(m_triangles.size(), {false, false});
    for (size_t ti = 0; ti < m_triangles.size(); ++ti) {
        const TriangleData& t = m_triangles[ti];
        for (size_t k = 0; k < 3; ++k) {
            const Eigen::Vector2d e = m_mesh.material_uv_m[static_cast<size_t>(t.v[(k + 1) % 3])] -
                                      m_mesh.material_uv_m[static_cast<size_t>(t.v[k])];
            for (size_t d = 0; d < 2; ++d)
                if (std::abs(e.x() * fibre[d].y() - e.y() * fibre[d].x()) <= 1e-9 * e.norm()) along[ti][d] = true;
        }
        for (size_t d = 0; d < 2; ++d)
            if (along[ti][d]) along_area[d] += t.rest_area_m2;
    }
    for (size_t d = 0; d < 2; ++d) {
        // A mesh whose edges follow the fibre in a few triangles only (an
        // irregular garment) keeps the per-triangle measure: a handful of
        // edges cannot carry the whole fabric's bias. A checkerboard grid has
        // half its area along each diagonal.
        const bool on_edges = along_area[d] > 0.0 && along_area[d] >= kMinAreaAlongDiagonal * m_total_area;
        const double weight = on_edges ? m_total_area / along_area[d] : 1.0;
        for (size_t ti = 0; ti < m_triangles.size(); ++ti)
            m_triangles[ti].diagonal_weight[d] = on_edges ? (along[ti][d] ? weight : 0.0) : 1.0;
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
    lin.has_cells = false;
    lin.cell_blocks.resize(16 * m_cells.size());
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
                       m_material.drag_linear_normal_kg_per_m2_s != 0.0 || m_environment.wind_pressure_kg_per_m3 != 0.0);
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
            m_pool->run(kChunks, [&](std::size_t c, int) { chunk(static_cast<int>(c)); });
        else
            for (int c = 0; c < kChunks; ++c) chunk(c);
        force = m_chunk_force[0];
        for (int c = 1; c < kChunks; ++c) force += m_chunk_force[static_cast<size_t>(c)];
        if (lin && product_of)
            for (int c = 0; c < kChunks; ++c) lin->dfdx_product += m_chunk_product[static_cast<size_t>(c)];
    }
    if (terms & ForceTerm::shear) add_cell_shear(x, &force, nullptr, dfdx, mode, lin, product_of);
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
        m_pool = std::make_unique<ThreadPool>(threads);
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
    if (lin.has_cells)
        for (size_t c = 0; c < m_cells.size(); ++c) {
            const CellData& cell = m_cells[c];
            const Matrix3d* B = &lin.cell_blocks[16 * c];
            for (int a = 0; a < 4; ++a) {
                Vector3d q = Vector3d::Zero();
                for (int b = 0; b < 4; ++b) q += B[4 * a + b] * at(p, cell.v[static_cast<size_t>(b)]);
                out.segment<3>(3 * cell.v[static_cast<size_t>(a)]) += q;
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
            if (lin.has_cells)
                for (const auto& [c, a] : m_vertex_cell_local[static_cast<size_t>(i)]) {
                    const CellData& cell = m_cells[static_cast<size_t>(c)];
                    const Matrix3d* B = &lin.cell_blocks[16 * static_cast<size_t>(c)];
                    for (int b = 0; b < 4; ++b) J.block(cell.slots[static_cast<size_t>(4 * a + b)]) += B[4 * a + b];
                }
            if (lin.has_vertex) J.block(J.diagonal_slot(i)) += lin.vertex_block[static_cast<size_t>(i)];
        }
    };
    if (m_pool)
        m_pool->run(kChunks, [&](std::size_t c, int) { rows(static_cast<int>(c)); });
    else
        for (int c = 0; c < kChunks; ++c) rows(c);
    for (const auto& e : lin.pair_blocks) J.add(e.row, e.col, e.value);
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
        // Compression stores the ratio's share (exactly ku, kv at ratio 1).
        const double ku_at = cu < 0.0 ? ku * m_material.stretch_warp_compression_ratio : ku;
        const double kv_at = cv < 0.0 ? kv * m_material.stretch_weft_compression_ratio : kv;
        energy += 0.5 * t.rest_area_m2 * (ku_at * cu * cu + kv_at * cv * cv + ks * t.shear_weight * cs * cs);
        if ((terms & ForceTerm::shear) && m_material.diagonal_tension_N_per_m != 0.0)
            for (const double sign : {1.0, -1.0}) {
                const double stretched = std::max((wu + sign * wv).norm() * 0.70710678118654752440 - 1.0, 0.0);
                energy += 0.5 * t.rest_area_m2 * m_material.diagonal_tension_N_per_m *
                          t.diagonal_weight[sign > 0.0 ? 0 : 1] * stretched * stretched;
            }
    }
    if (terms & ForceTerm::shear) add_cell_shear(x, nullptr, &energy, nullptr, JacobianMode::exact, nullptr, nullptr);
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
