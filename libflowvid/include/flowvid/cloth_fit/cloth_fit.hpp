#pragma once
// Inverse simulation for cloth (thesis 2.4): the objective that a fit
// minimises. For a set of trials (static drapes and waving tests, fitted
// jointly), a fabric material is simulated with each trial's pins, rendered
// through its camera with its projector's stripes, turned into angle maps and
// compared with the footage's (video/angle_map_metric.hpp):
//
//   E(material) = sum over trials, sum over compared frames k of w_k E_k
//
// Trials are loaded from capture folders (frames, masks or background plate,
// calibration, pins; never truth/) or built directly (synthetic footage in
// tests). Evaluations are deterministic: the static equilibrium of every
// trial is warm-started from one fixed solution computed up front, never
// from whatever was evaluated before.

#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/objective.hpp"
#include "flowvid/video/angle_map.hpp"
#include "flowvid/video/angle_map_metric.hpp"
#include "flowvid/video/cloth_footage.hpp"
#include "flowvid/video/stripe_render.hpp"

#include <Eigen/Core>

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flowvid::cloth_fit {

// One fitted quantity: a fabric preset key ("bend_stiffness_N_m", ...; see
// formats::fabric_parameter_table) or a tie of two of them:
// "stretch_stiffness_N_per_m" (warp and weft) and "stretch_damping_N_s_per_m".
struct FittedParameter {
    std::string key;
    double lower = 0.0;
    double upper = 1.0;
    bool log_scale = true;
};

// Sets or reads `key` of a material. Throws std::invalid_argument naming an unknown key.
void set_material_parameter(cloth::ClothMaterial& material, const std::string& key, double value);
double material_parameter(const cloth::ClothMaterial& material, const std::string& key);
// Whether a parameter may be 0 (a term switched off) in a fabric preset; the
// others must be positive.
bool parameter_allows_zero(const std::string& key);

// The thesis's choices: static test, 6 (stretch, shear, bend and their
// damping; drag held at its base value); waving test, those and the 3 drag
// terms (9). Ranges span the fabrics of the thesis and Blender's presets.
std::vector<FittedParameter> static_test_parameters();
std::vector<FittedParameter> waving_test_parameters();
// `parameters` with bend_stiffness_N_m's lower bound raised to
// `min_bending_N_m` (and its upper bound to at least 10x that); unchanged
// when it is 0 or bending is not fitted.
std::vector<FittedParameter> with_bending_floor(std::vector<FittedParameter> parameters, double min_bending_N_m);

// What a fit compares simulations with: the footage (angle maps and
// silhouettes, thesis 2.4.3), the swatch's shape the footage's projector
// stripes measure (a structured-light scan of each frame,
// video/stripe_scan.hpp; from the footage alone), or measured 3D positions
// of swatch points (capture.json "tracks": motion-capture markers, a
// scanner; also the model capacity study, which hands a capture's ground
// truth over as tracks).
enum class FitTarget { footage, scan, tracks };
const char* fit_target_name(FitTarget target);  // "footage", "scan", "tracks"
// The target of one of those names; nullopt for any other text.
std::optional<FitTarget> fit_target_from_name(std::string_view name);
// What `fit cloth`, `eval cloth`, `recognize` and the Python module compare
// with unless told: the scan, from the footage alone, whose fits reach the
// capacity model where the angle maps' did not (docs/cloth_fitting.md).
// Library structs keep FitTarget::footage as their own default.
constexpr FitTarget kDefaultFitTarget = FitTarget::scan;

// A tracks fit's waving frames and their half-life by default: point
// distances grow with chaos, so fewer and faster-fading frames than a
// footage fit (the capacity study, docs/cloth_model.md).
constexpr int kTracksWavingFrames = 20;
constexpr double kTracksHalfLifeFrames = 5.0;

// The measured positions a tracks trial is compared with, one matrix per
// compared frame in the order of ClothTrial::frames. E_k is the mean squared
// distance (mm^2) over the points seen in frame k between each point and the
// simulated surface at its uv; sum_k w_k E_k / sum_k w_k is a weighted mean
// square, so its root is an RMS distance in mm.
struct TrackReference {
    int rows = 0;  // uv grid: point r*cols + c at u = c/(cols-1), v = r/(rows-1)
    int cols = 0;
    std::vector<Eigen::MatrixX3d> positions_m;  // rows*cols x 3 per compared frame; a NaN row was not seen
    // E_k of a frame the simulation did not reach (it blew up): every point
    // off by the swatch's diagonal, so such a run ranks last.
    double missing_frame_error_mm2 = 0.0;
};

// Background pixels that count against a simulation covering them: those
// whose distance from the swatch's outline in the footage's silhouette lies
// in [min_px, max_px] (min_px leaves the outline's own uncertain pixels
// out; a simulation beyond max_px has lost scan samples too). max_px 0
// turns the term off.
struct ScanOutsideBand {
    double min_px = 1.5;
    double max_px = 16.0;
};

// The footage's own shape measurement a scan trial is compared with: per
// compared frame, sampled pixels where the stripe scan measured the absolute
// projector coordinate v_p of the swatch. Per sample the simulated surface
// seen through the same pixel has its own v_p; their difference times the
// ray's metres per unit of v_p is the depth error d along the camera ray
// (m), softly capped, r = cap tanh(d / cap), so that a region the scan
// placed a stripe period off (about 6 cm in the captures) costs a bounded
// amount. A sample the simulation does not cover costs the cap, and so does
// each `outside` pixel it covers: the footage shows background there, so
// the simulated swatch reaches too far sideways, which depth alone cannot
// see. E_k is the sum of r^2 over both, divided by the number of scan
// samples, in mm^2: for a simulation within the outline, sum_k w_k E_k /
// sum_k w_k is a mean square whose root is an RMS depth error in mm,
// comparable to a tracks fit's RMS distance.
struct ScanReference {
    struct Pixel {
        int x = 0;
        int y = 0;
    };
    struct Sample {
        int x = 0;  // pixel
        int y = 0;
        double projector_coordinate = 0.0;  // measured v_p (projector pixels)
        double metres_per_unit = 0.0;       // depth along the ray per unit of v_p there
    };
    std::vector<std::vector<Sample>> samples;  // per compared frame
    // Per compared frame: sampled background pixels near the swatch's
    // outline (ScanOutsideBand); empty when the term is off.
    std::vector<std::vector<Pixel>> outside;
    int stride_px = 2;             // of both grids
    ScanOutsideBand outside_band;  // where `outside` was taken from
    // Frame 1's scanned world points per pixel (row-major, NaN where not
    // measured), for starting the simulation in the fold state the footage
    // shows; empty when frame 1 is not compared.
    int width = 0;
    int height = 0;
    std::vector<Eigen::Vector3f> first_frame_points_m;
    double cap_m = 0.03;
    // The stripes' period in units of v_p. A scan region unwrapped a whole
    // number of periods off (a slip: the fold hid the step) measures v_p off
    // by that many periods: the difference is taken modulo the period, so a
    // slip costs nothing extra and a simulation more than half a period's
    // depth away (about 3 cm in the captures) is capped anyway. 0: absolute.
    double period_units = 0.0;
    // E_k of a frame the simulation did not reach: every sample at twice the
    // cap, so such a run ranks last.
    double missing_frame_error_mm2() const { return 4e6 * cap_m * cap_m; }
};

// One trial: what is simulated and what it is compared with.
struct ClothTrial {
    std::string name;                      // for reports (the capture folder)
    bool is_static = false;
    cloth::SwatchExperiment experiment;    // frame_count: the frames to simulate (>= the last compared)
    formats::CameraModel camera;
    formats::Projector projector;
    video::AngleMapSettings angle_map;
    // Compared frames; `number` is 1-based from the experiment's first frame
    // (the equilibrium is 1), `weight` is w_k. A tracks trial keeps only
    // their numbers and weights here (no angle maps).
    std::vector<video::ReferenceFrame> frames;
    // Set for a tracks trial: compared with these instead of the footage.
    std::optional<TrackReference> tracks;
    // Set for a scan trial: compared with the footage's scanned shape.
    std::optional<ScanReference> scan;
    // Compared with 3D measurements (tracks or a scan): E_k in mm^2, a
    // residual vector for least squares.
    bool measures_shape() const { return tracks.has_value() || scan.has_value(); }
};

// The stride-grid pixels of `silhouette`'s background within `band` of it.
std::vector<ScanReference::Pixel> scan_outside_pixels(const metrics::Silhouette& silhouette, int stride_px,
                                                      const ScanOutsideBand& band);

struct TrialLoadSettings {
    FitTarget target = FitTarget::footage;
    int static_frames = 1;        // a static drape does not move: its first frame(s)
    int waving_frames = 50;       // the thesis fitted the first 50 frames
    int full_weight_frames = 10;  // waving: frames after these count less ...
    double half_life_frames = 0;  // ... halving every this many frames (0: all count fully)
    double static_weight = 1.0;   // weight of each compared static-drape frame (a waving frame's full weight is 1)
    video::SegmentationSettings segmentation;
    std::optional<double> stripe_period_px;  // default: expected_stripe_period_px(capture)
    int scan_stride_px = 2;       // scan fits: every this many pixels in x and y is a sample
    double scan_cap_m = 0.03;     // scan fits: ScanReference::cap_m
    ScanOutsideBand scan_outside;  // scan fits: where ScanReference::outside samples lie
    video::SilhouetteTerm silhouette_term = video::SilhouetteTerm::pixel_xor;  // prepares edge distances when needed
};

// The static-drape weight at which a drape counts as much as a waving trial:
// the sum of the weights of `load`'s waving frames (about 15 for 20 frames
// halving every 5 after 10).
double balanced_static_weight(const TrialLoadSettings& load);

// fit cloth's static weight unless one is given: balanced for a tracks fit
// of drapes and waving tests together -- at one frame against a waving
// trial's fifteen, the drape was traded for the waving trial's chaotic later
// frames (silk static-1 fitted 5.8 mm from its tracks, balanced 4.5-4.9;
// docs/cloth_model.md) -- and 1 otherwise: the scan and angle-map defaults
// are measured at 1 (docs/cloth_fitting.md), and a drape alone has nothing
// to balance.
double default_static_weight(const TrialLoadSettings& load, const std::vector<formats::Capture>& captures);

// fit cloth's share of the shear read on the swatch grid's cells unless one
// is given (ClothMaterial::shear_cell_fraction): 1 for a tracks fit, where
// the capacity study measured it (silk's held-out drape 0.8 mm against 4.5
// read across each triangle, cotton's whole held-out trial 20.5 against
// 22.3-23.5; docs/cloth_model.md, "The bound remeasured"), 0 otherwise: the
// scan and angle-map fits are measured with the shear across each triangle.
double default_shear_cell_fraction(FitTarget target);

// Reads a cloth capture's footage (or, for FitTarget::tracks, its tracks)
// into a trial. Throws what ClothFootage and the capture readers throw
// (ValidationError naming capture.json fields; "/tracks" for a tracks fit of
// a capture without tracks).
ClothTrial load_trial(const formats::Capture& capture, const TrialLoadSettings& settings = {});

struct ClothFitSettings {
    cloth::SwatchOptions swatch;              // mesh resolution, integrator, equilibrium options
    video::AngleMapMetricSettings metric;
    cloth::ClothMaterial base;                // values of the parameters that are not fitted
    bool warm_start = true;                   // equilibria start from the base material's (computed once)
    // ... or, for a trial whose first frame is measured in 3D (tracks) and
    // matches best, from that measured shape itself. (Not a scan's: settling
    // from its noisy depth took twice the time an evaluation.)
    bool warm_start_from_measurement = true;
    // Hung cloth has several equilibria (the slack between the pins bows to
    // the front or the back, or folds): the base material's equilibrium is
    // solved from each of these bows and the one whose first frame matches
    // the footage best is the warm start. Empty: swatch.initial_bow only.
    std::vector<double> candidate_bows = {1.0, -1.0, 0.0};
    // A scan trial's start: rounds of registering the fabric to frame 1's
    // scanned surface before it settles (0: moved onto the scan along the
    // camera rays and settled, as before). Each round solves the fabric's
    // equilibrium with every vertex seen at a scanned pixel pulled towards
    // the scanned point's depth there (free to slide across the ray), then
    // looks the pixels up again.
    int scan_registration_rounds = 3;
    // How hard the pull is: a vertex this far off the scanned depth feels
    // the weight of a mean vertex.
    double scan_registration_tolerance_m = 0.003;
    // A second mesh for every static drape (rows x cols; 0: none): the drape
    // is also simulated on it and compared with the same measurements, and
    // that error is added to the total. A preset must drape alike on any
    // mesh; a fit that sees one mesh only can choose a nearly stiffless
    // fabric whose drape holds on that mesh alone (silk fitted on 24x24
    // settled 40 mm away on 12x12; docs/cloth_model.md). Costs a drape
    // simulation on that mesh per evaluation (silk's capacity fit: 7 minutes
    // instead of 5).
    int second_drape_rows = 0;
    int second_drape_cols = 0;
    // Newton iterations each candidate's equilibrium may take in a fit (the
    // swatch options' own limit where lower; the warm starts and the
    // predictions keep that). Candidates settle from a nearby warm start: one
    // that needs more is far off, and letting it run to the simulator's 2000
    // cost a cotton scan fit 25 s per such candidate (179 evaluations in its
    // 600 s and no variability restarts, instead of about 590 and four).
    int evaluation_equilibrium_iterations = 400;
    bool has_second_drape_mesh() const { return second_drape_rows >= 2 && second_drape_cols >= 2; }
};

struct TrialEvaluation {
    std::string name;
    double error = 0.0;                       // sum_k w_k E_k
    std::vector<video::FrameError> frames;  // per compared frame (a missing frame: the largest error)
    cloth::SimulationReport report;
    int simulated_frames = 0;                 // good frames (before a blow-up)
    // A static drape's sum_k w_k E_k on ClothFitSettings' second drape mesh
    // (0 when it has none); counted in ClothEvaluation::total, not in error.
    double second_mesh_error = 0.0;
};

struct ClothEvaluation {
    double total = 0.0;
    std::vector<TrialEvaluation> trials;
};

class ClothFitProblem {
public:
    // Throws std::invalid_argument for unknown parameter keys, bad bounds or
    // no trials.
    ClothFitProblem(std::vector<ClothTrial> trials, std::vector<FittedParameter> parameters, ClothFitSettings settings);

    const optim::ParameterSpace& space() const { return m_space; }
    const std::vector<ClothTrial>& trials() const { return m_trials; }
    const ClothFitSettings& settings() const { return m_settings; }

    cloth::ClothMaterial material(const Eigen::VectorXd& values) const;
    Eigen::VectorXd values_of(const cloth::ClothMaterial& material) const;

    // Simulates, renders and compares every trial; trials run on up to
    // `threads` threads (results do not depend on it).
    ClothEvaluation evaluate(const cloth::ClothMaterial& material, int threads = 1) const;
    // The simulated vertex positions of one trial (3*#V per frame, frame 1 first) and its mesh.
    cloth::SwatchRun simulate(std::size_t trial, const cloth::ClothMaterial& material, int threads = 1) const;
    // Whether a trial is also simulated on the second drape mesh, and that run.
    bool has_second_mesh(std::size_t trial) const;
    cloth::SwatchRun simulate_second_mesh(std::size_t trial, const cloth::ClothMaterial& material, int threads = 1) const;

    // E(values) for the optimizers; uses the spare threads it is given for
    // trials. Keeps a pointer to this problem, which must outlive it.
    optim::Objective objective() const;

    // Tracks and scan trials only (std::logic_error otherwise): the residual
    // vector whose squared norm is evaluate(material).total: for tracks one
    // entry per seen point, frame and axis, sqrt(w_k / n_k) * (simulated -
    // measured) in mm, n_k the points seen in frame k; for a scan one entry
    // per sample, sqrt(w_k / n_k) * r in mm. A frame the simulation did not
    // reach spreads its missing-frame error over its entries, so the length
    // never changes. A trial with a second drape mesh appends that run's
    // entries after its own. For the least-squares polish.
    Eigen::VectorXd residuals(const cloth::ClothMaterial& material, int threads = 1) const;
    bool all_measure_shape() const;

    // The shape each trial's simulations start from (its equilibrium solve's
    // first guess: the chosen fold state; empty when none), and a way to
    // replace it, e.g. by a first frame measured some other way (the
    // capacity bench's study of how much the start decides).
    const Eigen::VectorXd& warm_start(std::size_t trial) const { return m_warm_starts.at(trial); }
    void set_warm_start(std::size_t trial, Eigen::VectorXd positions_m) { m_warm_starts.at(trial) = std::move(positions_m); }
    // Seconds the main mesh's warm starts took to find (one thread, one
    // trial after another): what picking the fold states costs again later,
    // e.g. for a floor's nominal runs.
    double warm_start_seconds() const { return m_warm_start_seconds; }

private:
    // A candidate's run of a trial on the fit's mesh or the second drape
    // mesh: the evaluation's iteration limit, the matching warm start.
    cloth::SwatchRun simulate_candidate(std::size_t trial, const cloth::ClothMaterial& material, int threads,
                                        bool second_mesh) const;
    // Calls run_trial(trial, simulation threads) for every trial, in parallel
    // when they cost alike; each trial writes only its own slot.
    void for_each_trial(int threads, const std::function<void(std::size_t, int)>& run_trial) const;

    std::vector<ClothTrial> m_trials;
    std::vector<FittedParameter> m_parameters;
    ClothFitSettings m_settings;
    optim::ParameterSpace m_space;
    std::vector<Eigen::VectorXd> m_warm_starts;  // per trial, empty when none
    std::vector<Eigen::VectorXd> m_second_mesh_warm_starts;  // the same on the second drape mesh
    double m_warm_start_seconds = 0.0;
};

// A fabric preset of a fitted material: every value from `material`; each
// fitted parameter (both members of a tie) gets its search range and, when a
// variability analysis is given, the spread of its runs as the 1-sigma
// uncertainty (thesis table 2.2). Provenance: the captures (path,
// capture.json SHA-256, static or waving), the metric and its weights, the
// optimizer (`optimizer`: "simulated_annealing" or "cmaes"), seed, per-trial
// errors of `final`, simulator and integrator. `captures[i]` must be the
// capture of problem.trials()[i].
formats::FabricPreset fitted_preset(const std::string& name, const ClothFitProblem& problem,
                                    const std::vector<formats::Capture>& captures, const cloth::ClothMaterial& material,
                                    const ClothEvaluation& final, std::uint64_t seed,
                                    const optim::VariabilityReport* variability = nullptr,
                                    const std::string& optimizer = "simulated_annealing");

// Frames of a run that are good: all, or those before the frame it failed at.
int usable_frames(const cloth::SwatchRun& run);

// E_k of each of the trial's compared frames (in order) for one simulation
// run of it; a frame the run did not reach costs missing_frame_error.
std::vector<video::FrameError> compare_run(const ClothTrial& trial, const cloth::SwatchRun& run,
                                             const video::AngleMapMetricSettings& metric);

// The trial with its reference frames replaced by a simulation's own renders
// (same frames, weights, camera): a run as the "footage" another run is
// compared with (predictability ensembles, synthetic footage). Throws
// std::invalid_argument when the run lacks a compared frame.
ClothTrial simulated_trial(const ClothTrial& trial, const cloth::SwatchRun& run, bool edge_distance);

// The base material's equilibrium of a trial, from the candidate bow whose
// first frame matches the trial's footage best (the thesis takes the initial
// state from the footage, too). Empty when no candidate converged. With
// `measured_start`: the measured first frame on the mesh when the winning
// solve began there (a tracks trial's measured candidate), else empty.
Eigen::VectorXd matching_equilibrium(const ClothTrial& trial, const cloth::ClothMaterial& material,
                                     const ClothFitSettings& settings, double* chosen_bow = nullptr,
                                     Eigen::VectorXd* measured_start = nullptr);

// E_k when a simulation produced no frame k (it blew up): every masked pixel
// off by pi/2 and the silhouette term as if the swatch were missing.
double missing_frame_error(const video::ReferenceFrame& reference, const video::AngleMapMetricSettings& settings);

// E_k of a tracks frame: the mean squared distance (mm^2) between the seen
// points (finite rows of `measured_m`) and `simulated_m` (same grid); 0 when
// no point was seen.
double track_frame_error_mm2(const Eigen::MatrixX3d& measured_m, const Eigen::MatrixX3d& simulated_m);

// The trial's weighted RMS distance (mm) for a tracks or scan trial's
// weighted error sum_k w_k E_k: sqrt(error / sum_k w_k).
double tracks_rms_mm(const ClothTrial& trial, double weighted_error);

// r (m) of each of a scan frame's samples for a render of the simulation
// with projector coordinates (StripeRenderSettings::projector_coordinates),
// then of each of its outside pixels (the cap where the render covers it,
// else 0); samples without a measured v_p are left out.
std::vector<double> scan_residuals_m(const ScanReference& scan, std::size_t frame, const video::StripeImage& rendered);

// The scan samples of a frame with a measured v_p: what E_k divides by.
long long scan_measured_count(const ScanReference& scan, std::size_t frame);

}  // namespace flowvid::cloth_fit
