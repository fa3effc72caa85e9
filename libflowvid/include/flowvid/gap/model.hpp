#pragma once
// What the gap diagnosis (gap/diagnose.hpp) needs of a fitted model, cloth or
// rigid: per-frame residuals against footage with any catalogue effects added,
// each frame's floor (what even a perfect model leaves: chaos, image noise),
// refits of effects jointly with the base parameters, and maps of where the
// residual lies. The diagnosis itself (gap detection, screening, evidence,
// report) is generic over this interface.

#include "flowvid/gap/effects.hpp"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace flowvid::gap {

// Training and held-out frames alternate in blocks of `block` frames (1-5
// train, 6-10 held out, ...): every held-out frame has trained neighbours on
// both sides, so a refit is judged on frames it did not see but that follow
// the same motion. Frame numbers are 1-based.
constexpr int kHeldOutBlockFrames = 5;
bool is_held_out(int frame_number, int block = kHeldOutBlockFrames);

struct FrameResidual {
    int trial = 0;           // index into GapModel::trial_names()
    int frame = 1;           // 1-based frame number of the footage
    double time_s = 0.0;     // from the trial's first frame
    double error = 0.0;      // the frame's metric (cloth: E_k; rigid: mean squared edge distance, px^2)
    double floor = 0.0;      // the same metric's floor at this frame (> 0)
    bool held_out = false;   // is_held_out(frame)
    double driver = 0.0;     // what drives the motion here, for plots (cloth: pin speed m/s; rigid: body speed m/s)
    // Independent observations the frame's error sums (pixels compared over
    // the area one orientation estimate spans): weights the frame in
    // likelihood-based evidence (BIC). 1: the frame as one observation.
    double observations = 1.0;
};

struct Residuals {
    bool ok = true;          // false: the simulation failed (reason says why); frames then hold large errors
    std::string reason;
    std::vector<FrameResidual> frames;
};

// Sums of error/floor (each frame in units of what a perfect model leaves
// there) over training or held-out frames: what refits minimise and what
// the diagnosis judges them by.
double training_score(const Residuals& residuals);
double held_out_score(const Residuals& residuals);
// The share of the base's held-out gap (its score beyond the floor level,
// error = floor in every held-out frame) that `with` closes; NaN when the
// base is within the floor level.
double held_out_gap_closed(const Residuals& base, const Residuals& with);

struct BaseParameterChange {
    std::string key;         // model parameter ("bend_N_m", "gravity_tilt_rad", ...)
    double before = 0.0;
    double after = 0.0;
};

// The base model on a finer discretisation than the diagnoser's (a finer
// mesh): the share of the gap it closes is what the model's own
// discretisation accounts for, which an effect has to beat to be named.
struct DiscretisationControl {
    std::string description;  // what was refined, for people ("a 28x28 mesh")
    Residuals residuals;
};

struct RefitResult {
    EffectValues effects;                      // fitted values of the effects refitted
    std::vector<BaseParameterChange> base;     // base parameters refitted with them
    Residuals residuals;                       // at the refit's optimum, every frame
    long long evaluations = 0;
};

// A map of where the residual lies: row-major, NaN where nothing was seen.
struct RegionMap {
    std::string name;        // "swatch uv", "image"
    std::string units;
    int rows = 0;
    int cols = 0;
    std::vector<double> values;
};

class GapModel {
public:
    virtual ~GapModel() = default;
    virtual std::string kind() const = 0;                      // "cloth", "rigid"
    virtual std::vector<std::string> trial_names() const = 0;
    // Catalogue effects this model can add (an effect the base already
    // models, e.g. nonlinear drag in a preset that has it, is left out).
    virtual std::vector<std::string> candidate_effects() const = 0;
    // Base-model parameters a refit moves, in a stable order (for reports).
    virtual std::vector<std::string> base_parameter_keys() const = 0;
    // Residuals of the base model with `effects` added (others neutral), base
    // parameters as fitted -- except initial conditions, which any effect
    // shifts: a model whose base is initial conditions (rigid tosses) re-fits
    // them on the training frames for the effects. Deterministic.
    // With `base`, the base parameters take those changes' `after` values
    // (e.g. a refit's): screening then steps away from that model.
    virtual Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>& base = {}) const = 0;
    // Refits the effects in `start` (their parameters, from these values)
    // jointly with the base parameters (from `base_start`'s `after` values
    // where given, else as fitted), on training frames only.
    virtual RefitResult refit(const EffectValues& start, int max_evaluations,
                              const std::vector<BaseParameterChange>& base_start = {}) const = 0;
    // Where the residual of `effects` lies (over the object's own surface
    // coordinates and over the image), summed over every frame.
    virtual std::vector<RegionMap> localise(const EffectValues& effects) const = 0;
    // How many evaluate() or refit() calls the diagnosis may run at once
    // (from as many threads); a model shares its threads among them.
    virtual int concurrency() const { return 1; }
    // The base model with `base`'s changes and `effects` (the model's own
    // terms the diagnosis named, or none), on a finer discretisation; nullopt
    // when the model has none to offer.
    virtual std::optional<DiscretisationControl> discretisation_control(const std::vector<BaseParameterChange>& base,
                                                                        const EffectValues& effects) const {
        (void)base;
        (void)effects;
        return std::nullopt;
    }
};

}  // namespace flowvid::gap
