#include "flowvid/cloth_fit/fit_cloth.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/optim/design.hpp"
#include "flowvid/thread_pool.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <optional>
#include <stdexcept>
#include <thread>

namespace flowvid::cloth_fit {

const char* drag_model_name(DragModel model) { return model == DragModel::linear ? "linear" : "nonlinear"; }

std::vector<FittedParameter> linear_drag_test_parameters() {
    std::vector<FittedParameter> p = static_test_parameters();
    p.push_back({"drag_linear_normal_kg_per_m2_s", 1e-3, 10.0, true});
    p.push_back({"drag_tangential_kg_per_m2_s", 1e-3, 10.0, true});
    return p;
}

std::vector<FittedParameter> capacity_terms(bool waving, DragModel drag) {
    std::vector<FittedParameter> p = {
        {"hem_line_density_kg_per_m", 1e-5, 3e-3, true},
        {"stretch_warp_compression_ratio", 1e-3, 1.0, true},
        {"stretch_weft_compression_ratio", 1e-3, 1.0, true},
    };
    // The linear-drag model fits kL already.
    if (waving && drag == DragModel::nonlinear) p.push_back({"drag_linear_normal_kg_per_m2_s", 1e-3, 10.0, true});
    p.push_back({"diagonal_tension_stiffness_N_per_m", 1e-1, 1e4, true});
    // The diagonal fibres carry shear load in tension, so the isotropic
    // shear may go below the thesis's 5 N/m floor: silk's fits reach 1-6 N/m.
    // The rest of the thesis's shear range stays as it is.
    for (FittedParameter shear : static_test_parameters())
        if (shear.key == "shear_stiffness_N_per_m") {
            shear.lower = kShearFloorWithDiagonalFibres_N_per_m;
            p.push_back(shear);
        }
    return p;
}

std::vector<FittedParameter> with_terms(std::vector<FittedParameter> parameters, const std::vector<FittedParameter>& terms) {
    for (const FittedParameter& term : terms) {
        const auto same_key = std::find_if(parameters.begin(), parameters.end(),
                                           [&](const FittedParameter& p) { return p.key == term.key; });
        if (same_key != parameters.end())
            *same_key = term;
        else
            parameters.push_back(term);
    }
    return parameters;
}

std::vector<FittedParameter> parameters_for(const std::vector<ClothTrial>& trials, DragModel drag) {
    const bool any_waving = std::any_of(trials.begin(), trials.end(), [](const ClothTrial& t) { return !t.is_static; });
    std::vector<FittedParameter> p = !any_waving                ? static_test_parameters()
                                     : drag == DragModel::linear ? linear_drag_test_parameters()
                                                                 : waving_test_parameters();
    const bool measured_shape = !trials.empty() && std::all_of(trials.begin(), trials.end(),
                                                               [](const ClothTrial& t) { return t.measures_shape(); });
    return measured_shape ? with_terms(std::move(p), capacity_terms(any_waving, drag)) : p;
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

// What the fit reports at each step, before it becomes a flowvid::Progress report.
struct FitStep {
    std::string phase;
    double fraction = 0.0;      // of the whole fit
    long long evaluations = 0;  // objective evaluations so far
    double best_error = 0.0;
    std::string detail = {};  // the optimiser's own message, when a search or polish reports (its counts are its own)
};
using Reporter = std::function<bool(const FitStep&)>;

std::string step_message(const FitStep& p) {
    if (!p.detail.empty()) return p.detail;
    char text[160];
    std::snprintf(text, sizeof text, "%lld evaluations, best %.4g", p.evaluations, p.best_error);
    return text;
}

// Cancellation and progress of one fit: the request's cancel flag, or its
// progress callback returning false, stops it.
struct FitControl {
    explicit FitControl(const ClothFitRequest& request)
        : stop_requested([this, &request] { return cancelled.load() || (request.cancel && request.cancel->load()); }),
          report([this, &request](const FitStep& p) {
              if (request.progress && !request.progress({p.phase, p.fraction, step_message(p)})) cancelled = true;
              return !stop_requested();
          }) {}
    std::atomic<bool> cancelled{false};
    std::function<bool()> stop_requested;
    Reporter report;
};

// A held parameter, "key" or "key=value" (ClothFitRequest::held_parameters).
struct HeldParameter {
    std::string key;
    std::optional<double> value;  // none: the start's value
};

HeldParameter parse_held(const std::string& text) {
    const std::size_t equals = text.find('=');
    HeldParameter held{text.substr(0, equals), std::nullopt};
    if (equals == std::string::npos) return held;
    const std::string number = text.substr(equals + 1);
    char* end = nullptr;
    const double value = number.empty() ? NAN : std::strtod(number.c_str(), &end);
    if (number.empty() || end != number.c_str() + number.size() || !std::isfinite(value) || value < 0.0)
        throw UsageError("", "--hold", "'" + text + "': '" + number + "' is not a value the parameter can take",
                         "give a non-negative number in the preset's SI unit, e.g. --hold " + held.key + "=1e-6");
    held.value = value;
    return held;
}

// The request's trials; their names and the fitted parameters go into `outcome`.
std::vector<ClothTrial> load_fit_trials(const ClothFitRequest& request, ClothFitOutcome& outcome) {
    std::vector<ClothTrial> trials = load_trials(request.captures, request.load);
    for (const ClothTrial& t : trials) outcome.trial_names.push_back(t.name);
    std::vector<FittedParameter> parameters = request.parameters.empty() ? parameters_for(trials, request.drag) : request.parameters;
    for (const std::string& held_text : request.held_parameters) {
        const HeldParameter parsed = parse_held(held_text);
        const std::string& held = parsed.key;
        const auto it = std::find_if(parameters.begin(), parameters.end(), [&](const FittedParameter& p) { return p.key == held; });
        if (it == parameters.end()) {
            std::string fitted;
            for (const FittedParameter& p : parameters) fitted += (fitted.empty() ? "" : ", ") + p.key;
            throw UsageError("", "--hold", "cannot hold '" + held + "': this fit does not fit it",
                             "hold one of the fitted parameters: " + fitted);
        }
        if (parsed.value == 0.0 && !parameter_allows_zero(held))
            throw UsageError("", "--hold", "'" + held_text + "': a fabric preset needs " + held + " positive",
                             "hold it at a small positive value instead, e.g. --hold " + held + "=1e-6");
        parameters.erase(it);
    }
    outcome.parameters = with_bending_floor(parameters, request.min_bending_N_m);
    return trials;
}

}  // namespace

double resolved_shear_cell_fraction(const ClothFitRequest& request) {
    if (request.shear_cell_fraction) return *request.shear_cell_fraction;
    return request.start ? request.start->shear_cell_fraction : default_shear_cell_fraction(request.load.target);
}

namespace {

// The problem a whole fit searches and a merge finishes: the base starts in
// the middle of the fitted parameters' ranges.
ClothFitProblem make_problem(const ClothFitRequest& request, std::vector<ClothTrial> trials, ClothFitOutcome& outcome) {
    ClothFitSettings settings = request.problem;
    settings.base = middle_of_ranges(request.problem.base, outcome.parameters);
    if (request.start) {
        settings.base = *request.start;
        for (const FittedParameter& p : outcome.parameters)
            set_material_parameter(settings.base, p.key, std::clamp(material_parameter(*request.start, p.key), p.lower, p.upper));
    }
    for (const std::string& text : request.held_parameters)
        if (const HeldParameter held = parse_held(text); held.value) set_material_parameter(settings.base, held.key, *held.value);
    settings.base.shear_cell_fraction = resolved_shear_cell_fraction(request);
    outcome.start = settings.base;
    ClothFitProblem problem(std::move(trials), outcome.parameters, settings);
    outcome.trials = problem.trials();
    return problem;
}

int fit_threads(const ClothFitRequest& request) {
    return resolve_thread_count(request.threads);
}

// How every fit ends, whole or merged from shards: variability restarts from
// `best` (when `runs` > 0; a restart that finds a lower error improves the
// fit itself), the final evaluation and the preset. `restart_budget_seconds`
// (0: none) limits each restart. False when cancelled.
bool end_fit(const ClothFitRequest& request, const ClothFitProblem& problem, int threads, int runs,
             double restart_budget_seconds, double restart_evaluation_hint_seconds, double main_share,
             std::atomic<bool>& cancelled, const std::function<bool()>& stop_requested, const Reporter& report,
             Eigen::VectorXd best, ClothFitOutcome& outcome) {
    // Variability analysis: polish from +-5 % perturbed starts (each run on one thread).
    if (runs > 0) {
        optim::VariabilitySettings variability;
        variability.runs = runs;
        variability.perturbation = request.variability_perturbation;
        variability.threads = threads;
        variability.annealing.seed = request.seed ^ 0x5eedULL;
        variability.annealing.initial_temperature = 0.0;  // a polish: how well the data pins each parameter
        variability.annealing.initial_step = 0.05;
        variability.annealing.max_evaluations = request.variability_evaluations;
        variability.annealing.cancel = &cancelled;
        if (restart_budget_seconds > 0.0) {
            variability.annealing.budget_seconds = restart_budget_seconds;
            variability.annealing.evaluation_seconds_hint = restart_evaluation_hint_seconds;
        }
        report({"variability", main_share, outcome.evaluations, outcome.search.annealing.best_value});
        outcome.variability = optim::variability_analysis(problem.objective(), problem.space(), best, variability);
        for (const optim::AnnealingResult& run : outcome.variability->runs) {
            outcome.evaluations += run.evaluations;
            // A restart that found a lower error improves the fit itself.
            if (run.best_value < outcome.search.annealing.best_value && run.best_values.size() == best.size()) {
                outcome.search.annealing.best_value = run.best_value;
                best = run.best_values;
            }
        }
        if (stop_requested()) return false;
        // A restart the budget stopped before its first simplex was never
        // polished: its values are only the +-5 % perturbation. Fewer than two
        // polished restarts say nothing about how well the data pin the
        // parameters, so the preset then carries no uncertainty.
        int polished = 0;
        for (const optim::AnnealingResult& run : outcome.variability->runs) polished += run.evaluations > 0 ? 1 : 0;
        if (polished < std::min(2, runs)) {
            outcome.variability.reset();
            outcome.variability_runs_planned = 0;
        }
    }

    report({"final", 0.99, outcome.evaluations, outcome.search.annealing.best_value});
    outcome.fitted = problem.material(best);
    outcome.final_evaluation = problem.evaluate(outcome.fitted, threads);
    outcome.preset = fitted_preset(request.name, problem, request.captures, outcome.fitted, outcome.final_evaluation,
                                       request.seed, outcome.variability ? &*outcome.variability : nullptr,
                                       request.search == optim::SearchMethod::cmaes ? "cmaes" : "simulated_annealing");
    return true;
}

}  // namespace

// Evaluations' worth of time spent after the search inside the budget: the
// caller's, and each floor member with its reference run at the floor's
// substeps over the fit's, + the members' equilibrium solves (a few Newton
// steps from the nominal run's; the nominal runs' own fold-state searches
// are timed by the problem's warm starts).
double evaluations_after_fit(const ClothFitRequest& request) {
    if (request.floor_members <= 0 || request.shard) return request.evaluations_after_fit;
    const int fit_substeps = std::max(1, request.problem.swatch.simulation.implicit_substeps_per_frame);
    return request.evaluations_after_fit + (request.floor_members + 1) * kFloorSubstepsPerFrame / fit_substeps + 2;
}

// outcome.floors (ClothFitRequest::floor_members).
void report_floors(const ClothFitRequest& request, int threads, ClothFitOutcome& outcome) {
    if (request.floor_members <= 0 || request.shard) return;
    FloorSettings floor = reported_floor(request.floor_members);
    if (outcome.preset) floor.parameter_sigma = preset_uncertainty(outcome.preset->parameters);
    outcome.total_floor = 0.0;
    for (const ClothTrial& trial : outcome.trials) {
        try {
            const double weighted =
                weighted_floor(trial, estimate_floor(trial, outcome.fitted, request.problem, floor, threads));
            outcome.total_floor += weighted;
            outcome.floors.push_back({weighted, {}});
        } catch (const std::runtime_error& error) {
            outcome.floors.push_back({std::nullopt, error.what()});
        }
    }
}

ClothFitOutcome fit_cloth(const ClothFitRequest& request) {
    if (request.captures.empty()) throw std::invalid_argument("fit_cloth: no captures");
    const Clock::time_point started = Clock::now();
    ClothFitOutcome outcome;
    FitControl control(request);
    std::atomic<bool>& cancelled = control.cancelled;
    const std::function<bool()>& stop_requested = control.stop_requested;
    const Reporter& report = control.report;
    report({"loading", 0.0, 0, 0.0});
    // What a cancelled fit returns: everything so far, marked cancelled.
    const auto cancelled_outcome = [&] {
        outcome.status = ClothFitOutcome::Status::cancelled;
        outcome.seconds = seconds_since(started);
        return outcome;
    };

    const ClothFitProblem first_problem = make_problem(request, load_fit_trials(request, outcome), outcome);
    const int threads = fit_threads(request);
    // A shard without a time budget needs no start evaluation (it only
    // times the budget and is reported beside a whole fit's final error).
    const bool evaluate_start = !request.shard || request.budget_seconds > 0.0;
    const Clock::time_point start_evaluation_began = Clock::now();
    if (evaluate_start) outcome.start_evaluation = first_problem.evaluate(outcome.start, threads);
    const double evaluation_seconds = seconds_since(start_evaluation_began);
    // Seconds per evaluation of the latest search (its generations run in
    // parallel), or of the start's evaluation before any search.
    const auto search_pace = [&] {
        const optim::AnnealingResult& a = outcome.search.annealing;
        return a.evaluations > 0 ? a.elapsed_s / static_cast<double>(a.evaluations) : evaluation_seconds;
    };

    const int n = first_problem.space().size();
    // The final evaluation comes after the search: keep time for it (it
    // costs about what the start's did) so the whole fit stays in budget.
    // The floors' nominal runs pick their fold states again, one trial after
    // another, as the problem's warm starts did: keep that time too.
    const double floor_starts_seconds =
        request.floor_members > 0 && !request.shard ? first_problem.warm_start_seconds() : 0.0;
    const auto after_fit_seconds = [&](double evaluation_pace_s) {
        return (1.5 + evaluations_after_fit(request)) * evaluation_pace_s + floor_starts_seconds;
    };
    const double budget =
        request.budget_seconds > 0.0 ? std::max(1.0, request.budget_seconds - after_fit_seconds(evaluation_seconds)) : 0.0;
    // Variability restarts run one per thread, each evaluating its trials on
    // one thread; a restart costs at least its start, its simplex and a few
    // moves. Reserve that time up front (a budget too small for it keeps
    // fewer restarts, then none), instead of letting restarts overrun.
    const double single_thread_evaluation_seconds =
        evaluation_seconds * static_cast<double>(std::min<std::size_t>(threads, first_problem.trials().size()));
    int variability_runs = request.shard ? 0 : request.variability_runs;  // shards skip the restarts
    double variability_seconds = 0.0;
    const auto restart_rounds = [&](int runs) { return std::ceil(double(runs) / std::max(1, threads)); };
    const auto restart_seconds = [&](int runs, double single_thread_evaluation_s) {
        const double evaluations = std::min<double>(request.variability_evaluations, n + 1 + 6);
        return 1.15 * restart_rounds(runs) * evaluations * single_thread_evaluation_s;
    };
    // Fewer restarts (one round), then none, until they fit in `available_s`.
    const auto affordable_runs = [&](int runs, double single_thread_evaluation_s, double available_s) {
        if (runs > 0 && restart_seconds(runs, single_thread_evaluation_s) > available_s) runs = std::min(runs, std::max(2, threads));
        if (runs > 0 && restart_seconds(runs, single_thread_evaluation_s) > available_s) runs = 0;
        return runs;
    };
    if (budget > 0.0 && variability_runs > 0) {
        variability_runs = affordable_runs(variability_runs, single_thread_evaluation_seconds, 0.4 * budget);
        if (variability_runs > 0)
            variability_seconds = std::max(restart_seconds(variability_runs, single_thread_evaluation_seconds), 0.2 * budget);
    }
    outcome.variability_runs_planned = variability_runs;
    const double variability_share = budget > 0.0 ? variability_seconds / budget : (variability_runs > 0 ? 0.2 : 0.0);
    const double main_share = 1.0 - variability_share;

    // The rounds: the first search, then the refinement rounds that its
    // evaluations and time can pay for (each at least a design and two
    // CMA-ES generations, and under a budget the time of that many
    // evaluations and of picking the fold states again).
    const bool any_tracks = std::any_of(first_problem.trials().begin(), first_problem.trials().end(),
                                        [](const ClothTrial& t) { return t.tracks.has_value(); });
    int refine_rounds = request.shard || any_tracks ? 0 : std::max(0, request.refine_rounds);
    const double refine_share = std::clamp(request.refine_share, 0.0, 0.9);
    const long long smallest_round = (n + 1) + 2LL * (4 + static_cast<long long>(std::floor(3.0 * std::log(std::max(1.0, double(n))))));
    const double search_seconds = budget > 0.0 ? std::max(2.0, main_share * budget - seconds_since(started)) : 0.0;
    const auto refinement_affordable = [&](int rounds) {
        if (rounds <= 0 || refine_share <= 0.0) return false;
        const double share = refine_share / rounds;
        if (static_cast<double>(request.evaluations) * share < static_cast<double>(smallest_round)) return false;
        return budget <= 0.0 || search_seconds * share >= static_cast<double>(smallest_round + 4) * evaluation_seconds;
    };
    while (refine_rounds > 0 && !refinement_affordable(refine_rounds)) --refine_rounds;
    const int round_count = 1 + refine_rounds;
    // Each round's share of the search (evaluations, time, progress).
    std::vector<double> round_shares(static_cast<std::size_t>(round_count), 1.0);
    if (refine_rounds > 0) {
        round_shares[0] = 1.0 - refine_share;
        for (int r = 1; r < round_count; ++r) round_shares[std::size_t(r)] = refine_share / refine_rounds;
    }
    const double search_began_s = seconds_since(started);

    // The problem each round searches: the first picks its fold states with
    // the start's fabric, each refinement round with the best fabric so far.
    std::optional<ClothFitProblem> refined_problem;
    const ClothFitProblem* problem = &first_problem;
    cloth::ClothMaterial round_start = outcome.start;
    ClothEvaluation round_start_evaluation = outcome.start_evaluation;
    double share_done = 0.0;
    for (int round = 0; round < round_count; ++round) {
        const Clock::time_point round_began = Clock::now();
        const long long evaluations_before = outcome.evaluations;
        const double share = round_shares[std::size_t(round)];
        const bool last_round = round + 1 == round_count;
        const double progress_begin = main_share * share_done;
        if (round > 0) {
            report({"refining", progress_begin, outcome.evaluations, outcome.search.annealing.best_value});
            round_start = outcome.rounds.back().best;
            ClothFitSettings settings = problem->settings();
            settings.base = round_start;
            refined_problem.emplace(problem->trials(), outcome.parameters, settings);
            problem = &*refined_problem;
            round_start_evaluation = problem->evaluate(round_start, threads);
            outcome.evaluations += 1;
            if (stop_requested()) {
                return cancelled_outcome();
            }
        }
        // Tracks and scan fits: a least-squares polish of the search's best point.
        const long long polish_evaluations =
            request.polish_evaluations >= 0 ? request.polish_evaluations : (problem->all_measure_shape() ? 8LL * (n + 1) : 0LL);
        const bool polishes = polish_evaluations > 0 && problem->all_measure_shape();
        // The round's search ends at its share of the search time, less a
        // fifth of it for its polish: the variability restarts keep theirs.
        const double round_end_s = search_began_s + search_seconds * (share_done + share);
        const double search_end_s = round_end_s - (polishes ? 0.2 * search_seconds * share : 0.0);

        optim::MinimizeSettings search;
        search.design = optim::DesignKind::halton;
        // CMA-ES explores by itself from its first generation: its design only
        // picks the start (one point per shard at least), which leaves the
        // simulations to the search that learns from them (docs/cloth_fitting.md, "Search").
        const long long round_evaluations =
            last_round ? request.evaluations - std::llround(static_cast<double>(request.evaluations) * share_done)
                       : std::llround(static_cast<double>(request.evaluations) * share);
        const long long default_design = request.search == optim::SearchMethod::cmaes
                                             ? std::max<long long>(n + 1, request.shard ? request.shard->count : 1)
                                             : std::clamp<long long>(round_evaluations / 4, n + 1, 16LL * n);
        search.design_points = request.design_points > 0 ? request.design_points : static_cast<int>(default_design);
        search.threads = threads;
        search.method = request.search;
        if ((evaluate_start || round > 0) && std::isfinite(round_start_evaluation.total)) {
            search.cmaes_known_unit = problem->space().to_unit(problem->values_of(round_start));
            search.cmaes_known_value = round_start_evaluation.total;
        }
        if (request.shard) {
            search.shard_index = request.shard->index;
            search.shard_count = request.shard->count;
        }
        optim::AnnealingSettings& annealing = search.annealing;
        // Each round searches with a seed of its own (the first, the request's).
        annealing.seed = request.seed + 0x9e3779b97f4a7c15ULL * static_cast<std::uint64_t>(round);
        annealing.max_evaluations = round_evaluations;
        annealing.fit_schedule_to_budget = true;
        annealing.evaluations_per_stage =
            static_cast<int>(std::max<long long>(n + 1, (round_evaluations - search.design_points) / 16));
        annealing.cancel = &cancelled;
        if (budget > 0.0) {
            const double round_seconds = search_end_s - seconds_since(started);
            // A third of the round's search time at most for the design, the rest for the search.
            search.design_budget_seconds = std::max(1.0, main_share * budget * share / 3.0);
            // minimize measures the design, then plans the search for what is left.
            search.total_budget_seconds = std::max(2.0, round_seconds);
        }
        const double progress_span = main_share * share;
        annealing.progress = [&](const ProgressReport& p) {
            return report({round > 0 ? "refining" : "annealing", progress_begin + progress_span * p.fraction,
                           outcome.evaluations, 0.0, p.message});
        };
        if (round == 0) report({"design", 0.02, 0, 0.0});
        if (request.cancel && request.cancel->load()) cancelled = true;
        // The annealer polls `cancelled`; an external cancel is forwarded by the progress callback.
        outcome.search = optim::minimize(problem->objective(), problem->space(), search);
        outcome.polish.reset();
        outcome.evaluations += outcome.search.evaluations;
        if (outcome.search.annealing.status == optim::AnnealingResult::Status::cancelled || stop_requested()) {
            return cancelled_outcome();
        }
        if (request.shard) {
            // A shard ends with its search: the merge evaluates the winner.
            if (evaluate_start) outcome.evaluations += 1;
            outcome.fitted = problem->material(outcome.search.annealing.best_values);
            outcome.simulations = outcome.evaluations * static_cast<long long>(problem->trials().size());
            outcome.seconds = seconds_since(started);
            outcome.rounds.push_back({outcome.fitted, round_start_evaluation.total, outcome.search.annealing.best_value,
                                      outcome.evaluations, outcome.seconds});
            report({"final", 1.0, outcome.evaluations, outcome.search.annealing.best_value});
            return outcome;
        }

        // Under a budget (which already keeps the final evaluation's time), the
        // polish checks the clock before each iteration (a Jacobian, n + 1
        // evaluations, and a few steps): it may start one only while a whole
        // iteration still fits, at the pace the search measured, or it would
        // overrun its share (the next round's, or the restarts').
        double polish_budget_seconds = 0.0;
        if (budget > 0.0) {
            const double pace = search_pace();
            const double left = round_end_s - seconds_since(started);
            polish_budget_seconds = left - static_cast<double>(n + 4) * pace;
        }
        if (polishes && (budget <= 0.0 || polish_budget_seconds > 0.0)) {
            optim::LeastSquaresSettings polish;
            polish.max_evaluations = polish_evaluations;
            polish.threads = threads;
            polish.cancel = &cancelled;
            if (budget > 0.0) polish.budget_seconds = polish_budget_seconds;
            const double polish_progress = progress_begin + progress_span;
            polish.progress = [&](const ProgressReport& p) {
                return report({"polish", polish_progress, outcome.evaluations, 0.0, p.message});
            };
            const optim::ResidualFunction residuals = [problem](const Eigen::VectorXd& values, int residual_threads) {
                return problem->residuals(problem->material(values), residual_threads);
            };
            outcome.polish = optim::levenberg_marquardt(residuals, problem->space(), outcome.search.annealing.best_values, polish);
            outcome.evaluations += outcome.polish->evaluations;
            if (stop_requested()) {
                return cancelled_outcome();
            }
            if (outcome.polish->best_value < outcome.search.annealing.best_value) {
                outcome.search.annealing.best_value = outcome.polish->best_value;
                outcome.search.annealing.best_values = outcome.polish->best_values;
                outcome.search.annealing.best_unit = outcome.polish->best_unit;
            }
        }
        outcome.rounds.push_back({problem->material(outcome.search.annealing.best_values), round_start_evaluation.total,
                                  outcome.search.annealing.best_value, outcome.evaluations - evaluations_before,
                                  seconds_since(round_began)});
        share_done += share;
    }

    // Re-plan the restarts at the pace the search just measured: when the
    // machine got busier than at the start, keep fewer (or none) rather than
    // overrun. The final evaluation and the caller's work after the fit keep
    // their share at that pace too.
    double restart_hint = single_thread_evaluation_seconds;
    double restart_budget = 0.0;
    if (budget > 0.0) {
        const double latest = std::max(evaluation_seconds, search_pace());
        restart_hint = std::max(restart_hint, latest * static_cast<double>(std::min<std::size_t>(threads, problem->trials().size())));
        const double left = request.budget_seconds - seconds_since(started) - after_fit_seconds(latest);
        variability_runs = affordable_runs(variability_runs, restart_hint, left);
        outcome.variability_runs_planned = variability_runs;
        restart_budget = std::max(1.0, left) / std::max(1.0, restart_rounds(variability_runs));
    }
    if (!end_fit(request, *problem, threads, variability_runs, restart_budget, restart_hint, main_share,
                 cancelled, stop_requested, report, outcome.search.annealing.best_values, outcome)) {
        return cancelled_outcome();
    }
    outcome.evaluations += 2;  // start and final evaluations
    outcome.simulations = outcome.evaluations * static_cast<long long>(problem->trials().size());
    report({"floors", 0.995, outcome.evaluations, outcome.final_evaluation.total});
    report_floors(request, threads, outcome);
    outcome.seconds = seconds_since(started);
    report({"final", 1.0, outcome.evaluations, outcome.final_evaluation.total});
    return outcome;
}

ClothFitOutcome finish_cloth_fit(const ClothFitRequest& request, const std::vector<std::string>& names,
                                 const Eigen::VectorXd& values, double error) {
    if (request.captures.empty()) throw std::invalid_argument("finish_cloth_fit: no captures");
    const Clock::time_point started = Clock::now();
    ClothFitOutcome outcome;
    FitControl control(request);
    std::atomic<bool>& cancelled = control.cancelled;
    const std::function<bool()>& stop_requested = control.stop_requested;
    const Reporter& report = control.report;
    report({"loading", 0.0, 0, 0.0});

    // The same problem fit_cloth builds for these captures and settings.
    std::vector<ClothTrial> trials = load_fit_trials(request, outcome);
    std::string expected, given;
    for (const FittedParameter& p : outcome.parameters) expected += (expected.empty() ? "" : ", ") + p.key;
    for (const std::string& name : names) given += (given.empty() ? "" : ", ") + name;
    if (expected != given || values.size() != static_cast<Eigen::Index>(names.size()))
        throw std::invalid_argument("the best point gives " + (given.empty() ? std::string("no parameters") : given) +
                                    " but these captures fit " + expected);
    const ClothFitProblem problem = make_problem(request, std::move(trials), outcome);
    const int threads = fit_threads(request);

    outcome.search.annealing.best_values = values;
    outcome.search.annealing.best_unit = problem.space().to_unit(values);
    outcome.search.annealing.best_value = error;
    const int runs = std::max(0, request.variability_runs);
    outcome.variability_runs_planned = runs;
    if (!end_fit(request, problem, threads, runs, 0.0, 0.0, runs > 0 ? 0.8 : 1.0, cancelled, stop_requested, report, values,
                 outcome)) {
        outcome.status = ClothFitOutcome::Status::cancelled;
        outcome.seconds = seconds_since(started);
        return outcome;
    }
    outcome.evaluations += 1;  // the final evaluation
    outcome.simulations = outcome.evaluations * static_cast<long long>(problem.trials().size());
    report({"floors", 0.995, outcome.evaluations, outcome.final_evaluation.total});
    report_floors(request, threads, outcome);
    outcome.seconds = seconds_since(started);
    report({"final", 1.0, outcome.evaluations, outcome.final_evaluation.total});
    return outcome;
}

}  // namespace flowvid::cloth_fit
