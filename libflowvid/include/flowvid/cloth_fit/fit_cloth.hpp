#pragma once
// The whole cloth fit (thesis 2.4.5-2.5) as one call: load the trials of
// several captures (static drapes and waving tests, fitted jointly), search
// the fabric parameters (a small Halton design, then CMA-ES or the thesis's
// simulated annealing from its best point; a least-squares polish for
// tracks and scan fits), search again from the best fabric with each
// trial's fold state picked by it (refinement rounds), repeat from +-5 %
// perturbed starts for the variability analysis, and produce the fabric
// preset. Used by `flowvid fit cloth`, the fit benchmarks and the tests.

#include "flowvid/progress.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/least_squares.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::cloth_fit {

// Which drag law the fit uses: the thesis's nonlinear one (kN, kf, kT), or
// linear drag only (kL on the normal, kT on the tangential velocity, like
// Blender's air damping) -- the comparison the thesis made for nonlinear drag.
enum class DragModel { nonlinear, linear };
const char* drag_model_name(DragModel model);

// Static-test parameters (6) + kL and kT: the linear-drag comparison fit.
std::vector<FittedParameter> linear_drag_test_parameters();

// The shear stiffness's floor once the diagonal fibres are fitted (N/m; the
// thesis's range starts at 5). Measured in docs/cloth_model.md, "The shear
// floor settled".
inline constexpr double kShearFloorWithDiagonalFibres_N_per_m = 0.5;

// The terms the model capacity study added (fabric preset 1.1) and their
// search ranges: the hem and both compression ratios (the drape's shape),
// with a waving test the linear normal drag, the diagonal tension fibres
// (docs/cloth_model.md), and the wider shear range the fibres call for
// (it replaces the thesis's shear range: see with_terms).
std::vector<FittedParameter> capacity_terms(bool waving, DragModel drag);

// `parameters` with each of `terms` in place of the entry with its key, or
// appended where there is none.
std::vector<FittedParameter> with_terms(std::vector<FittedParameter> parameters, const std::vector<FittedParameter>& terms);

// What is fitted for a set of trials: the 6 static-test parameters when all
// trials are static drapes (drag cannot be seen at rest), else 9 (nonlinear)
// or 8 (linear drag). Trials that measure the swatch's shape (tracks, or a
// stripe scan) also fit capacity_terms(): 10 static, 14 (nonlinear) or 12
// (linear) with a waving test. Angle-map fits keep the thesis's set.
std::vector<FittedParameter> parameters_for(const std::vector<ClothTrial>& trials, DragModel drag);

// The start guess: `base` with every fitted parameter at the geometric middle
// of its range (no hand tuning, the same for every fabric).
cloth::ClothMaterial middle_of_ranges(const cloth::ClothMaterial& base, const std::vector<FittedParameter>& parameters);


// One of `count` independent tasks a fit is split into for a render farm or
// a cluster (1-based `index`): its share of the design (points index - 1,
// index - 1 + count, ... of the design the whole fit draws) and one
// annealing from the best of them with a seed derived from (seed, index).
// The shard with the lowest error wins; finish_cloth_fit makes its preset.
struct ClothFitShard {
    int index = 1;
    int count = 1;
};

struct ClothFitRequest {
    std::string name = "fitted fabric";
    std::vector<formats::Capture> captures;
    TrialLoadSettings load;                // frames and their weights (predictability: decaying weights)
    ClothFitSettings problem;              // mesh, integrator, metric, base material (unfitted values)
    DragModel drag = DragModel::nonlinear;
    // The fitted parameters and their ranges; empty: parameters_for(trials, drag).
    std::vector<FittedParameter> parameters;
    // A floor on the fitted bending stiffness (N m; 0: the parameters' own
    // range). Folds much finer than a mesh edge make a drape depend on the
    // mesh; a floor buys a preset that drapes alike on 12x12 to 48x48 meshes
    // at the cost of reach (docs/cloth_model.md, "Resolution").
    double min_bending_N_m = 0.0;
    // Parameters left out of the fit (keys of `parameters`): "key" keeps the
    // start's value (the base material's, e.g. a capacity term's neutral
    // value), "key=value" holds it at that value (SI, the preset's unit).
    // An ablation: a fabric fitted without soft compression, say, for the gap
    // diagnosis to find it missing; or a trade: silk's shear held near 0
    // buys a preset that drapes alike on 12x12 to 48x48 meshes at a cost in
    // reach (not cotton's: docs/cloth_model.md). Unknown keys, bad values:
    // UsageError.
    std::vector<std::string> held_parameters;
    // The share of the shear read on the swatch grid's cells (not fitted; the
    // preset keeps it). nullopt: the start's when a start is given, else
    // default_shear_cell_fraction(load.target).
    std::optional<double> shear_cell_fraction;
    // The fit's start instead of the middle of the parameters' ranges (its
    // fitted values clamped into them): where the search begins, and the
    // fabric whose equilibrium picks each trial's fold state (an earlier
    // fit's preset, to refine it).
    std::optional<cloth::ClothMaterial> start;
    // Refinement rounds after the first search. Each trial's fold state is
    // picked by the start's fabric, and a footage objective then rewards
    // fabrics that suit that start (docs/cloth_fitting.md, "What the start
    // decides"): a refinement round picks the fold states again with the
    // fabric found so far and searches again from it, as `fit cloth --start`
    // does by hand. Not the default: in 600 s scan fits it improved both
    // public fabrics' held-out trials in the capacity bench and made them
    // worse in all four `fit cloth` runs (docs/cloth_fitting.md). Tracks
    // fits and shards never refine. A round the evaluations or the budget
    // cannot pay for (its design and two generations) is dropped.
    int refine_rounds = 0;
    // The refinement rounds' share of the search's evaluations and, under a
    // budget, of its time (split evenly between them).
    double refine_share = 0.4;
    long long evaluations = 400;           // main search, all rounds: design + CMA-ES (or annealing)
    // The search after the design: CMA-ES, which evaluates a generation of
    // candidates in parallel and learns the parameters' scales and
    // correlations, or the thesis's annealing, which needed more simulations
    // for the same error on every fit we measured (docs/cloth_fitting.md, "Search").
    optim::SearchMethod search = optim::SearchMethod::cmaes;
    int design_points = 0;                 // 0: annealing min(16 n, evaluations / 4) (at least n + 1); CMA-ES n + 1
    // Fits to tracks or a scan: after the search, a Levenberg-Marquardt
    // polish of its best point (their error is a sum of squares, so a few
    // Jacobians converge where annealing creeps). Evaluations it may use;
    // -1: 8 (n + 1) for tracks and scan fits, none for footage fits.
    long long polish_evaluations = -1;
    int variability_runs = 4;              // thesis table 2.2; 0: none (no uncertainty in the preset)
    long long variability_evaluations = 40;  // per run (a polish from the perturbed start)
    double variability_perturbation = 0.05;
    double budget_seconds = 0.0;           // wall-clock cap on the whole fit, 0 = none (then deterministic)
    // Evaluations' worth of time the caller spends after the fit inside the
    // same budget, kept out of the search's share (the floors below keep
    // their own share: they need not be counted here).
    double evaluations_after_fit = 0.0;
    // Members of the predictability floor reported beside each trial's final
    // error (outcome.floors): an ensemble at the fitted fabric, with the
    // preset's uncertainty, at the steps floors are reported with
    // (reported_floor), inside the same budget. An error near its floor is as
    // good as it gets. 0: no floors (shards never have them).
    int floor_members = 0;
    std::uint64_t seed = 1;
    // Only this shard's search (no variability restarts, no final evaluation,
    // no preset: outcome.search holds its best point). Throws
    // std::invalid_argument when there are more shards than design points.
    std::optional<ClothFitShard> shard;
    int threads = 0;                       // 0: all cores; results do not depend on it
    // Stages "loading", "design", "annealing", "polish", "refining",
    // "variability", "floors", "final", with fractions of the whole fit and
    // "N evaluations, best E[, T t, ETA s]" as the message (each evaluation
    // simulates every trial); false cancels (status cancelled). The
    // convergence itself is in the outcome (search history, rounds).
    Progress progress;
    const std::atomic<bool>* cancel = nullptr;
};

// The share of the shear the request's fit reads on the grid's cells: the
// request's, else its start's, else the fit target's default.
double resolved_shear_cell_fraction(const ClothFitRequest& request);

// One search round of a fit: its start (the previous round's best, or the
// request's start), its best point, both on this round's objective (its fold
// states), and what it cost, polish included.
struct ClothFitRound {
    cloth::ClothMaterial best;             // the next round's start
    double start_error = 0.0;
    double best_error = 0.0;
    long long evaluations = 0;
    double seconds = 0.0;
};

// One trial's predictability floor as the fit reports it (weighted like its
// error). The floor re-solves the fitted fabric's equilibrium from scratch;
// when that fails the fit is still good: the floor is missing and `failure`
// says why.
struct ReportedFloor {
    std::optional<double> weighted;
    std::string failure;
};

struct ClothFitOutcome {
    enum class Status { ok, cancelled };
    Status status = Status::ok;
    std::vector<FittedParameter> parameters;
    std::vector<std::string> trial_names;
    std::vector<ClothTrial> trials;        // as loaded and fitted (footage angle maps, weights)
    cloth::ClothMaterial start;            // middle_of_ranges, or the request's start (the first round's)
    cloth::ClothMaterial fitted;
    ClothEvaluation start_evaluation;      // the first round's start
    ClothEvaluation final_evaluation;      // on the last round's objective
    // The last round's search (its annealing's best is the polished point
    // when there was a polish) and polish.
    optim::MinimizeResult search;
    std::optional<optim::LeastSquaresResult> polish;
    std::vector<ClothFitRound> rounds;     // the first search, then each refinement round run
    std::optional<optim::VariabilityReport> variability;
    std::optional<formats::FabricPreset> preset;
    // Variability restarts the budget allowed (the request's, or fewer when a
    // time budget cannot pay for them; 0: no uncertainty in the preset).
    int variability_runs_planned = 0;
    // With request.floor_members: one per trial, and the sum of those there are.
    std::vector<ReportedFloor> floors;
    double total_floor = 0.0;
    long long evaluations = 0;             // objective evaluations in all phases
    long long simulations = 0;             // evaluations x trials
    double seconds = 0.0;
};

// Throws what load_trial throws for unusable captures, std::invalid_argument
// for no captures.
ClothFitOutcome fit_cloth(const ClothFitRequest& request);

// The end of a fit whose main search ran elsewhere (the winning shard's
// best point, `values` of the parameters `names` in search order):
// variability restarts from there when request.variability_runs > 0 (a
// restart with a lower error moves the fit there, as in fit_cloth), then the
// final evaluation and the preset, exactly as fit_cloth ends. Ignores
// request.shard and the time budget, so it is deterministic. Reports the
// floors as fit_cloth does. outcome.search
// gets `values` and `error` as its annealing's best; start_evaluation is
// left empty (no start is simulated). Throws std::invalid_argument when
// `names` are not the parameters the request's captures fit.
ClothFitOutcome finish_cloth_fit(const ClothFitRequest& request, const std::vector<std::string>& names,
                                 const Eigen::VectorXd& values, double error);

// The trials of captures with the request's load settings (in order).
std::vector<ClothTrial> load_trials(const std::vector<formats::Capture>& captures, const TrialLoadSettings& load);

}  // namespace flowvid::cloth_fit
