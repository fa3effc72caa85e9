#pragma once
// Fabric material of the cloth model: the SI parameters of a fabric preset
// as plain numbers. How each one enters the energy (and why the result
// does not depend on the mesh resolution) is written in docs/cloth_model.md.

#include "flowvid/formats/fabric_preset.hpp"

#include <string>
#include <vector>

namespace flowvid::cloth {

struct ClothMaterial {
    double areal_density_kg_per_m2 = 0.15;
    // Extra mass along the cloth's free boundary (a hem or selvedge), kg per
    // metre of rest boundary length: each boundary edge adds half its share
    // to each end vertex. 0: mass from the areal density alone, bit for bit.
    double hem_line_density_kg_per_m = 0.0;
    // Membrane: E = k/2 * A_rest * C^2 per triangle (C dimensionless), k in N/m.
    double stretch_warp_N_per_m = 150.0;     // C = |w_u| - 1
    double stretch_weft_N_per_m = 150.0;     // C = |w_v| - 1
    double shear_N_per_m = 90.0;             // C = w_u . w_v
    // Where a grid mesh reads that shear (preset key since 1.2): this share of
    // ks on its cells, E = ks/2 A h(P_wing, P_diagonal) at all four corners,
    // which a fold along either diagonal leaves at zero (cell_shear.cpp), the
    // rest across each triangle. Meshes without rectangular cells read it all
    // on triangles. 0: across each triangle, bit for bit.
    double shear_cell_fraction = 0.0;
    // Tension-only fibres along both diagonals of the weave, w_d = (w_u +- w_v)/sqrt 2:
    // E = k/2 * A_rest * max(|w_d| - 1, 0)^2 each. They resist shear and
    // stretch only where they are pulled, not in compressed folds (Blender's
    // diagonal "shear" springs behave so). 0: none, bit for bit.
    double diagonal_tension_N_per_m = 0.0;
    // Compression (C < 0) is stiffer or softer than tension by these factors:
    // E = ratio * k/2 * A_rest * C^2 there. Woven fabric (and Blender's cloth,
    // whose diagonal springs only pull) shortens far more easily than it
    // stretches. 1 is the symmetric Baraff-Witkin model, bit for bit.
    double stretch_warp_compression_ratio = 1.0;
    double stretch_weft_compression_ratio = 1.0;
    // Bending: E = k/2 * |e|^2 / (A1 + A2) * theta^2 per interior edge (rest
    // |e|, A1, A2): k/2 * integral of curvature^2 dA for a cylindrical bend.
    double bend_N_m = 1e-6;
    // Damping d = -k_d * A_rest * dC/dx * dC/dt (bending: weight as above).
    double stretch_warp_damping_N_s_per_m = 0.0;
    double stretch_weft_damping_N_s_per_m = 0.0;
    double shear_damping_N_s_per_m = 0.0;
    double bend_damping_N_m_s = 0.0;
    // Air drag per triangle: f = -a (kN |vN|^2/(1 + kf |vN|^2) vN/|vN| + kT vT).
    double drag_normal_kg_per_m3 = 0.0;
    double drag_degradation_s2_per_m2 = 0.0;
    double drag_tangential_kg_per_m2_s = 0.0;
    // Linear normal drag kL, added to the normal term: -a kL vN (preset key
    // since 1.1). Slow air drag is linear in speed; alone (kN = kf = 0) it is
    // the "linear drag only" comparison model of the thesis.
    double drag_linear_normal_kg_per_m2_s = 0.0;

    // Optional terms of the gap diagnosis (docs/cloth_model.md, "Optional
    // terms for the gap diagnosis"). Neither is a fabric-preset key:
    // material_from_fabric / fabric_from_material ignore them (always 0 from
    // a preset). 0 reproduces the model above bit for bit.
    // Bias angle: the warp direction is rotated by this angle from the mesh's
    // material u axis, counter-clockwise towards v (a bias-cut fabric);
    // stretch_warp acts along it, stretch_weft across it.
    double bias_angle_rad = 0.0;
    // Bending memory (hysteresis): each hinge's rest angle theta0 creeps
    // towards its current angle, theta0 += (1 - exp(-r dt)) (theta - theta0)
    // after every accepted step of a dynamic run; <= 0: no memory.
    double bend_memory_rate_per_s = 0.0;
};

// The length a hanging fabric folds at: its elastogravity length
// (B / (rho g))^(1/3), metres, from the bending stiffness B and the areal
// density rho (apply experiment_material first where a capture weighs the
// swatch). 0 for a material without bending or mass.
double fold_length_m(const ClothMaterial& material, double gravity_m_per_s2 = 9.81);

// A mesh holds a fabric's folds while its edges are at most this many fold
// lengths long; with longer edges it folds at its own scale, and a finer mesh
// drapes differently. Measured on the fitted silk with only its bending
// varied (docs/cloth_model.md, "Folds finer than the grid"): 12x12, 24x24
// and 48x48 drapes agree at edge / fold length 0.89 and 1.33 (the drape
// test's cotton: 1.14), and disagree by 40-86 mm at 1.9 and above.
inline constexpr double kLongestEdgePerFoldLength = 4.0 / 3.0;

// Whether a mesh whose edges are edge_m long holds the material's folds
// (fold_length_m, kLongestEdgePerFoldLength): a garment, a swatch or any
// mesh, given its edge (the longest along the weave, or a garment's mean).
struct FoldCheck {
    double fold_length_m = 0.0;   // 0: no bending or no weight (then any mesh holds them)
    double edge_m = 0.0;
    double longest_edge_m = 0.0;  // the longest edge that holds the folds
    bool holds_folds = true;
};
FoldCheck check_folds(const ClothMaterial& material, double edge_m, double gravity_m_per_s2 = 9.81);

// The values of a preset's parameters (uncertainties and ranges are dropped).
ClothMaterial material_from_fabric(const formats::FabricParameters& parameters);
// The inverse, with only `value` set: for writing a fitted material as a preset.
formats::FabricParameters fabric_from_material(const ClothMaterial& material);

// Problems that make a simulation meaningless: non-finite numbers, a density
// that is not positive. Field names are the preset's JSON keys (the two
// optional terms, which have none, use their member names). Negative
// stiffness is allowed here on purpose (an optimizer may try it; the
// simulation then reports the blow-up instead of throwing).
std::vector<Problem> check_material(const ClothMaterial& material);

// Reads a fabric preset and checks that the simulator can use its material:
// throws the reader's errors, and ValidationError naming the file for a
// material check_material refuses. Warnings go to `warnings`.
formats::FabricPreset read_preset_for_simulation(const std::string& path, std::vector<Problem>* warnings = nullptr);

}  // namespace flowvid::cloth
