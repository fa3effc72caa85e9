#pragma once
// The rigid side of the gap diagnosis (docs/rigid.md, "Gap diagnosis: rigid
// effects"): a GapModel over one or more rigid.toss captures of the same kind
// of body, and the writer of synthetic bench cases for `flowvid bench gap`.
//
// Candidate effects: "air_drag" (quadratic_per_m: dv/dt -= c |v| v;
// angular_rate_per_s: dw/dt -= k w, body axes) and "inertia_error"
// (log_scale_x, log_scale_y: the moments about body x and y scaled by
// exp(.) relative to body z). "camera_roll" is not a candidate: the rigid
// fit's free gravity direction absorbs it (the camera_roll|gravity_tilt
// class of gap/effects.hpp).
//
// What the numbers mean:
//  * error (per frame): E_k of rigid/silhouette_residuals.hpp, the mean
//    squared distance (px^2) between the predicted outline and the observed
//    mask's outline, both directions averaged.
//  * base parameters: the toss's 14 flight parameters per trial (initial
//    COM, orientation, velocities, gravity tilt and roll). They are initial
//    conditions, so any effect shifts them: evaluate() re-fits them on the
//    training frames for the effects given (Levenberg-Marquardt from the base
//    fit, RigidGapSettings::refit_initial_state; from scratch too when that
//    stays far above the floor) and judges an effect by what it adds beyond
//    initial conditions. At neutral effects this reproduces the base fit (it
//    is already at the optimum when made on the training frames). This
//    departs from GapModel's "base parameters as fitted", which suits
//    material parameters, not initial conditions.
//  * floor (per frame): what a perfect model leaves. Masks are rendered from
//    the base fit's own motion with the capture's pixel grid (coverage of
//    s x s samples thresholded at 0.5, as the captures' masks are made), the
//    14 parameters are re-fitted to those masks on the training frames, and
//    the floor is that fit's E_k on every frame: mask quantisation plus the
//    parameter error quantisation causes, extrapolated to held-out frames as
//    the real fit's is. Averaged over `floor_repeats` copies of the toss
//    shifted by random sub-pixel offsets (a different quantisation each).
//    Segmentation noise beyond quantisation (masks cut from noisy frames) is
//    not modelled: on captures without masks the floor is a lower bound.
//  * driver: the body's COM speed (m/s) in the simulated motion.
//  * observations: observed outline length / 8 px (see docs/rigid.md).

#include "flowvid/formats/capture.hpp"
#include "flowvid/gap/model.hpp"
#include "flowvid/rigid/fit.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::gap {

// One rigid capture and what is known about it.
struct RigidTrial {
    formats::Capture capture;                // rigid.toss, with masks (or a background to segment against)
    std::optional<rigid::RigidBody> body;    // none: RigidBody::from_capture(*capture.rigid)
    // An existing fit of this capture (e.g. from fit.json: parameters =
    // record.initial, reference_frame = record.initial_frame, fps). None:
    // fit_rigid on the training frames. A fit that saw held-out frames makes
    // the held-out residuals optimistic.
    std::optional<rigid::FitResult> fit;
    std::string name;                        // for reports; empty: the capture folder's name
    int first_frame = 0;                     // 0: the capture's first
    int last_frame = 0;                      // 0: the capture's last
};

struct RigidGapSettings {
    int threads = 0;                         // 0 = std::thread::hardware_concurrency()
    double max_step_s = 1.0 / 240.0;         // RK4 step of every simulation (rigid::SimulationSettings)
    rigid::FitSettings fit;                  // for trials without a fit (threads, max_step_s and log set from here)
    bool refit_initial_state = true;         // evaluate(): re-fit the 14 flight parameters for the effects (see above)
    int lm_iterations = 25;                  // Levenberg-Marquardt iterations per re-fit of the flight parameters
    // When re-fitting the flight parameters from the base fit leaves more
    // than this many times the training frames' floor, evaluate() also runs
    // fit_rigid from scratch with the effects (multi-start, as for a trial
    // without a fit) and keeps the better: a strong effect can put the best
    // initial state in another valley (a strongly damped spin moved the
    // neutral fit's orientation 2 rad from the truth in our tests).
    double scratch_refit_above_floor = 2.0;
    int refit_scratch_fits = 3;              // at most this many such fits per refit()
    int floor_repeats = 3;                   // synthetic re-fits averaged for the floor
    int floor_supersampling = 4;             // coverage samples per pixel side of the synthetic masks
    std::uint64_t floor_seed = 1;            // sub-pixel offsets of the floor's copies
    int image_rows = 12;                     // localise(): image grid
    int image_cols = 16;
    int body_rows = 9;                       // localise(): body directions, elevation x azimuth about body z
    int body_cols = 18;
    std::function<void(const std::string&)> log;  // the library never prints
};

// The catalogue's rigid effects as simulation terms. Effects not listed are
// neutral. Throws std::invalid_argument for an effect that is not a rigid one
// (naming the rigid ones), a wrong number of values or non-finite values.
rigid::FlightEffects flight_effects(const EffectValues& effects);

class RigidGapModel final : public GapModel {
public:
    // Loads every trial's frames, fits trials without a fit and estimates the
    // floors. Throws ValidationError naming the capture.json and field when a
    // capture is not a usable rigid toss (no rigid block or camera, no masks
    // and no background, a frame range outside the capture, fewer than 3
    // training frames), IoError when a mask cannot be read,
    // std::invalid_argument when no trial is given.
    explicit RigidGapModel(std::vector<RigidTrial> trials, RigidGapSettings settings = {});
    ~RigidGapModel() override;
    RigidGapModel(RigidGapModel&&) noexcept;
    RigidGapModel& operator=(RigidGapModel&&) noexcept;

    std::string kind() const override { return "rigid"; }
    std::vector<std::string> trial_names() const override;
    // {"air_drag", "inertia_error"}.
    std::vector<std::string> candidate_effects() const override;
    // Per trial (prefixed "<trial>/" when there are several): com_{x,y,z}_m,
    // rotation_{x,y,z}_rad (camera-frame rotation vector relative to the base
    // fit's orientation), com_velocity_{x,y,z}_m_per_s,
    // angular_velocity_{x,y,z}_rad_per_s, gravity_tilt_rad, gravity_roll_rad:
    // all at the trial's reference frame (the fit's first frame).
    std::vector<std::string> base_parameter_keys() const override;
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>& base = {}) const override;
    // Compass search over the effects' parameters in `start` (within their
    // catalogue ranges, steps from their screen steps) minimising
    // training_score, each point scored by re-fitting every trial's flight
    // parameters on the training frames (LM, warm-started from the best point
    // so far; the first from `base_start`'s values, else the base fit).
    // `max_evaluations` bounds the effect points tried (each one LM per
    // trial; a fit from scratch counts as one); <= 0: 80. Throws
    // std::invalid_argument for a base_start key not of base_parameter_keys.
    RefitResult refit(const EffectValues& start, int max_evaluations,
                      const std::vector<BaseParameterChange>& base_start = {}) const override;
    // Two maps, summed over frames and trials:
    //  "image" (image_rows x image_cols cells of the image): pixels where the
    //    predicted and observed silhouettes differ, NaN where neither was.
    //  "body directions" (body_rows elevations x body_cols azimuths of the
    //    direction from the COM, body frame, about body z): squared distance
    //    (px^2) of each visible predicted outline piece to the observed
    //    outline times its length (px), NaN where no outline was seen.
    std::vector<RegionMap> localise(const EffectValues& effects) const override;

    // Not part of GapModel:
    const rigid::RigidBody& body(int trial) const;
    const rigid::FitResult& base_fit(int trial) const;   // as given or as fitted on the training frames
    std::vector<double> floors(int trial) const;          // px^2, one per frame in frame order

private:
    struct Trial;
    struct Profile;
    // The flight parameters of every trial re-fitted on its training frames
    // for each of `effects`, LM from `starts` (one per trial).
    // `from_scratch_when_poor`: see RigidGapSettings::scratch_refit_above_floor.
    std::vector<Profile> profiles(const std::vector<rigid::FlightEffects>& effects,
                                  const std::vector<rigid::FlightParameters>& starts, bool from_scratch_when_poor) const;
    Residuals residuals_of(const rigid::FlightEffects& effects, const std::vector<rigid::FlightParameters>& parameters) const;
    std::vector<rigid::FlightParameters> base_parameters() const;
    // The base fit with `base_start`'s `after` values put in (keys of base_parameter_keys).
    std::vector<rigid::FlightParameters> starting_parameters(const std::vector<BaseParameterChange>& base_start) const;

    std::vector<std::unique_ptr<Trial>> m_trials;
    RigidGapSettings m_settings;
};

// ---- Bench cases ------------------------------------------------------------------

struct RigidCaseSettings {
    int frame_count = 0;                      // 0: the template's
    double fps = 0.0;                         // 0: the template's
    double max_step_s = 1.0 / 960.0;          // finer than the fits' 1/240 s: the case's own integration error is negligible
    double spin_min_rad_per_s = 6.0;          // |angular velocity|, uniform in [min, max], random axis
    double spin_max_rad_per_s = 14.0;
    double size_min_px = 45.0;                // the body's projected diameter at the start, uniform in [min, max]
    double size_max_px = 70.0;
    double gravity_tilt_max_rad = 0.1;        // gravity direction in camera space, uniform in +-max
    double gravity_roll_max_rad = 0.05;
    double margin_px = 4.0;                   // the body stays this far inside the image in every frame
    int supersampling = 5;                    // coverage samples per pixel side (masks: coverage >= 0.5)
    double noise_sigma = 1.0 / 255.0;         // frames: Gaussian noise per pixel, correlated over 3 x 3 (as the captures')
    int max_attempts = 2000;                  // draws of the toss until one stays in view
    int threads = 0;                          // frames rendered in parallel; 0 = hardware (the files do not depend on it)
};

// What was simulated (for the generator's labels; the case folder holds no truth).
struct RigidCase {
    std::string folder;
    rigid::FlightParameters initial;          // at frame 1 (time 0), camera space, |g| = 9.81
    rigid::FlightEffects effects;
    EffectValues effect_values;               // as given
    std::uint64_t seed = 0;
    int frame_count = 0;
    double fps = 0.0;
    int attempts = 0;                         // draws until the toss stayed in view
};

// Simulates a toss with `effects` (RK4 at settings.max_step_s) of the
// template's body, seen by the template's camera, and writes a rigid.toss
// capture folder: capture.json (formats::capture_to_json; world = camera
// frame, gravity unknown), body.glb (copied), masks/%06d.png (binary),
// frames/%06d.png and background.png (a flat backdrop of the template
// background's mean colour, a Lambert-shaded body, sensor noise). Deterministic for a seed.
// Files are written atomically and capture.json last. Throws ValidationError
// naming the template's capture.json and field when it is not a rigid toss
// with a camera, std::invalid_argument for non-rigid effects, IoError when a
// file cannot be written, std::runtime_error when no toss stays in view.
RigidCase write_rigid_case(const std::string& folder, const formats::Capture& template_capture, const EffectValues& effects,
                           std::uint64_t seed, const RigidCaseSettings& settings = {});

// A binary silhouette of the body in `state` (coverage of s x s samples
// per pixel >= 0.5): how the captures' masks are made.
metrics::Silhouette render_rigid_mask(const rigid::RigidBody& body, const formats::CameraModel& camera,
                                      const rigid::RigidState& state, int supersampling = 5);

}  // namespace flowvid::gap
