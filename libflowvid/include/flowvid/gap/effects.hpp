#pragma once
// The catalogue of unmodelled effects the gap diagnosis can add to a fitted
// model (names are part of the interface: diagnosis.json, bench labels,
// `flowvid diagnose --effects`). Every effect is an optional term with its
// own parameters and a neutral value that reproduces the base model exactly.
// The `model` domain holds the cloth model's own optional physics (the terms
// the capacity study added: softer compression, a hem, diagonal fibres,
// linear drag): a preset that holds one at its neutral value was fitted
// without it, and the diagnosis asks first whether that is the gap.

#include <Eigen/Core>

#include <map>
#include <string>
#include <vector>

namespace flowvid::gap {

enum class EffectDomain { model, cloth, camera, rigid };
const char* domain_name(EffectDomain domain);

struct EffectParameter {
    std::string key;         // "speed_m_per_s": units in the name, SI
    double neutral = 0.0;    // the value that switches the effect off
    double lower = 0.0;      // search range for refits
    double upper = 1.0;
    double screen_step = 0.1;  // finite-difference step of the screening (same units; 0: not screened)
};

struct Effect {
    std::string name;        // "wind", "pin_lag", ...
    EffectDomain domain = EffectDomain::cloth;
    std::string summary;     // one line for reports
    std::vector<EffectParameter> parameters;
    // Effects the footage of one camera cannot tell apart from this one
    // (e.g. camera_roll and a gravity tilt): reported as one class.
    std::string equivalence_class;  // empty: identifiable on its own
    // For people: a plain name ("soft compression", "wind") and the next step
    // once it is named ("refit the fabric with the capacity terms").
    std::string plain_name;
    std::string next_step;
};

// Every effect, in a fixed order (model, cloth, camera, rigid).
const std::vector<Effect>& effect_catalogue();
// Throws std::invalid_argument listing the known names.
const Effect& find_effect(const std::string& name);
// For people: the plain name beside the key, "pins out of step with the
// footage [pin_lag]"; a name the catalogue does not know stays as it is.
std::string labelled_name(const std::string& name);

// Classes of effects (and base-model changes) that one camera's footage
// cannot separate: their members are reported together, never guessed.
struct EquivalenceClass {
    std::string name;                  // "camera_roll|gravity_tilt"
    std::vector<std::string> members;  // effect names or base-model changes
    std::string why;
};
const std::vector<EquivalenceClass>& equivalence_classes();

// Parameter values of the effects switched on: name -> values in the order
// of Effect::parameters. Effects not listed are neutral.
using EffectValues = std::map<std::string, Eigen::VectorXd>;
// The effect's neutral values.
Eigen::VectorXd neutral_values(const Effect& effect);

}  // namespace flowvid::gap
