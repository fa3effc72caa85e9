// Membrane terms of the cloth model: Baraff-Witkin stretch along warp and
// weft and shear, with their damping (docs/cloth_model.md).

#include "flowvid/cloth/model.hpp"

#include "model_terms.hpp"

#include <algorithm>
#include <cmath>

namespace flowvid::cloth {

using detail::at;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// The stretch stiffness at strain C: k in tension, ratio * k in compression.
// At ratio 1 this is k * 1.0 == k exactly, so the symmetric model keeps every bit.
inline double stretch_stiffness(double k, double compression_ratio, double C) { return C < 0.0 ? k * compression_ratio : k; }

constexpr double kInvSqrt2 = 0.70710678118654752440;

// A tension-only fibre along a diagonal of the weave, w_d = (w_u + sign w_v)/sqrt 2,
// E = k/2 A max(|w_d| - 1, 0)^2: its force on w_u and w_v, and (when asked)
// d(-dE/dw_d)/dw_d = -k A (h h^T + C/|w_d| (I - h h^T)), exact and definite
// alike since C > 0 where it acts. False where the fibre is slack or k is 0
// (a fibre this triangle does not measure, ClothModel::TriangleData).
inline bool diagonal_fibre(const Vector3d& wu, const Vector3d& wv, double sign, double k, double A, Vector3d& fu,
                           Vector3d& fv, Matrix3d* K) {
    if (k == 0.0) return false;
    const Vector3d wd = kInvSqrt2 * (wu + sign * wv);
    const double ld = wd.norm();
    if (!(ld > 1.0)) return false;
    const double C = ld - 1.0;
    const Vector3d h = wd / ld;
    const Vector3d g = (-k * A * C) * h;  // -dE/dw_d
    fu += kInvSqrt2 * g;
    fv += (sign * kInvSqrt2) * g;
    if (K) {
        const double c = C / ld;
        *K = (-k * A * (1.0 - c)) * h * h.transpose();
        K->diagonal().array() += -k * A * c;
    }
    return true;
}

}  // namespace

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
    const double ru = m_material.stretch_warp_compression_ratio, rv = m_material.stretch_weft_compression_ratio;
    const double ks = m_material.shear_N_per_m;
    // Diagonal tension-only fibres count as shear (they resist shearing the weave).
    const double kd_on = shear ? m_material.diagonal_tension_N_per_m : 0.0;
    const double cu = m_material.stretch_warp_damping_N_s_per_m, cv = m_material.stretch_weft_damping_N_s_per_m;
    const double cs = m_material.shear_damping_N_s_per_m;
    // The terms switched on (the force-only and the element-wise paths).
    const double ku_on = stretch ? ku : 0.0, kv_on = stretch ? kv : 0.0, ks_on = shear ? ks : 0.0;
    const double cu_on = stretch_damp ? cu : 0.0, cv_on = stretch_damp ? cv : 0.0, cs_on = shear_damp ? cs : 0.0;
    const Matrix3d I = Matrix3d::Identity();

    if (!dfdx && !dfdv && !lin) {
        // Forces only (explicit integration): the same formulas without the
        // matrices, which is most of the cost of the hot loop.
        for (size_t ti = begin; ti < end; ++ti) {
            const TriangleData& t = m_triangles[ti];
            const Vector3d x0 = at(x, t.v[0]), x1 = at(x, t.v[1]), x2 = at(x, t.v[2]);
            const Vector3d wu = t.alpha[0] * x0 + t.alpha[1] * x1 + t.alpha[2] * x2;
            const Vector3d wv = t.beta[0] * x0 + t.beta[1] * x1 + t.beta[2] * x2;
            const double A = t.rest_area_m2;
            const double lu = wu.norm(), lv = wv.norm();
            double su = stretch_stiffness(ku_on, ru, lu - 1.0) * (lu - 1.0);
            double sv = stretch_stiffness(kv_on, rv, lv - 1.0) * (lv - 1.0);
            double sh = ks_on * t.shear_weight * wu.dot(wv);
            if (need_v) {
                const Vector3d v0 = at(v, t.v[0]), v1 = at(v, t.v[1]), v2 = at(v, t.v[2]);
                const Vector3d wu_dot = t.alpha[0] * v0 + t.alpha[1] * v1 + t.alpha[2] * v2;
                const Vector3d wv_dot = t.beta[0] * v0 + t.beta[1] * v1 + t.beta[2] * v2;
                if (lu > 0.0) su += cu_on * wu.dot(wu_dot) / lu;
                if (lv > 0.0) sv += cv_on * wv.dot(wv_dot) / lv;
                sh += cs_on * (wu_dot.dot(wv) + wu.dot(wv_dot));
            }
            // f_a = -A (su w_u/|w_u| + sh w_v) alpha_a - A (sv w_v/|w_v| + sh w_u) beta_a
            Vector3d fu = -A * ((lu > 0.0 ? su / lu : 0.0) * wu + sh * wv);
            Vector3d fv = -A * ((lv > 0.0 ? sv / lv : 0.0) * wv + sh * wu);
            if (kd_on != 0.0)
                for (size_t d = 0; d < 2; ++d)
                    diagonal_fibre(wu, wv, d == 0 ? 1.0 : -1.0, kd_on * t.diagonal_weight[d], A, fu, fv, nullptr);
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
            const double ku_at = stretch_stiffness(ku_on, ru, lu - 1.0), kv_at = stretch_stiffness(kv_on, rv, lv - 1.0);
            const double ks_t = ks_on * t.shear_weight;
            double su = ku_at * (lu - 1.0), svv = kv_at * (lv - 1.0), sh = ks_t * wu.dot(wv);
            if (need_v) {
                const Vector3d v0 = at(v, t.v[0]), v1 = at(v, t.v[1]), v2 = at(v, t.v[2]);
                const Vector3d wu_dot = t.alpha[0] * v0 + t.alpha[1] * v1 + t.alpha[2] * v2;
                const Vector3d wv_dot = t.beta[0] * v0 + t.beta[1] * v1 + t.beta[2] * v2;
                if (lu > 0.0) su += cu_on * hu.dot(wu_dot);
                if (lv > 0.0) svv += cv_on * hv.dot(wv_dot);
                sh += cs_on * (wu_dot.dot(wv) + wu.dot(wv_dot));
            }
            Vector3d fu = -A * (su * hu + sh * wv);
            Vector3d fv = -A * (svv * hv + sh * wu);
            Matrix3d Kd[2];
            bool taut[2] = {false, false};
            if (kd_on != 0.0)
                for (size_t d = 0; d < 2; ++d)
                    taut[d] = diagonal_fibre(wu, wv, d == 0 ? 1.0 : -1.0, kd_on * t.diagonal_weight[d], A, fu, fv, &Kd[d]);
            for (int a = 0; a < 3; ++a)
                f.segment<3>(3 * t.v[static_cast<size_t>(a)]) +=
                    t.alpha[static_cast<size_t>(a)] * fu + t.beta[static_cast<size_t>(a)] * fv;
            // J blocks.
            const double ju_ww = -A * (sx * ku_at * (1.0 - cpu) + sv * cu_on), ju_i = -A * sx * ku_at * cpu;
            const double jv_ww = -A * (sx * kv_at * (1.0 - cpv) + sv * cv_on), jv_i = -A * sx * kv_at * cpv;
            const double js = -A * (sx * ks_t + sv * cs_on);
            Matrix3d C0 = ju_ww * hu * hu.transpose() + js * wv * wv.transpose();
            C0.diagonal().array() += ju_i;
            Matrix3d C1 = jv_ww * hv * hv.transpose() + js * wu * wu.transpose();
            C1.diagonal().array() += jv_i;
            Matrix3d C2 = js * wv * wu.transpose();  // alpha_a beta_b
            // A diagonal fibre's block enters with (alpha_a + s beta_a)(alpha_b + s beta_b) / 2.
            for (int d = 0; d < 2; ++d)
                if (taut[d]) {
                    C0 += (0.5 * sx) * Kd[d];
                    C1 += (0.5 * sx) * Kd[d];
                    C2 += ((d == 0 ? 0.5 : -0.5) * sx) * Kd[d];
                }
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
                Vector3d qu = -A * (ku_at * ((1.0 - cpu) * hu.dot(pu) * hu + cpu * pu) + ks_t * (wvpu + wupv) * wv);
                Vector3d qv = -A * (kv_at * ((1.0 - cpv) * hv.dot(pv) * hv + cpv * pv) + ks_t * (wvpu + wupv) * wu);
                for (int d = 0; d < 2; ++d)
                    if (taut[d]) {
                        const double sign = d == 0 ? 1.0 : -1.0;
                        const Vector3d qd = Kd[d] * (kInvSqrt2 * (pu + sign * pv));
                        qu += kInvSqrt2 * qd;
                        qv += (sign * kInvSqrt2) * qd;
                    }
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

        auto axis_term = [&](const Vector3d& w, const Vector3d& w_dot, double k_tension, double ratio, double c,
                             Vector3d& fw, Matrix3d& Kww, Matrix3d& Dww) {
            const double len = w.norm();
            if (!(len > 0.0)) return;
            const Vector3d what = w / len;
            const double C = len - 1.0;
            const double k = stretch_stiffness(k_tension, ratio, C);
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
        axis_term(wu, wu_dot, ku, ru, cu, fu, Kuu, Duu);
        axis_term(wv, wv_dot, kv, rv, cv, fv, Kvv, Dvv);

        // Shear: C = wu . wv, dC/dx_a = alpha_a wv + beta_a wu.
        double shear_coef = 0.0;  // force = -shear_coef * grad C
        double shear_curv = 0.0;  // coefficient of (alpha_a beta_b + beta_a alpha_b) I in K
        if (shear || shear_damp) {
            const double C = wu.dot(wv);
            if (shear) {
                const double ks_t = ks * t.shear_weight;
                shear_coef += ks_t * A * C;
                if (want_dx) {
                    // -ks A grad C grad C^T
                    Kuu -= ks_t * A * wv * wv.transpose();
                    Kvv -= ks_t * A * wu * wu.transpose();
                    Kuv -= ks_t * A * wv * wu.transpose();
                    Kvu -= ks_t * A * wu * wv.transpose();
                    if (exact) shear_curv -= ks_t * A * C;
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
        if (kd_on != 0.0)
            for (size_t d = 0; d < 2; ++d) {
                const double sign = d == 0 ? 1.0 : -1.0;
                Matrix3d Kd;
                if (!diagonal_fibre(wu, wv, sign, kd_on * t.diagonal_weight[d], A, fu, fv, want_dx ? &Kd : nullptr) ||
                    !want_dx)
                    continue;
                Kuu += 0.5 * Kd;
                Kvv += 0.5 * Kd;
                Kuv += (0.5 * sign) * Kd;
                Kvu += (0.5 * sign) * Kd;
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

}  // namespace flowvid::cloth
