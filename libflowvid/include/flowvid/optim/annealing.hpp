#pragma once
// Simulated annealing for continuous parameters (thesis 2.4.5): the downhill
// simplex method with Metropolis-style thermal fluctuations (the idea of
// Press et al.'s amebsa, written here from its description): every simplex
// vertex's value is raised by T |log u| and every trial point's value lowered
// by T |log u| (u uniform in (0, 1]) before the simplex compares them, so at
// temperature T uphill moves of order T are accepted. The temperature falls
// geometrically by `cooling` after every stage of `evaluations_per_stage`
// evaluations; whenever it has dropped by `reset_factor` (3, as the thesis)
// the simplex is rebuilt around the best point found so far. Below
// final_temperature_ratio * T0 the temperature is set to 0 and the plain
// simplex polishes the best point until it converges.
//
// Parameters are searched in the unit cube of a ParameterSpace (log space
// where asked); points outside it count as +inf, which keeps the search in
// bounds. initial_temperature = 0 makes this the plain downhill simplex (the
// baseline the tests compare against).
//
// Determinism: all random numbers come from the seed in an order that does
// not depend on evaluation results' timing, batches are evaluated into
// per-index slots, and the objective is deterministic: the same seed gives
// bit-identical results for any number of threads.
//
// The library never prints: progress goes to a callback (iteration,
// temperature, best error, ETA) that can cancel by returning false, and
// `cancel` can be set from another thread.

#include "flowvid/progress.hpp"
#include "flowvid/optim/design.hpp"
#include "flowvid/optim/objective.hpp"

#include <Eigen/Core>

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flowvid::optim {

struct AnnealingSettings {
    std::uint64_t seed = 1;
    // < 0: automatic, temperature_scale times the spread of the start (the
    // design's value spread, else the initial simplex's); 0: plain simplex.
    double initial_temperature = -1.0;
    double temperature_scale = 1.0;
    double cooling = 0.9;               // T <- cooling * T after every stage
    int evaluations_per_stage = 0;      // 0: 10 (n + 1)
    double reset_factor = 3.0;          // rebuild the simplex at the best point when T falls by this factor
    double final_temperature_ratio = 1e-4;  // then T = 0 and polish
    double initial_step = 0.1;          // simplex edge, unit-cube units
    // Simplex edge at a reset: initial_step (T / T0)^step_exponent (>= min_step).
    // 0 (the same edge at every reset) found the global minimum of Rastrigin
    // 2-D in 20 of 20 shifted instances against 6 with 0.5 (the instances of
    // bench_optim --report; see docs/cloth_fitting.md).
    double step_exponent = 0.0;
    double min_step = 1e-3;
    double tolerance = 1e-8;            // polish stops when 2 |hi - lo| / (|hi| + |lo| + 1e-12) < tolerance ...
    double step_tolerance = 1e-7;       // ... or the simplex is smaller than this (unit cube)
    long long max_evaluations = 20000;
    // Fit the schedule to max_evaluations: cooling is chosen so that the
    // final temperature is reached after 3/4 of the budget, leaving the rest
    // for the polish (for expensive objectives with a fixed simulation budget;
    // `cooling` is ignored then).
    bool fit_schedule_to_budget = false;
    double budget_seconds = 0.0;        // wall-clock limit, 0 = none
    // Expected wall time of one evaluation, until the run has measured its
    // own: a budgeted run never starts evaluations it cannot finish in time.
    double evaluation_seconds_hint = 0.0;
    // After every temperature stage: stage "annealing" ("variability" for the
    // runs of a variability analysis, the run named in the message), the
    // fraction done (the schedule or the limits, whichever ends first) and
    // "N evaluations, best V, T t, ETA s" (this run's); false cancels. The
    // stages themselves are in AnnealingResult::history.
    Progress progress;
    const std::atomic<bool>* cancel = nullptr;
};

struct AnnealingStage {
    long long evaluations = 0;  // at the end of the stage
    double temperature = 0.0;
    double best_value = 0.0;
};

struct AnnealingResult {
    enum class Status { converged, max_evaluations, time_budget, cancelled, no_finite_value };
    Status status = Status::converged;
    std::string reason;
    Eigen::VectorXd best_unit;    // unit cube
    Eigen::VectorXd best_values;  // parameter values
    double best_value = 0.0;
    double start_value = 0.0;
    long long evaluations = 0;
    int iterations = 0;
    int stages = 0;
    int resets = 0;
    double initial_temperature = 0.0;
    double final_temperature = 0.0;
    double elapsed_s = 0.0;
    std::vector<AnnealingStage> history;
};
const char* status_name(AnnealingResult::Status status);

// One annealing run from `start_unit` (unit cube). `start_value` is the
// objective there when known (NaN: evaluated); `start_spread` the scale for
// the automatic temperature (0: from the initial simplex).
AnnealingResult anneal(Evaluator& evaluator, const Eigen::VectorXd& start_unit, const AnnealingSettings& settings,
                       double start_value = std::numeric_limits<double>::quiet_NaN(), double start_spread = 0.0,
                       int run = 0);

struct CmaesSettings;

// What searches from the design's best point: the thesis's annealing, or
// CMA-ES (optim/cmaes.hpp), which evaluates a generation in parallel.
enum class SearchMethod { annealing, cmaes };
const char* search_method_name(SearchMethod method);
// The method of one of those names; nullopt for any other text.
std::optional<SearchMethod> search_method_from_name(std::string_view name);

// The thesis's procedure: a space-filling design, then annealing (or CMA-ES)
// from its best point.
struct MinimizeSettings {
    DesignKind design = DesignKind::halton;
    int grid_levels = 4;          // grid: levels^n points (the thesis's 4^n)
    int design_points = 0;        // halton: 0 = 16 n
    AnnealingSettings annealing;  // its seed also scrambles the Halton design
    // The search after the design. Its seed, evaluation and time limits,
    // progress callback and cancel flag are `annealing`'s for either method;
    // CMA-ES takes its population and step size from `cmaes_population` and
    // `cmaes_initial_sigma`.
    SearchMethod method = SearchMethod::annealing;
    int cmaes_population = 0;          // 0: 4 + floor(3 ln n)
    double cmaes_initial_sigma = 0.2;  // unit-cube units
    // A point the caller has evaluated already (unit cube; its value, NaN:
    // none): CMA-ES starts from it when it beats the design's best (a
    // design of a few points in many dimensions rarely beats a good guess).
    Eigen::VectorXd cmaes_known_unit;
    double cmaes_known_value = std::numeric_limits<double>::quiet_NaN();
    int threads = 0;              // 0: all cores
    // Wall-clock limit of the design (0 = none): points not started by then
    // are skipped (+inf) and the annealing starts from the best evaluated one.
    // Makes the result depend on the machine's speed, like budget_seconds.
    double design_budget_seconds = 0.0;
    // Wall-clock limit of design + annealing (0 = none): the annealing gets
    // what the design left (overrides annealing.budget_seconds).
    double total_budget_seconds = 0.0;
    // Shard `shard_index` (1-based) of `shard_count` (0: no sharding), for a
    // search split over machines: it evaluates design points shard_index - 1,
    // shard_index - 1 + shard_count, ... of the same design the whole search
    // draws (same seed), then anneals from the best of those with a seed
    // derived from the seed and shard_index. Its annealing gets the
    // evaluations the whole search's would (max_evaluations minus the whole
    // design), so every shard is an independent restart of equal weight.
    // std::invalid_argument when the index is out of 1..count or there are
    // more shards than design points.
    int shard_index = 0;
    int shard_count = 0;
};
struct MinimizeResult {
    DesignResult design;        // the points this search (or shard) evaluated
    AnnealingResult annealing;  // the search after the design (CMA-ES fills it the same way)
    long long evaluations = 0;  // design + annealing
    int design_points_total = 0;  // of the whole design (sharded: all shards' points)
};
MinimizeResult minimize(const Objective& objective, const ParameterSpace& space, const MinimizeSettings& settings);

// Variability analysis (thesis table 2.2): anneal again from starts whose
// every parameter is the given start times (1 + U(-p, p)), clamped to the
// bounds, and report how much each parameter's result varies. A parameter
// the data does not determine (damping in a static test) varies a lot.
struct VariabilitySettings {
    int runs = 5;
    double perturbation = 0.05;   // +-5 %
    AnnealingSettings annealing;  // run i uses a seed derived from annealing.seed and i
    double start_spread = 0.0;    // temperature scale, as anneal()
    int threads = 0;              // runs are spread over the threads, each run on one
};
struct ParameterVariability {
    std::string name;
    double mean = 0.0;
    double stddev = 0.0;               // sample standard deviation over runs
    double variability_percent = 0.0;  // 100 stddev / |mean|
    double log_stddev = 0.0;           // stddev of ln(value) (log-scaled parameters: ~ relative spread)
    double min = 0.0;
    double max = 0.0;
};
struct VariabilityReport {
    std::vector<Eigen::VectorXd> starts;  // values
    std::vector<AnnealingResult> runs;
    std::vector<ParameterVariability> parameters;
    double best_value = 0.0;   // over runs
    double worst_value = 0.0;
};
VariabilityReport variability_analysis(const Objective& objective, const ParameterSpace& space,
                                       const Eigen::VectorXd& start_values, const VariabilitySettings& settings);

}  // namespace flowvid::optim
