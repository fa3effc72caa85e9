#pragma once
// The cloth model: Baraff-Witkin stretch, shear and bending condition
// functions with their damping, the thesis's nonlinear air drag, gravity and
// contact penalties. Forces with analytic Jacobians df/dx and df/dv.
//
// Shapes: positions x and velocities v are 3*#V vectors (x0 y0 z0 x1 ...),
// metres and m/s; forces are 3*#V, newtons.

#include "flowvid/cloth/block_matrix.hpp"
#include "flowvid/cloth/collision.hpp"
#include "flowvid/cloth/geometry.hpp"
#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/mesh.hpp"

#include <Eigen/Core>

#include <functional>
#include <memory>
#include <vector>

namespace flowvid {
class ThreadPool;
}

namespace flowvid::cloth {

// Which terms to evaluate (bit mask).
namespace ForceTerm {
enum : unsigned {
    stretch = 1u << 0,
    shear = 1u << 1,
    bending = 1u << 2,
    stretch_damping = 1u << 3,
    shear_damping = 1u << 4,
    bending_damping = 1u << 5,
    drag = 1u << 6,
    gravity = 1u << 7,
    body_contact = 1u << 8,
    friction = 1u << 9,
    self_contact = 1u << 10,
    elastic = stretch | shear | bending,
    damping = stretch_damping | shear_damping | bending_damping,
    // Terms with a potential energy (potential_energy() sums these).
    conservative = elastic | gravity | body_contact | self_contact,
    all = (1u << 11) - 1,
};
}  // namespace ForceTerm

// exact: the true derivatives (tests, Newton near a stable minimum).
// definite: for implicit solves, -df/dx and -df/dv made positive
// semi-definite and symmetric: compressive stretch curvature clamped, the
// C * d2C/dx2 terms of shear and bending dropped (Gauss-Newton), the
// non-symmetric position derivatives of damping, drag and friction dropped.
enum class JacobianMode { exact, definite };

struct Environment {
    Eigen::Vector3d gravity_m_per_s2{0.0, 0.0, -9.81};  // world z up, as in captures
    // Air velocity: `wind_field(position, time)` when set, else the constant.
    // Jacobians treat the wind as locally uniform.
    Eigen::Vector3d wind_m_per_s = Eigen::Vector3d::Zero();
    std::function<Eigen::Vector3d(const Eigen::Vector3d& position_m, double time_s)> wind_field;
    // The wind's push as on a flat plate, c = rho_air C_d / 2 (kg/m^3): per
    // triangle f = a c (w.n)|w.n| n, on top of the drag law on the velocity
    // relative to the air. A drag law fitted to a swatch's own motion is
    // tuned to small relative speeds (its degradation caps its push at kN/kf,
    // a few per cent of the weight of cotton), so a draught of a metre per
    // second would barely lean the swatch through it alone. 0: the drag law
    // alone. No velocity derivative; its position derivative only in
    // JacobianMode::exact (dropped like the drag's in definite mode).
    double wind_pressure_kg_per_m3 = 0.0;
    std::vector<Collider> colliders;
    ContactSettings contact;
    SelfContactSettings self_contact;
};

// The definite Jacobians of one evaluation, J = sx df/dx + sv df/dv, kept per
// element instead of assembled (ClothModel::linearize), for the implicit
// integrator: assembled row by row (no two threads write a block) or applied
// matrix-free. Equal to sx K + sv D of the assembled JacobianMode::definite
// matrices (tested).
struct Linearization {
    double sx = 0.0, sv = 0.0;
    // Triangle t, local vertices a, b: block (a, b) = alpha_a U_b + beta_a V_b
    // with U_0..2, V_0..2 stored at 6 t.
    std::vector<Eigen::Matrix3d> membrane_blocks;
    std::vector<Vector12d> hinge_gradient;       // per interior edge: block (a, b) = c g_a g_b^T
    std::vector<double> hinge_coefficient;
    std::vector<Eigen::Matrix3d> drag_block;     // per triangle: the block between any two of its vertices
    std::vector<Eigen::Matrix3d> vertex_block;   // contacts and friction (diagonal blocks)
    std::vector<BlockSparseMatrix::Extra> pair_blocks;  // self contact
    std::vector<Eigen::Matrix3d> cell_blocks;   // per grid cell: block (a, b) at 16 c + 4 a + b (ClothModel::CellData)
    bool has_membrane = false, has_bending = false, has_drag = false, has_vertex = false, has_cells = false;
    // df/dx (definite, unscaled) times the vector given to linearize.
    Eigen::VectorXd dfdx_product;
};

class ClothModel {
public:
    // Throws flowvid::ValidationError for a mesh or material that cannot be
    // simulated (degenerate rest triangles, non-manifold edges, bad numbers).
    ClothModel(ClothMesh mesh, ClothMaterial material, Environment environment = {});
    ~ClothModel();
    ClothModel(ClothModel&&) noexcept;
    ClothModel& operator=(ClothModel&&) noexcept;

    const ClothMesh& mesh() const { return m_mesh; }
    const ClothMaterial& material() const { return m_material; }
    const Environment& environment() const { return m_environment; }
    int vertex_count() const { return m_mesh.vertex_count(); }
    // #V lumped masses: areal density x one third of each incident rest
    // triangle, plus the hem's line density x half of each incident rest
    // boundary edge.
    const Eigen::VectorXd& vertex_masses_kg() const { return m_mass; }
    // Rest length of the mesh's free boundary (edges with one triangle), m.
    double boundary_length_m() const { return m_boundary_length; }
    double total_mass_kg() const { return m_total_mass; }
    double total_rest_area_m2() const { return m_total_area; }
    const std::vector<BendingStencil>& bending_stencils() const { return m_stencils; }

    // Changes the material without rebuilding the topology (for fitting); a
    // new bias_angle_rad recomputes the triangles' warp/weft frames.
    void set_material(const ClothMaterial& material);
    void set_environment(Environment environment);

    // Overwrites `force` with the sum of `terms` at (x, v, time). When given,
    // `dfdx` / `dfdv` (with the pattern of make_jacobian_matrix()) are cleared
    // and filled with the derivatives of the same terms.
    void evaluate(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms,
                  Eigen::VectorXd& force, BlockSparseMatrix* dfdx = nullptr, BlockSparseMatrix* dfdv = nullptr,
                  JacobianMode mode = JacobianMode::exact);
    // Potential energy (J) of the conservative terms among `terms`; gravity is
    // -sum m g.x, so it is relative to the origin.
    // Forces as evaluate(), with J = sx df/dx + sv df/dv (definite) kept per
    // element; when `product_of` is given, also lin.dfdx_product = df/dx p.
    void linearize(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms, double sx,
                   double sv, Eigen::VectorXd& force, Linearization& lin, const Eigen::VectorXd* product_of = nullptr);
    // out = J p from the element data, without assembling.
    void apply_product(const Linearization& lin, const Eigen::VectorXd& p, Eigen::VectorXd& out) const;
    // J assembled (pattern of make_jacobian_matrix()), row by row.
    void assemble_product(const Linearization& lin, BlockSparseMatrix& J);

    // Worker threads for the element loops (1 = none). Results do not depend
    // on it (fixed chunks, summed in order). A wind_field must then be safe to
    // call from several threads.
    void set_threads(int threads);
    int threads() const;
    ThreadPool* worker_pool() { return m_pool.get(); }
    static constexpr int kChunks = 2;
    // A diagonal fibre family is measured on the mesh's own edges where
    // triangles with an edge along it cover at least this share of the area.
    static constexpr double kMinAreaAlongDiagonal = 0.4;

    double potential_energy(const Eigen::VectorXd& x, unsigned terms = ForceTerm::conservative);
    double kinetic_energy(const Eigen::VectorXd& v) const;
    BlockSparseMatrix make_jacobian_matrix() const;

    // Bending memory (ClothMaterial::bend_memory_rate_per_s): one rest fold
    // angle theta0 per interior edge, in the order of bending_stencils(),
    // radians; the bending energy is k/2 * weight * (theta - theta0)^2 (the
    // difference taken in (-pi, pi]). All 0 (the flat rest state) until a
    // dynamic run updates them; solve_static_equilibrium and
    // ClothSimulator::set_state reset them.
    Eigen::VectorXd rest_fold_angles_rad() const;
    // Throws std::invalid_argument unless there is one finite angle per edge.
    void set_rest_fold_angles_rad(const Eigen::VectorXd& angles_rad);
    void reset_rest_fold_angles();
    bool has_rest_fold() const { return !m_rest_fold_rad.empty(); }
    // The memory law over one accepted step of length dt_s at positions x:
    // theta0 += (1 - exp(-r dt)) (theta - theta0), r = bend_memory_rate_per_s.
    // Does nothing when r <= 0. When `bending_force_change` (3*#V) is given,
    // adds the change of the bending force at x that the new rest angles make
    // (so that a force evaluated before the update can be corrected).
    void update_rest_fold_angles(const Eigen::VectorXd& x, double dt_s,
                                 Eigen::VectorXd* bending_force_change = nullptr);

    // Largest of |w_u|, |w_v| (stretch ratio along warp/weft) over triangles.
    double max_stretch_ratio(const Eigen::VectorXd& x) const;

    // Contact bookkeeping (candidate lists are rebuilt when vertices have
    // moved more than half the search margin since the last build).
    struct ContactStatistics {
        long long self_rebuilds = 0;
        long long body_rebuilds = 0;
        int self_candidates = 0;
        int body_candidates = 0;
    };
    const ContactStatistics& contact_statistics() const { return m_contact_stats; }

    struct TriangleData {
        std::array<int, 3> v;
        std::array<double, 3> alpha;  // w_u = sum alpha_a x_a (u: the warp, rotated by the bias angle)
        std::array<double, 3> beta;   // w_v = sum beta_a x_a (v: the weft)
        double rest_area_m2;
        // Weights of the diagonal fibres (1, 1) and (1, -1) of the weave in
        // this triangle (compute_diagonal_fibre_weights).
        std::array<double, 2> diagonal_weight{1.0, 1.0};
        // 0 where a grid cell measures this triangle's shear (CellData), else 1.
        double shear_weight = 1.0;
        std::array<int, 9> slots;     // Jacobian blocks (a, b) -> slot
    };
    struct EdgeData {
        std::array<int, 4> v;
        double weight;                // |e|^2 / (A1 + A2) at rest, dimensionless
        std::array<int, 16> slots;
    };

    // A grid cell: two triangles that share a diagonal edge and make a
    // rectangle along warp and weft. Its shear is read at all four corners
    // (cell_shear.cpp): built when the material's shear_cell_fraction is
    // above 0 (or the experimental FLOWVID_EXPERIMENTAL_CELL_FIBRES is set).
    struct CellData {
        std::array<int, 4> v;                 // edge v0-v1 (the diagonal), wings v2, v3
        std::array<std::array<int, 3>, 4> corner;  // per corner: local (c, p, q), p along the warp, q the weft
        std::array<double, 4> inverse_uv;     // 1 / (du_p dv_q): s = k (x_p - x_c).(x_q - x_c) is w_u . w_v there
        double rest_area_m2 = 0.0;
        // Rest lengths of the diagonals v0-v1 and v2-v3 when the cell is square
        // (they then run along the weave's bias), else 0: no fibres on the cell.
        std::array<double, 2> diagonal_rest_m{0.0, 0.0};
        std::array<int, 16> slots;            // Jacobian blocks (a, b) -> slot
    };
    const std::vector<CellData>& cells() const { return m_cells; }

private:
    void compute_cells();
    void index_cells(const BlockSparseMatrix& pattern);  // slots and the vertex -> cell map
    void refresh_cells();  // both, after the material's cell share or frames changed
    // Fold-free cell shear and the cells' fibres (docs/cloth_model.md): their
    // forces, energy, and Jacobians or the linearisation's cell blocks.
    void add_cell_shear(const Eigen::VectorXd& x, Eigen::VectorXd* f, double* energy, BlockSparseMatrix* dfdx,
                        JacobianMode mode, Linearization* lin, const Eigen::VectorXd* product_of) const;
    void validate_and_precompute();
    void compute_material_frames();  // alpha, beta of every triangle for m_material.bias_angle_rad
    // Where the mesh has edges along a diagonal of the weave (a grid with its
    // cells split along alternating diagonals), that fibre family is measured
    // on those edges only, weighted so that its total area is the mesh's;
    // elsewhere each triangle measures both fibres (weights 1). Depends on the
    // bias angle.
    void compute_diagonal_fibre_weights();
    void evaluate_terms(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, unsigned terms,
                        Eigen::VectorXd& force, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode,
                        Linearization* lin, const Eigen::VectorXd* product_of = nullptr);
    void add_membrane(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd& f,
                      BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                      size_t begin, size_t end, const Eigen::VectorXd* product_of = nullptr,
                      Eigen::VectorXd* product = nullptr) const;
    void add_bending(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd& f,
                     BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                     size_t begin, size_t end, const Eigen::VectorXd* product_of = nullptr,
                     Eigen::VectorXd* product = nullptr) const;
    void add_drag(const Eigen::VectorXd& x, const Eigen::VectorXd& v, double time_s, Eigen::VectorXd& f,
                  BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode, Linearization* lin,
                  size_t begin, size_t end) const;
    void add_body_contact(const Eigen::VectorXd& x, const Eigen::VectorXd& v, unsigned terms, Eigen::VectorXd* f,
                          double* energy, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv, JacobianMode mode,
                          Linearization* lin = nullptr, const Eigen::VectorXd* product_of = nullptr);
    void add_self_contact(const Eigen::VectorXd& x, Eigen::VectorXd* f, double* energy, BlockSparseMatrix* dfdx,
                          JacobianMode mode, Linearization* lin = nullptr, const Eigen::VectorXd* product_of = nullptr);
    void update_body_candidates(const Eigen::VectorXd& x);
    void update_self_candidates(const Eigen::VectorXd& x);

    ClothMesh m_mesh;
    ClothMaterial m_material;
    Environment m_environment;
    std::vector<BendingStencil> m_stencils;
    std::vector<TriangleData> m_triangles;
    std::vector<EdgeData> m_edges;
    std::vector<CellData> m_cells;
    double m_cells_fraction = 0.0;  // the shear_cell_fraction the cells and weights were built for
    double m_frame_bias_rad = 0.0;        // the bias angle alpha, beta were computed for
    std::vector<double> m_rest_fold_rad;  // per edge; empty: all 0 (no extra work in the loops)
    std::vector<std::pair<int, int>> m_pattern_pairs;
    Eigen::VectorXd m_mass;
    Eigen::VectorXd m_vertex_area;
    Eigen::VectorXd m_vertex_boundary_length;  // half of each incident boundary edge, m
    double m_boundary_length = 0.0;
    double m_total_mass = 0.0;
    double m_total_area = 0.0;

    // Contacts.
    struct BodyMeshGrid;
    std::vector<std::vector<int>> m_vertex_triangles;  // incident triangles per vertex
    std::vector<std::pair<int, int>> m_body_candidates;  // (vertex, collider triangle packed id)
    std::vector<std::pair<int, int>> m_self_candidates;  // (vertex, triangle)
    Eigen::VectorXd m_body_build_x;
    Eigen::VectorXd m_self_build_x;
    bool m_body_built = false;
    bool m_self_built = false;
    std::vector<int> m_body_mesh_offsets;  // per collider: first packed triangle id
    std::vector<std::vector<std::pair<int, int>>> m_vertex_triangle_local;  // (triangle, local index)
    std::vector<std::vector<std::pair<int, int>>> m_vertex_edge_local;      // (edge, local index)
    std::vector<std::vector<std::pair<int, int>>> m_vertex_cell_local;      // (cell, local index)
    std::vector<Eigen::VectorXd> m_chunk_force;
    std::vector<Eigen::VectorXd> m_chunk_product;
    std::unique_ptr<ThreadPool> m_pool;
    ContactStatistics m_contact_stats;
};

}  // namespace flowvid::cloth
