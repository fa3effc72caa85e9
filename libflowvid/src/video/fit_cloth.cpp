#include "flowvid/video/fit_cloth.hpp"

#include "flowvid/optim/design.hpp"
#include "flowvid/optim/thread_pool.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace flowvid::video {

const char* drag_model_name(DragModel model) { return model == DragModel::linear ? "linear" : "nonlinear"; }

std::vector<FittedParameter> linear_drag_test_parameters() {
    std::vector<FittedParameter> p = static_test_parameters();
    p.push_back({"drag_linear_normal_kg_per_m2_s", 1e-3, 10.0, true});
    p.push_back({"drag_tangential_kg_per_m2_s", 1e-3, 10.0, true});
    return p;
}

std::vector<FittedParameter> parameters_for(const std::vector<ClothTrial>& trials, DragModel drag) {
    const bool any_waving = std::any_of(trials.begin(), trials.end(), [](const ClothTrial& t) { return !t.is_static; });
    if (!any_waving) return static_test_parameters();
    return drag == DragModel::linear ? linear_drag_test_parameters() : waving_test_parameters();
}

cloth::ClothMaterial middle_of_ranges(const cloth::ClothMaterial& base, const std::vector<FittedParameter>& parameters) {
    cloth::ClothMaterial m = base;
    for (const FittedParameter& p : parameters)
        set_material_parameter(m, p.key, p.log_scale ? std::sqrt(p.lower * p.upper) : 0.5 * (p.lower + p.upper));
    return m;
}

std::vector<ClothTrial> load_trials(const std::vector<formats::Capture>& captures, const TrialLoadSettings& load) {
    std::vector<ClothTrial> trials;
    for (const formats::Capture& capture : captures) trials.push_back(load_trial(capture, load));
    return trials;
}

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

}  // namespace

ClothFitOutcome fit_cloth(const ClothFitRequest& request) {
    if (request.captures.empty()) throw std::invalid_argument("fit_cloth: no captures");
    const Clock::time_point started = Clock::now();
    ClothFitOutcome outcome;
    std::atomic<bool> cancelled{false};
    const auto stop_requested = [&] { return cancelled.load() || (request.cancel && request.cancel->load()); };
    const auto report = [&](const ClothFitProgress& p) {
        if (request.progress && !request.progress(p)) cancelled = true;
        return !stop_requested();
    };
    report({"loading", 0.0, 0, 0.0, 0.0, 0.0});

    std::vector<ClothTrial> trials = load_trials(request.captures, request.load);
    for (const ClothTrial& t : trials) outcome.trial_names.push_back(t.name);
    outcome.parameters = parameters_for(trials, request.drag);
    ClothFitSettings settings = request.problem;
    settings.base = middle_of_ranges(request.problem.base, outcome.parameters);
    outcome.start = settings.base;
    const ClothFitProblem problem(std::move(trials), outcome.parameters, settings);
    outcome.trials = problem.trials();
    const int threads = request.threads > 0 ? request.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    const Clock::time_point start_evaluation_began = Clock::now();
    outcome.start_evaluation = problem.evaluate(outcome.start, threads);
    const double evaluation_seconds = seconds_since(start_evaluation_began);

    // Main search: design, then annealing on the rest of the evaluations.
    const int n = problem.space().size();
    // The final evaluation comes after the search: keep time for it (it
    // costs about what the start's did) so the whole fit stays in budget.
    const double budget = request.budget_seconds > 0.0
                              ? std::max(1.0, request.budget_seconds - 1.5 * evaluation_seconds)
                              : 0.0;
    const double variability_share = request.variability_runs > 0 ? 0.2 : 0.0;
    optim::MinimizeSettings search;
    search.design = optim::DesignKind::halton;
    search.design_points = request.design_points > 0
                               ? request.design_points
                               : static_cast<int>(std::clamp<long long>(request.evaluations / 4, n + 1, 16LL * n));
    search.threads = threads;
    optim::AnnealingSettings& annealing = search.annealing;
    annealing.seed = request.seed;
    annealing.max_evaluations = request.evaluations;
    annealing.fit_schedule_to_budget = true;
    annealing.evaluations_per_stage = static_cast<int>(std::max<long long>(n + 1, (request.evaluations - search.design_points) / 16));
    annealing.cancel = &cancelled;
    if (budget > 0.0) {
        // A third of the search's time at most for the design, the rest for annealing.
        search.design_budget_seconds = std::max(1.0, (1.0 - variability_share) * budget / 3.0);
        // minimize measures the design, then plans the cooling for what is left.
        search.total_budget_seconds = std::max(2.0, (1.0 - variability_share) * budget - seconds_since(started));
    }
    const double main_share = 1.0 - variability_share;
    annealing.progress = [&](const optim::AnnealingProgress& p) {
        return report({"annealing", main_share * p.fraction_done, p.evaluations, p.best_value, p.temperature, p.eta_s});
    };
    report({"design", 0.02, 0, 0.0, 0.0, 0.0});
    if (request.cancel && request.cancel->load()) cancelled = true;
    // The annealer polls `cancelled`; an external cancel is forwarded by the progress callback.
    outcome.search = optim::minimize(problem.objective(), problem.space(), search);
    outcome.evaluations = outcome.search.evaluations;
    if (outcome.search.annealing.status == optim::AnnealingResult::Status::cancelled || stop_requested()) {
        outcome.status = ClothFitOutcome::Status::cancelled;
        outcome.seconds = seconds_since(started);
        return outcome;
    }
    Eigen::VectorXd best = outcome.search.annealing.best_values;

    // Variability analysis: polish from +-5 % perturbed starts (each run on one thread).
    if (request.variability_runs > 0) {
        optim::VariabilitySettings variability;
        variability.runs = request.variability_runs;
        variability.perturbation = request.variability_perturbation;
        variability.threads = threads;
        variability.annealing.seed = request.seed ^ 0x5eedULL;
        variability.annealing.initial_temperature = 0.0;  // a polish: how well the data pins each parameter
        variability.annealing.initial_step = 0.05;
        variability.annealing.max_evaluations = request.variability_evaluations;
        variability.annealing.cancel = &cancelled;
        if (budget > 0.0) variability.annealing.budget_seconds = std::max(1.0, budget - seconds_since(started)) /
                                                                 std::max(1.0, std::ceil(double(request.variability_runs) / threads));
        report({"variability", main_share, outcome.evaluations, outcome.search.annealing.best_value, 0.0, 0.0});
        outcome.variability = optim::variability_analysis(problem.objective(), problem.space(), best, variability);
        for (const optim::AnnealingResult& run : outcome.variability->runs) {
            outcome.evaluations += run.evaluations;
            // A restart that found a lower error improves the fit itself.
            if (run.best_value < outcome.search.annealing.best_value && run.best_values.size() == best.size()) {
                outcome.search.annealing.best_value = run.best_value;
                best = run.best_values;
            }
        }
        if (stop_requested()) {
            outcome.status = ClothFitOutcome::Status::cancelled;
            outcome.seconds = seconds_since(started);
            return outcome;
        }
    }

    report({"final", 0.99, outcome.evaluations, outcome.search.annealing.best_value, 0.0, 0.0});
    outcome.fitted = problem.material(best);
    outcome.final_evaluation = problem.evaluate(outcome.fitted, threads);
    outcome.evaluations += 2;  // start and final evaluations
    outcome.simulations = outcome.evaluations * static_cast<long long>(problem.trials().size());
    if (request.drag == DragModel::nonlinear)
        outcome.preset = fitted_preset(request.name, problem, request.captures, outcome.fitted, outcome.final_evaluation,
                                       request.seed, outcome.variability ? &*outcome.variability : nullptr);
    outcome.seconds = seconds_since(started);
    report({"final", 1.0, outcome.evaluations, outcome.final_evaluation.total, 0.0, 0.0});
    return outcome;
}

}  // namespace flowvid::video
