// Shear read on a grid's cells instead of its triangles (docs/cloth_model.md,
// "Shear on the cells' four corners"). A triangle reads w_u . w_v at the corner
// opposite its diagonal edge, so a cell folded along the diagonal no edge
// follows is read as sheared. A cell folded along either diagonal keeps the
// corner angles at the ends of the fold line and changes the other two; an
// in-plane shear changes all four. So the cell stores the shear of the pair of
// corners that moved less: E = ks/2 A h(P_wing, P_diagonal), P the mean
// square shear of a diagonal pair of corners, h(a, b) = 2 a b / (a + b) (the
// harmonic mean: a pure shear stores ks/2 A gamma^2 as the triangles do, a
// fold along either diagonal stores nothing). With the fibres switch, square
// cells also carry the tension-only diagonal fibres on both their diagonals
// (Blender's shear springs) instead of on the triangles' edges.
//
// The material's shear_cell_fraction (preset key since 1.2) is the share of
// ks read on the cells; the cells' triangles keep the rest. At 0 no cells are
// built and every triangle keeps its own shear, bit for bit. The cells' fibres
// are experimental, for the capacity study (#28): off unless the environment
// sets FLOWVID_EXPERIMENTAL_CELL_FIBRES.

#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

namespace flowvid::cloth {

using detail::at;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {
using Vector12 = Eigen::Matrix<double, 12, 1>;
using Matrix12 = Eigen::Matrix<double, 12, 12>;

bool cell_fibres_enabled() {
    static const bool enabled = std::getenv("FLOWVID_EXPERIMENTAL_CELL_FIBRES") != nullptr;
    return enabled;
}
}  // namespace

void ClothModel::compute_cells() {
    m_cells.clear();
    for (TriangleData& t : m_triangles) t.shear_weight = 1.0;
    m_cells_fraction = m_material.shear_cell_fraction;
    if (m_cells_fraction == 0.0 && !cell_fibres_enabled()) return;
    const double c = std::cos(m_material.bias_angle_rad), s = std::sin(m_material.bias_angle_rad);
    const Eigen::Vector2d warp(c, s), weft(-s, c);
    std::map<std::array<int, 3>, size_t> triangle_of;
    for (size_t ti = 0; ti < m_triangles.size(); ++ti) {
        std::array<int, 3> key = m_triangles[ti].v;
        std::sort(key.begin(), key.end());
        triangle_of[key] = ti;
    }
    const auto along = [](const Eigen::Vector2d& d, const Eigen::Vector2d& axis) {
        return std::abs(d.x() * axis.y() - d.y() * axis.x()) <= 1e-9 * d.norm();
    };
    std::vector<bool> claimed(m_triangles.size(), false);
    for (const BendingStencil& stencil : m_stencils) {
        const std::array<int, 4>& V = stencil.vertices;
        std::array<Eigen::Vector2d, 4> uv;
        for (size_t k = 0; k < 4; ++k) uv[k] = m_mesh.material_uv_m[static_cast<size_t>(V[k])];
        if ((uv[2] + uv[3] - uv[0] - uv[1]).norm() > 1e-9 * (uv[0] - uv[1]).norm()) continue;  // not a parallelogram
        CellData cell;
        cell.v = V;
        bool rectangle = true;
        for (int k = 0; k < 4 && rectangle; ++k) {
            // Corners 0 and 1 (the diagonal's ends) meet the wings 2 and 3; the wings meet 0 and 1.
            const int n1 = k < 2 ? 2 : 0, n2 = k < 2 ? 3 : 1;
            const Eigen::Vector2d d1 = uv[static_cast<size_t>(n1)] - uv[static_cast<size_t>(k)];
            const Eigen::Vector2d d2 = uv[static_cast<size_t>(n2)] - uv[static_cast<size_t>(k)];
            int p = -1, q = -1;
            if (along(d1, warp) && along(d2, weft))
                p = n1, q = n2;
            else if (along(d2, warp) && along(d1, weft))
                p = n2, q = n1;
            else
                rectangle = false;
            if (!rectangle) break;
            const double du = (uv[static_cast<size_t>(p)] - uv[static_cast<size_t>(k)]).dot(warp);
            const double dv = (uv[static_cast<size_t>(q)] - uv[static_cast<size_t>(k)]).dot(weft);
            cell.corner[static_cast<size_t>(k)] = {k, p, q};
            cell.inverse_uv[static_cast<size_t>(k)] = 1.0 / (du * dv);
        }
        if (!rectangle) continue;
        std::array<int, 3> a = {V[0], V[1], V[2]}, b = {V[0], V[1], V[3]};
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        const auto ia = triangle_of.find(a), ib = triangle_of.find(b);
        if (ia == triangle_of.end() || ib == triangle_of.end() || claimed[ia->second] || claimed[ib->second]) continue;
        claimed[ia->second] = claimed[ib->second] = true;
        cell.rest_area_m2 = m_triangles[ia->second].rest_area_m2 + m_triangles[ib->second].rest_area_m2;
        const double d01 = (uv[1] - uv[0]).norm(), d23 = (uv[3] - uv[2]).norm();
        if (cell_fibres_enabled() && std::abs(d01 - d23) <= 1e-9 * d01) cell.diagonal_rest_m = {d01, d23};
        if (cell_fibres_enabled()) {
            // Square cells carry the fibres on both their diagonals instead of the triangles.
            if (cell.diagonal_rest_m[0] > 0.0)
                m_triangles[ia->second].diagonal_weight = m_triangles[ib->second].diagonal_weight = {0.0, 0.0};
        }
        m_cells.push_back(cell);
    }
    // The cells' triangles keep the share not read on the cells.
    for (size_t ti = 0; ti < m_triangles.size(); ++ti)
        if (claimed[ti]) m_triangles[ti].shear_weight = 1.0 - m_cells_fraction;
}

void ClothModel::add_cell_shear(const Eigen::VectorXd& x, Eigen::VectorXd* f, double* energy, BlockSparseMatrix* dfdx,
                                JacobianMode mode, Linearization* lin, const Eigen::VectorXd* product_of) const {
    const double ks = m_material.shear_cell_fraction * m_material.shear_N_per_m;
    const double kd = m_material.diagonal_tension_N_per_m;
    if (m_cells.empty() || (ks == 0.0 && kd == 0.0)) return;
    const bool exact = mode == JacobianMode::exact;
    for (size_t ci = 0; ci < m_cells.size(); ++ci) {
        const CellData& cell = m_cells[ci];
        std::array<Vector3d, 4> X;
        for (size_t k = 0; k < 4; ++k) X[k] = at(x, cell.v[k]);
        std::array<double, 4> shear;
        std::array<Vector12, 4> grad;
        for (size_t k = 0; k < 4; ++k) {
            const auto [c, p, q] = cell.corner[k];
            const double w = cell.inverse_uv[k];
            const Vector3d ep = X[static_cast<size_t>(p)] - X[static_cast<size_t>(c)];
            const Vector3d eq = X[static_cast<size_t>(q)] - X[static_cast<size_t>(c)];
            shear[k] = w * ep.dot(eq);
            grad[k].setZero();
            grad[k].segment<3>(3 * p) = w * eq;
            grad[k].segment<3>(3 * q) = w * ep;
            grad[k].segment<3>(3 * c) = -w * (ep + eq);
        }
        const double pd = 0.5 * (shear[0] * shear[0] + shear[1] * shear[1]);
        const double pw = 0.5 * (shear[2] * shear[2] + shear[3] * shear[3]);
        const double sum = pd + pw;
        // h and its derivatives; at no shear at all (sum 0) h's slope depends
        // on the direction: the pure shear's 1/2, 1/2 is used.
        double h = 0.0, hw = 0.5, hd = 0.5, hww = 0.0, hwd = 0.0, hdd = 0.0;
        if (sum > 1e-30) {
            h = 2.0 * pw * pd / sum;
            hw = 2.0 * pd * pd / (sum * sum);
            hd = 2.0 * pw * pw / (sum * sum);
            const double cube = sum * sum * sum;
            hww = -4.0 * pd * pd / cube;
            hdd = -4.0 * pw * pw / cube;
            hwd = 4.0 * pw * pd / cube;
        }
        const double scale = 0.5 * ks * cell.rest_area_m2;
        if (energy) *energy += scale * h;
        const Vector12 grad_pd = shear[0] * grad[0] + shear[1] * grad[1];
        const Vector12 grad_pw = shear[2] * grad[2] + shear[3] * grad[3];
        // Tension-only fibres on both diagonals: E = kd/2 A max(|d|/L - 1, 0)^2 each.
        Vector12 fibre_grad = Vector12::Zero();
        Matrix12 fibre_hessian = Matrix12::Zero();
        if (kd != 0.0 && cell.diagonal_rest_m[0] > 0.0)
            for (int d = 0; d < 2; ++d) {
                const int i = 2 * d, j = 2 * d + 1;
                const double L = cell.diagonal_rest_m[static_cast<size_t>(d)];
                const Vector3d diag = X[static_cast<size_t>(j)] - X[static_cast<size_t>(i)];
                const double len = diag.norm(), strain = len / L - 1.0;
                if (!(strain > 0.0)) continue;
                const double k = kd * cell.rest_area_m2;
                if (energy) *energy += 0.5 * k * strain * strain;
                const Vector3d unit = diag / len;
                const Vector3d g = (k * strain / L) * unit;  // dE/dx_j
                fibre_grad.segment<3>(3 * j) += g;
                fibre_grad.segment<3>(3 * i) -= g;
                Matrix3d Hd = (k / (L * L)) * ((1.0 - strain / (1.0 + strain)) * unit * unit.transpose());
                Hd.diagonal().array() += (k / (L * L)) * strain / (1.0 + strain);
                fibre_hessian.block<3, 3>(3 * i, 3 * i) += Hd;
                fibre_hessian.block<3, 3>(3 * j, 3 * j) += Hd;
                fibre_hessian.block<3, 3>(3 * i, 3 * j) -= Hd;
                fibre_hessian.block<3, 3>(3 * j, 3 * i) -= Hd;
            }
        if (f) {
            const Vector12 g = scale * (hw * grad_pw + hd * grad_pd) + fibre_grad;
            for (size_t a = 0; a < 4; ++a) f->segment<3>(3 * cell.v[a]) -= g.segment<3>(3 * static_cast<int>(a));
        }
        if (!dfdx && !lin) continue;
        // Hessian of E / scale; definite: the Gauss-Newton part only (h is
        // concave, so leaving out its curvature keeps the matrix definite).
        Matrix12 H = hw * (grad[2] * grad[2].transpose() + grad[3] * grad[3].transpose()) +
                     hd * (grad[0] * grad[0].transpose() + grad[1] * grad[1].transpose());
        if (exact && dfdx) {
            for (size_t k = 0; k < 4; ++k) {
                const double weight = (k < 2 ? hd : hw) * shear[k] * cell.inverse_uv[k];
                const auto [c, p, q] = cell.corner[k];
                const Matrix3d I = Matrix3d::Identity() * weight;
                H.block<3, 3>(3 * p, 3 * q) += I;
                H.block<3, 3>(3 * q, 3 * p) += I;
                H.block<3, 3>(3 * c, 3 * c) += 2.0 * I;
                H.block<3, 3>(3 * c, 3 * p) -= I;
                H.block<3, 3>(3 * p, 3 * c) -= I;
                H.block<3, 3>(3 * c, 3 * q) -= I;
                H.block<3, 3>(3 * q, 3 * c) -= I;
            }
            H += hww * grad_pw * grad_pw.transpose() + hdd * grad_pd * grad_pd.transpose() +
                 hwd * (grad_pw * grad_pd.transpose() + grad_pd * grad_pw.transpose());
        }
        const Matrix12 K = -scale * H - fibre_hessian;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                const Matrix3d block = K.block<3, 3>(3 * a, 3 * b);
                if (dfdx) dfdx->block(cell.slots[static_cast<size_t>(4 * a + b)]) += block;
                if (lin) lin->cell_blocks[16 * ci + static_cast<size_t>(4 * a + b)] = lin->sx * block;
            }
        if (lin) lin->has_cells = true;
        if (lin && product_of) {
            Vector12 p;
            for (int a = 0; a < 4; ++a) p.segment<3>(3 * a) = at(*product_of, cell.v[static_cast<size_t>(a)]);
            const Vector12 q = K * p;
            for (int a = 0; a < 4; ++a) lin->dfdx_product.segment<3>(3 * cell.v[static_cast<size_t>(a)]) += q.segment<3>(3 * a);
        }
    }
}

}  // namespace flowvid::cloth
