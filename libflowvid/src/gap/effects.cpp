// The effect catalogue: names, parameters (SI, units in the keys), neutral
// values and refit ranges. Ranges span what a swatch test or a toss can show:
// winds of a few m/s, pin timing errors of a few frames, lens distortion of
// consumer lenses, a rolling-shutter readout up to a frame time.

#include "flowvid/gap/effects.hpp"

#include "flowvid/gap/model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::gap {

const char* domain_name(EffectDomain domain) {
    switch (domain) {
    case EffectDomain::model: return "model";
    case EffectDomain::cloth: return "cloth";
    case EffectDomain::camera: return "camera";
    case EffectDomain::rigid: return "rigid";
    }
    return "?";
}

namespace {

std::vector<Effect> make_catalogue() {
    using D = EffectDomain;
    const std::string refit_capacity =
        "refit the fabric with the capacity terms (flowvid fit cloth --fit-to scan fits them), then diagnose again";
    return {
        // The model's own optional physics (docs/cloth_model.md, "Terms added
        // for the model's capacity"). Each is offered only when the preset
        // holds it at its neutral value (ClothGapModel::candidate_effects).
        {"compression_softness", D::model,
         "the fabric shortens more easily than it stretches (woven cloth buckles): compression stiffness = "
         "exp(-softness) x the stretch stiffness, both weave directions",
         {{"softness", 0.0, 0.0, 7.0, 1.5}}, "", "soft compression (buckling)", refit_capacity},
        {"hem_mass", D::model, "extra mass along the free edges (a hem or selvedge), the swatch's total mass kept",
         {{"line_density_kg_per_m", 0.0, 0.0, 3e-3, 5e-4}}, "", "a heavier hem", refit_capacity},
        {"diagonal_fibres", D::model,
         "tension-only fibres along both diagonals of the weave: they resist shear where pulled, nothing in folds",
         {{"stiffness_over_stretch", 0.0, 0.0, 2.0, 0.25}}, "", "diagonal (bias) fibres", refit_capacity},
        {"drag_linear", D::model, "slow-air drag linear in the normal speed, beside the quadratic law",
         {{"normal_kg_per_m2_s", 0.0, 0.0, 2.0, 0.1}}, "", "linear air drag", refit_capacity},
        {"drag_nonlinear", D::cloth, "the thesis's nonlinear normal air drag on top of a linear-drag model",
         {{"normal_kg_per_m3", 0.0, 0.0, 8.0, 1.0}, {"degradation_s2_per_m2", 0.0, 0.0, 4.0, 0.5}}, "",
         "nonlinear air drag", "refit the fabric with the nonlinear drag (flowvid fit cloth --drag nonlinear)"},
        {"wind", D::cloth, "air moving past the swatch: a steady velocity (world axes) plus a sinusoidal gust along it; "
                           "it pushes as on a flat plate (rho C_d / 2 = 0.72 kg/m^3), beside the fabric's drag on the motion relative to it",
         {{"x_m_per_s", 0.0, -4.0, 4.0, 1.0},
          {"y_m_per_s", 0.0, -4.0, 4.0, 1.0},
          {"z_m_per_s", 0.0, -4.0, 4.0, 1.0},
          {"gust_amplitude_m_per_s", 0.0, 0.0, 3.0, 0.5},
          {"gust_frequency_hz", 1.0, 0.2, 4.0, 0.0}},
         "", "wind (a draught past the swatch)",
         "film again with the air still (no fan, door or vent nearby), or keep the fitted wind when you simulate"},
        {"anisotropy", D::cloth, "warp and weft of different stiffness, the weave at a bias angle to the swatch edges",
         {{"log_weft_over_warp", 0.0, -2.0, 2.0, 0.3}, {"bias_angle_rad", 0.0, -0.8, 0.8, 0.15}}, "",
         "warp and weft of different stiffness",
         "check the swatch was cut along the weave, and give warp and weft their own stiffness in the preset"},
        {"hysteresis", D::cloth, "bending with memory: the rest fold angle creeps towards the current one",
         {{"bend_memory_rate_per_s", 0.0, 0.0, 20.0, 2.0}}, "", "folds that remember (bending hysteresis)",
         "expect creased fabric to keep its folds; the preset cannot: simulate with bending memory"},
        {"pin_lag", D::cloth, "the recorded pin trajectories run ahead of (or behind) the footage by a time offset",
         {{"lag_s", 0.0, -0.2, 0.2, 0.04}}, "", "pins out of step with the footage",
         "check the sync between the pin record and the camera (timecode, a dropped or repeated frame)"},
        {"pin_slip", D::cloth, "the fabric slides down through the clamps at a steady speed",
         {{"drop_speed_m_per_s", 0.0, 0.0, 0.1, 0.01}}, "", "fabric slipping in the clamps",
         "tighten the clamps and film again"},
        {"camera_roll", D::camera, "the camera is rolled about its optical axis against its calibration",
         {{"roll_rad", 0.0, -0.2, 0.2, 0.05}}, "camera_roll|gravity_tilt", "a rolled camera (or tilted rig)",
         "check the camera calibration (its roll) and that the rig hangs plumb"},
        {"lens_distortion", D::camera, "radial lens distortion the calibration left out (k1, k2 on normalised coordinates)",
         {{"k1", 0.0, -0.6, 0.6, 0.05}, {"k2", 0.0, -0.6, 0.6, 0.1}}, "", "lens distortion",
         "calibrate the camera again with its distortion coefficients"},
        {"rolling_shutter", D::camera, "rows exposed one after another: the bottom row this much later than the top",
         {{"readout_s", 0.0, -0.04, 0.04, 0.008}}, "", "a rolling shutter",
         "film with a global-shutter camera or a faster readout, or give the capture its readout time"},
        {"motion_blur", D::camera, "the shutter open for part of the frame time: moving stripes smear",
         {{"exposure_s", 0.0, 0.0, 0.04, 0.01}}, "", "motion blur", "film with a shorter exposure (more light)"},
        {"air_drag", D::rigid, "air resistance on the tossed body: quadratic on its speed, linear on its spin",
         {{"quadratic_per_m", 0.0, 0.0, 2.0, 0.1}, {"angular_rate_per_s", 0.0, 0.0, 5.0, 0.25}}, "", "air drag",
         "simulate the body with air drag (the fitted values are in diagnosis.json)"},
        {"inertia_error", D::rigid, "principal moments of inertia off from the mesh's uniform density",
         {{"log_scale_x", 0.0, -0.5, 0.5, 0.05}, {"log_scale_y", 0.0, -0.5, 0.5, 0.05}}, "",
         "mass not spread evenly through the body", "give the body its measured inertia instead of a uniform density"},
    };
}

}  // namespace

const std::vector<Effect>& effect_catalogue() {
    static const std::vector<Effect> catalogue = make_catalogue();
    return catalogue;
}

const Effect& find_effect(const std::string& name) {
    std::string known;
    for (const Effect& effect : effect_catalogue()) {
        if (effect.name == name) return effect;
        known += (known.empty() ? "" : ", ") + effect.name;
    }
    throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

std::string labelled_name(const std::string& name) {
    for (const Effect& effect : effect_catalogue())
        if (effect.name == name && !effect.plain_name.empty()) return effect.plain_name + " [" + name + "]";
    return name;
}

const std::vector<EquivalenceClass>& equivalence_classes() {
    static const std::vector<EquivalenceClass> classes = {
        {"camera_roll|gravity_tilt",
         {"camera_roll", "gravity_tilt"},
         "one camera sees only the angle between gravity and the image axes: a rolled camera and a tilted gravity "
         "give the same footage"},
        {"mass_scale|force_scale",
         {"mass_scale", "force_scale"},
         "motion depends on force over mass only: a global mass scale and the same scale on every force (stiffness, "
         "damping, drag) give the same footage"},
    };
    return classes;
}

Eigen::VectorXd neutral_values(const Effect& effect) {
    Eigen::VectorXd values(static_cast<Eigen::Index>(effect.parameters.size()));
    for (std::size_t i = 0; i < effect.parameters.size(); ++i)
        values(static_cast<Eigen::Index>(i)) = effect.parameters[i].neutral;
    return values;
}

bool is_held_out(int frame_number, int block) { return ((frame_number - 1) / std::max(1, block)) % 2 == 1; }

double training_score(const Residuals& residuals) {
    double sum = 0.0;
    for (const FrameResidual& f : residuals.frames)
        if (!f.held_out) sum += f.error / f.floor;
    return sum;
}

double held_out_score(const Residuals& residuals) {
    double sum = 0.0;
    for (const FrameResidual& f : residuals.frames)
        if (f.held_out) sum += f.error / f.floor;
    return sum;
}

double held_out_gap_closed(const Residuals& base, const Residuals& with) {
    int held_out = 0;
    for (const FrameResidual& f : base.frames) held_out += f.held_out ? 1 : 0;
    const double gap = held_out_score(base) - held_out;
    return gap > 0.0 ? (held_out_score(base) - held_out_score(with)) / gap : std::nan("");
}

}  // namespace flowvid::gap
