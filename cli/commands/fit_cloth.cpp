// flowvid fit cloth: fabric parameters from footage of swatch experiments
// (static drapes and waving tests, fitted jointly), saved as a fabric preset.

#include "commands/cloth_options.hpp"
#include "commands/fit.hpp"
#include "commands/merge.hpp"
#include "frame_options.hpp"
#include "output.hpp"
#include "report_html.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fit_shard.hpp"
#include "flowvid/version.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"
#include "flowvid/cloth_fit/fit_cloth_shards.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <initializer_list>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>

namespace flowvid::cli {
namespace {

void apply_source_date_epoch(formats::FabricPreset& preset);

// Members of the floor ensemble reported beside each trial's error.
constexpr int kFloorMembers = 4;

struct FitClothOptions {
    std::vector<std::string> captures;
    std::string out;
    std::string name;
    std::string drag = "nonlinear";
    std::string metric = "xor";
    // The default compares the swatch's shape the footage's stripes measure:
    // it reaches the model's capacity where the angle maps did not
    // (docs/cloth_fitting.md, "Fitting to the scan").
    std::string fit_to = cloth_fit::fit_target_name(cloth_fit::kDefaultFitTarget);  // scan, footage or tracks
    std::string search = "cmaes";         // or "annealing" (the thesis's)
    std::uint64_t seed = 1;
    long long evaluations = 400;
    int variability_runs = 4;
    long long variability_evaluations = 40;
    double budget_seconds = 0.0;
    // Footage fits compare 50 waving frames whose weight halves every 10
    // after the first 10; tracks fits 20 frames halving every 5 (the
    // capacity study's held-out trials: docs/cloth_model.md). Unless given.
    FrameOptions frame_selection;  // --frames / --frame-count as given
    int frames = 50;               // resolved
    int full_weight_frames = 10;
    double half_life_frames = 10.0;
    double static_weight = 1.0;  // each static drape against one full-weight waving frame, when given
    bool static_weight_given = false;  // else cloth_fit::default_static_weight
    double min_bending_N_m = 0.0;  // a floor on the fitted bending (0: its range)
    std::string second_drape_mesh = "none";  // RxC: each drape is also fitted on this mesh
    std::vector<std::string> hold;  // parameters left out of the fit
    double shear_cells = 0.0;         // the share of the shear read on the grid's cells, when given
    bool shear_cells_given = false;   // else the start's, else cloth_fit::default_shear_cell_fraction
    std::string start;             // a preset to refine (empty: the middle of the ranges)
    int refine_rounds = 0;         // searches again after the first, from its fabric
    ClothRunOptions run;
    bool json = false;
    // Farm and cluster splitting (docs/farm.md).
    std::string shard;                    // "i/n": run only shard i of n and write its partial result to --out
    int shards = 0;                       // n > 0: run all n shards here, then merge them (as `flowvid merge`)
    bool variability_runs_given = false;  // --shards: restarts in the merge only when asked for
};

nlohmann::json material_summary(const cloth::ClothMaterial& material, const std::vector<cloth_fit::FittedParameter>& parameters,
                                const optim::VariabilityReport* variability) {
    nlohmann::json out = nlohmann::json::object();
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        nlohmann::json entry = {{"value", cloth_fit::material_parameter(material, parameters[i].key)}};
        if (variability && i < variability->parameters.size()) {
            entry["uncertainty"] = variability->parameters[i].stddev;
            entry["variability_percent"] = variability->parameters[i].variability_percent;
        }
        out[parameters[i].key] = entry;
    }
    return out;
}

// The fit's request from the options (every path: whole, shard, merge).
cloth_fit::ClothFitRequest make_request(const FitClothOptions& options, const cloth::SwatchOptions& swatch,
                                    std::vector<formats::Capture> captures, const std::string& out) {
    cloth_fit::ClothFitRequest request;
    request.captures = std::move(captures);
    request.name = options.name.empty() ? std::filesystem::path(out).stem().stem().string() : options.name;
    request.load.target = cloth_fit::fit_target_from_name(options.fit_to).value_or(cloth_fit::kDefaultFitTarget);
    request.load.waving_frames = options.frames;
    request.load.full_weight_frames = options.full_weight_frames;
    request.load.half_life_frames = options.half_life_frames;
    request.load.static_weight =
        options.static_weight_given ? options.static_weight : cloth_fit::default_static_weight(request.load, request.captures);
    request.min_bending_N_m = options.min_bending_N_m;
    request.held_parameters = options.hold;
    if (options.shear_cells_given) request.shear_cell_fraction = options.shear_cells;
    request.problem.swatch = swatch;
    if (options.second_drape_mesh != "none")
        if (const auto mesh = cloth::mesh_size_from_text(options.second_drape_mesh)) {  // checked by the option
            request.problem.second_drape_rows = mesh->first;
            request.problem.second_drape_cols = mesh->second;
        }
    request.problem.metric.silhouette_term =
        options.metric == "edge" ? video::SilhouetteTerm::edge_distance : video::SilhouetteTerm::pixel_xor;
    request.load.silhouette_term = request.problem.metric.silhouette_term;
    request.drag = options.drag == "linear" ? cloth_fit::DragModel::linear : cloth_fit::DragModel::nonlinear;
    request.evaluations = options.evaluations;
    request.refine_rounds = options.refine_rounds;
    request.search = optim::search_method_from_name(options.search).value_or(optim::SearchMethod::cmaes);
    request.variability_runs = options.variability_runs;
    request.variability_evaluations = options.variability_evaluations;
    request.budget_seconds = options.budget_seconds;
    request.seed = options.seed;
    request.threads = thread_count(options.run.threads);
    request.floor_members = kFloorMembers;
    return request;
}

int run_shards(const FitClothOptions& options, const GlobalOptions& global, cloth_fit::ClothFitRequest request);

// How the reported floor's runs are integrated (cloth_fit::reported_floor).
std::string reported_floor_integrator() {
    return std::string(cloth::integrator_name(cloth::Integrator::implicit_euler)) + ", " +
           std::to_string(cloth_fit::kFloorSubstepsPerFrame) + " substeps a frame";
}

// A fitted preset reproduces the drape of the mesh it was fitted on. Where
// that mesh is coarser than the fitted fabric's folds (fitting_swatch_folds),
// a finer mesh drapes differently: the summary says so, and a note.
void report_fitted_mesh_folds(const formats::FabricPreset& preset, nlohmann::json& summary) {
    const std::optional<cloth::FoldCheck> folds = fitting_swatch_folds(preset);
    if (!folds) return;
    summary["fold_length_mm"] = 1e3 * folds->fold_length_m;
    summary["fitted_mesh_edge_mm"] = 1e3 * folds->edge_m;
    summary["fitted_mesh_holds_folds"] = folds->holds_folds;
    if (!folds->holds_folds)
        log_message("note: the fitted fabric folds at about " + html::format_number(1e3 * folds->fold_length_m, 2) +
                    " mm (its elastogravity length), finer than the " + html::format_number(1e3 * folds->edge_m, 3) +
                    " mm edges of the mesh it was fitted on: the preset reproduces the footage's drape on meshes with "
                    "edges near that, and a finer mesh drapes differently (flowvid info --mesh-edge-mm E PRESET "
                    "checks a mesh)");
}

// Each trial's final error next to its predictability floor (the fit's
// ClothFitRequest::floor_members): an error near the floor is as good as it gets.
nlohmann::json trials_with_floors(const cloth_fit::ClothFitOutcome& outcome) {
    nlohmann::json trials = nlohmann::json::array();
    for (std::size_t i = 0; i < outcome.final_evaluation.trials.size(); ++i) {
        nlohmann::json trial = {{"capture", outcome.trial_names[i]}, {"final_error", outcome.final_evaluation.trials[i].error}};
        const bool shape = outcome.trials[i].measures_shape();
        if (shape)
            // A tracks or scan fit's error is a weighted mean square (mm^2): its root reads as a distance.
            trial["final_rms_mm"] = cloth_fit::tracks_rms_mm(outcome.trials[i], outcome.final_evaluation.trials[i].error);
        const cloth_fit::ReportedFloor& floor = outcome.floors.at(i);
        if (floor.weighted) {
            trial["floor"] = *floor.weighted;
            if (shape) trial["floor_rms_mm"] = cloth_fit::tracks_rms_mm(outcome.trials[i], *floor.weighted);
        } else {
            log_message("warning: no predictability floor for " + outcome.trial_names[i] + ": " + floor.failure);
            trial["floor"] = nullptr;
        }
        trials.push_back(trial);
    }
    return trials;
}

int run_fit_cloth(const FitClothOptions& options, const GlobalOptions& global) {
    const auto command_started = std::chrono::steady_clock::now();
    const auto seconds_since = [](std::chrono::steady_clock::time_point t) {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    };
    std::optional<cloth::SwatchOptions> swatch = swatch_options(options.run);
    if (!swatch) return kExitUsage;
    const bool sharded = !options.shard.empty() || options.shards > 0;
    std::vector<formats::Capture> captures;
    for (const std::string& path : options.captures)
        captures.push_back(formats::read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid fit cloth"));
    formats::create_parent_folder(options.out);
    cloth_fit::ClothFitRequest request = make_request(options, *swatch, std::move(captures), options.out);
    // Say what the fit compares: the default changed (the scan), and the errors' units follow it.
    const bool any_waving = std::any_of(request.captures.begin(), request.captures.end(),
                                        [](const formats::Capture& c) { return c.kind == "cloth.waving"; });
    switch (request.load.target) {
        case cloth_fit::FitTarget::scan:
            log_message("comparing with the swatch's shape the footage's stripes measure (RMS depth error, mm" +
                        (any_waving ? "; " + std::to_string(request.load.waving_frames) + " waving frames" : std::string()) +
                        "); --fit-to footage compares the thesis's angle maps");
            break;
        case cloth_fit::FitTarget::footage:
            log_message("comparing the footage's angle maps and silhouettes (the thesis's metric)");
            break;
        case cloth_fit::FitTarget::tracks: log_message("comparing the captures' measured 3D points (RMS distance, mm)"); break;
    }
    if (request.load.static_weight != 1.0) {
        char weight[160];
        std::snprintf(weight, sizeof weight, "each drape weighs %.3g waving frames%s", request.load.static_weight,
                      options.static_weight_given ? "" : ", as much as a waving test (--static-weight to change)");
        log_message(weight);
    }
    if (request.problem.has_second_drape_mesh())
        log_message("each drape is also simulated on a " + options.second_drape_mesh +
                    " mesh and compared with the same measurements (--second-drape-mesh)");
    if (!options.start.empty()) request.start = cloth::material_from_fabric(formats::read_fabric_preset(options.start).parameters);
    if (sharded) return run_shards(options, global, std::move(request));
    ProgressBar progress(global, "fit cloth");
    const InterruptWatch interrupt;
    request.progress = [&](const ProgressReport& p) {
        progress.update(p.fraction, p.stage + ", " + p.message);
        return !interrupt.requested();
    };
    const cloth_fit::ClothFitOutcome outcome = cloth_fit::fit_cloth(request);
    progress.done();
    if (outcome.status == cloth_fit::ClothFitOutcome::Status::cancelled) {
        log_message("interrupted: nothing written");
        return kExitInterrupted;
    }

    if (outcome.variability_runs_planned < request.variability_runs)
        log_message("the time budget paid for " + std::to_string(outcome.variability_runs_planned) + " of " +
                    std::to_string(request.variability_runs) + " variability restarts" +
                    (outcome.variability_runs_planned == 0 ? ": the preset has no uncertainty (raise --budget-seconds)" : ""));
    const optim::VariabilityReport* variability = outcome.variability ? &*outcome.variability : nullptr;
    nlohmann::json trials = trials_with_floors(outcome);
    for (std::size_t i = 0; i < trials.size(); ++i) trials[i]["start_error"] = outcome.start_evaluation.trials[i].error;
    nlohmann::json summary = {{"out", options.out},
                              {"fit_to", cloth_fit::fit_target_name(request.load.target)},
                              {"waving_frames", request.load.waving_frames},
                              {"half_life_frames", request.load.half_life_frames},
                              {"static_weight", request.load.static_weight},
                              {"min_bending_N_m", request.min_bending_N_m},
                              {"second_drape_mesh", options.second_drape_mesh},
                              {"held_parameters", request.held_parameters},
                              {"shear_cell_fraction", cloth_fit::resolved_shear_cell_fraction(request)},
                              {"start", options.start.empty() ? nlohmann::json("middle of the ranges") : nlohmann::json(options.start)},
                              {"search", optim::search_method_name(request.search)},
                              {"drag", cloth_fit::drag_model_name(request.drag)},
                              {"parameters", material_summary(outcome.fitted, outcome.parameters, variability)},
                              {"start_error", outcome.start_evaluation.total},
                              {"final_error", outcome.final_evaluation.total},
                              {"final_error_floor", outcome.total_floor},
                              {"floor_integrator", reported_floor_integrator()},
                              {"trials", trials},
                              {"evaluations", outcome.evaluations},
                              {"simulations", outcome.simulations},
                              {"variability_runs", outcome.variability_runs_planned},
                              {"seconds", outcome.seconds},
                              {"total_seconds", seconds_since(command_started)},
                              {"search_status", optim::status_name(outcome.search.annealing.status)}};
    // Each round's errors are on its own fold states: a refinement round's
    // start is the previous round's best, scored again.
    nlohmann::json rounds = nlohmann::json::array();
    for (const cloth_fit::ClothFitRound& r : outcome.rounds)
        rounds.push_back({{"start_error", r.start_error}, {"best_error", r.best_error}, {"evaluations", r.evaluations},
                          {"seconds", r.seconds}});
    summary["rounds"] = rounds;
    if (outcome.preset) {
        formats::FabricPreset preset = *outcome.preset;
        apply_source_date_epoch(preset);
        formats::write_fabric_preset(options.out, preset);
        report_fitted_mesh_folds(preset, summary);
    } else formats::write_file_atomically(options.out, [&](std::ostream& out) { out << summary.dump(2) << '\n'; });
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

// ---- Farm and cluster splitting: --shard i/n, --shards n, and the cloth merge.

// "i/n" with 1 <= i <= n <= 10000; nullopt (logged) otherwise.
std::optional<cloth_fit::ClothFitShard> parse_shard(const std::string& text) {
    int index = 0, count = 0;
    char slash = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &index, &slash, &count, &extra) == 3 && slash == '/' && index >= 1 &&
        count >= 1 && index <= count && count <= 10000)
        return cloth_fit::ClothFitShard{index, count};
    log_message("error: --shard " + text + ": expected i/n with 1 <= i <= n, e.g. 2/8 (the second of 8 shards)");
    return std::nullopt;
}

// The reproducible-builds convention: SOURCE_DATE_EPOCH (seconds since
// 1970, UTC) replaces the preset's creation time, so that a fit run twice,
// or split and merged, gives the same bytes.
void apply_source_date_epoch(formats::FabricPreset& preset) {
    const char* text = std::getenv("SOURCE_DATE_EPOCH");
    if (!text || !*text) return;
    char* end = nullptr;
    const long long seconds = std::strtoll(text, &end, 10);
    if (*end != '\0' || seconds < 0) {
        log_message(std::string("warning: SOURCE_DATE_EPOCH=") + text + " is not whole seconds since 1970; the preset gets the current time");
        return;
    }
    const std::time_t t = static_cast<std::time_t>(seconds);
    std::tm utc{};
    gmtime_r(&t, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &utc);
    preset.provenance.created_utc = stamp;
}

// The last step of a split cloth fit (cloth_fit::merge_cloth_fit_shards), written
// exactly as fit cloth writes. Used by `flowvid merge` and by `fit cloth --shards n`.
int merge_cloth(const MergeRequest& merge, const GlobalOptions& global) {
    cloth_fit::ClothMergeRequest request;
    request.shards = merge.shards;
    request.name = merge.name.empty() ? std::filesystem::path(merge.out).stem().stem().string() : merge.name;
    request.variability_runs = merge.variability_runs;
    request.variability_evaluations = merge.variability_evaluations;
    request.floor_members = kFloorMembers;
    request.threads = merge.threads;
    ProgressBar progress(global, "merge cloth");
    const InterruptWatch interrupt;
    request.progress = [&](const ProgressReport& p) {
        progress.update(p.fraction, p.stage);
        return !interrupt.requested();
    };
    const cloth_fit::ClothMergeOutcome merged = cloth_fit::merge_cloth_fit_shards(request);
    const cloth_fit::ClothFitOutcome& outcome = merged.fit;
    progress.done();
    if (outcome.status == cloth_fit::ClothFitOutcome::Status::cancelled) {
        log_message("interrupted: nothing written");
        return kExitInterrupted;
    }
    const formats::FitShardFile& winner = merge.shards.at(merged.winner);
    const optim::VariabilityReport* variability = outcome.variability ? &*outcome.variability : nullptr;
    const std::string split = std::to_string(winner.shard.index) + "/" + std::to_string(winner.shard.count);
    nlohmann::json summary = {{"out", merge.out},
                              {"drag", winner.shard.options.value("drag", "nonlinear")},
                              {"parameters", material_summary(outcome.fitted, outcome.parameters, variability)},
                              {"winner", {{"shard", split}, {"file", winner.path}, {"error", winner.shard.best_error}}},
                              {"shard_errors", merged.shard_errors},
                              {"final_error", outcome.final_evaluation.total},
                              {"final_error_floor", outcome.total_floor},
                              {"floor_integrator", reported_floor_integrator()},
                              {"trials", trials_with_floors(outcome)},
                              {"evaluations", merged.evaluations},
                              {"variability_runs", outcome.variability_runs_planned},
                              {"seconds", outcome.seconds}};
    if (outcome.preset) {
        formats::FabricPreset preset = *outcome.preset;
        apply_source_date_epoch(preset);
        formats::write_fabric_preset(merge.out, preset);
        report_fitted_mesh_folds(preset, summary);
    } else {
        formats::write_file_atomically(merge.out, [&](std::ostream& out) { out << summary.dump(2) << '\n'; });
    }
    if (merge.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterMergeKind merge_registration{MergeKind{"cloth", merge_cloth}};

// --shard i/n: one shard, its partial result to --out. --shards n: every
// shard here, one after the other (each with every thread; the result does
// not depend on the order or the threads), then the same merge as
// `flowvid merge`.
int run_shards(const FitClothOptions& options, const GlobalOptions& global, cloth_fit::ClothFitRequest request) {
    std::vector<cloth_fit::ClothFitShard> todo;
    if (!options.shard.empty()) {
        const std::optional<cloth_fit::ClothFitShard> shard = parse_shard(options.shard);
        if (!shard) return kExitUsage;
        todo.push_back(*shard);
    } else {
        for (int i = 1; i <= options.shards; ++i) todo.push_back({i, options.shards});
    }
    std::vector<formats::FitShardFile> results;
    {
        const InterruptWatch interrupt;
        for (const cloth_fit::ClothFitShard& shard : todo) {
            const std::string split = std::to_string(shard.index) + "/" + std::to_string(shard.count);
            ProgressBar progress(global, "fit cloth shard " + split);
            request.shard = shard;
            request.progress = [&](const ProgressReport& p) {
                progress.update(p.fraction, p.stage + ", " + p.message);
                return !interrupt.requested();
            };
            cloth_fit::ClothFitOutcome outcome;
            try {
                outcome = cloth_fit::fit_cloth(request);
            } catch (const std::invalid_argument& error) {
                log_message("error: --shard " + split + ": " + error.what() +
                            " (use fewer shards, or more --evaluations: the design has about a quarter of them)");
                return kExitUsage;
            }
            progress.done();
            if (outcome.status == cloth_fit::ClothFitOutcome::Status::cancelled) {
                log_message("interrupted: nothing written");
                return kExitInterrupted;
            }
            results.push_back({"shard " + split + " (this run)", cloth_fit::cloth_fit_shard(request, outcome)});
            if (!global.quiet && options.shards > 0)
                log_message("shard " + split + ": error " + std::to_string(outcome.search.annealing.best_value) + " after " +
                            std::to_string(outcome.evaluations) + " evaluations");
            if (!options.shard.empty()) {
                formats::write_fit_shard(options.out, results.back().shard);
                nlohmann::json summary = formats::summarize_fit_shard(results.back().shard);
                summary["out"] = options.out;
                summary["design_points"] = outcome.search.design.points.size();
                summary["seconds"] = outcome.seconds;
                if (options.json) std::cout << summary.dump(2) << '\n';
                else std::cout << human_readable(summary);
                return kExitOk;
            }
        }
    }
    MergeRequest merge;
    merge.shards = std::move(results);
    merge.out = options.out;
    merge.name = options.name;
    merge.variability_runs = options.variability_runs_given ? options.variability_runs : 0;
    merge.variability_evaluations = options.variability_evaluations;
    merge.threads = options.run.threads;
    merge.json = options.json;
    return merge_cloth(merge, global);
}

const RegisterFitKind registration{FitKind{
    "cloth", "fabric parameters from static drape and waving captures, saved as a fabric preset",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<FitClothOptions>();
        app.footer(
            "Simulates the capture's swatch experiments with candidate fabrics, renders each frame\n"
            "through the capture's camera under its stripe projector and compares it with the footage.\n"
            "By default (--fit-to scan) the footage's own stripes are triangulated per pixel into the\n"
            "swatch's shape, and the fit compares depths along the camera rays: an RMS depth error in\n"
            "mm (background pixels near the swatch's outline that the simulation covers count as 3 cm\n"
            "misses: depth alone cannot see cloth that reaches too far sideways). --fit-to footage\n"
            "compares angle maps and silhouettes instead (the thesis's eq. 2.20-2.24; its fabrics miss\n"
            "the captures by more: docs/cloth_fitting.md). --fit-to tracks compares the capture's\n"
            "measured 3D points (capture.json \"tracks\": motion-capture markers, a scanner), also in mm.\n"
            "Several captures are fitted jointly: give the static drape(s) and the waving test(s) of\n"
            "one fabric. Static drapes alone fit the 6 stiffness and damping parameters; with a waving\n"
            "test the 3 drag parameters too (9). Scan and tracks fits add the hem's mass, soft\n"
            "compression per direction, tension-only diagonal fibres and (waving) linear drag: 10 and\n"
            "14 parameters (docs/cloth_model.md).\n"
            "The search is CMA-ES (an evolution strategy that simulates a generation of candidates at\n"
            "once and learns which parameters move together) from the better of the start and a small\n"
            "Halton design (--search annealing: the thesis's design, then simulated annealing), with\n"
            "--refine-rounds a second search from the best fabric, which first picks again the fold\n"
            "state each trial starts in. Last, a\n"
            "variability analysis (restarts from +-5 % perturbed starts) whose spread becomes the\n"
            "preset's uncertainty. Waving cloth is chaotic: frames after --full-weight-frames count\n"
            "less (halving every --half-life-frames), so the fit does not chase unpredictable folds.\n"
            "Never reads truth/. Same seed and options give the same preset whatever --threads, unless\n"
            "--budget-seconds stops the search early. See docs/cloth_fitting.md.\n\n"
            "Farms and clusters (docs/farm.md): --shard i/n runs one of n independent tasks (its share of the\n"
            "design, then one search of its own, no refinement round) and writes a partial result;\n"
            "`flowvid merge` picks the best shard and writes the preset. --shards n does all of it here and writes the same bytes\n"
            "(set SOURCE_DATE_EPOCH to fix created_utc). Deterministic only without --budget-seconds (which\n"
            "then limits each shard).\n\n"
            "Examples:\n"
            "  flowvid fit cloth --capture ../shared/captures/cloth-cotton-static-1 \\\n"
            "                    --capture ../shared/captures/cloth-cotton-waving-1 --out cotton.fabric.json\n"
            "  flowvid fit cloth --capture drape/ --capture wave1/ --capture wave2/ --out silk.fabric.json \\\n"
            "                    --budget-seconds 600 --seed 7\n"
            "  flowvid fit cloth --capture drape/ --capture wave1/ --out shards/3.json --shard 3/8   # task 3 of 8\n"
            "  flowvid merge --out silk.fabric.json shards/*.json\n\n"
            "Exit codes: 0 ok, 2 bad option, 3 invalid capture (each problem names its file and field),\n"
            "4 unreadable or unwritable file, 130 interrupted (nothing written).");
        app.add_option("--capture", options->captures, "cloth capture folder (repeat: static and waving tests of one fabric)")
            ->required();
        app.add_option("--out", options->out, "fabric preset to write (*.fabric.json)")->required();
        app.add_option("--name", options->name, "fabric name in the preset (default: from --out)");
        app.add_option("--seed", options->seed, "random seed (design scrambling, the search)")->capture_default_str();
        app.add_option("--evaluations", options->evaluations,
                       "simulations of the trial set in the main search (design + CMA-ES or annealing)")
            ->check(CLI::Range(10LL, 1000000LL))
            ->capture_default_str();
        app.add_option("--variability-runs", options->variability_runs,
                       "restarts from +-5 % perturbed starts (the preset's uncertainty); 0 = none")
            ->check(CLI::Range(0, 64))
            ->capture_default_str();
        app.add_option("--variability-evaluations", options->variability_evaluations, "evaluations per variability restart")
            ->check(CLI::Range(4LL, 1000000LL))
            ->capture_default_str();
        app.add_option("--budget-seconds", options->budget_seconds, "stop the search after this wall time (0 = no limit)")
            ->check(CLI::NonNegativeNumber)
            ->capture_default_str();
        add_frame_options(app, options->frame_selection,
                          "waving frames A to B compared; A is the wave's first frame (the start is what is predictable)",
                          "the first N waving frames", "the first 20; --fit-to footage: 50");
        app.add_option("--full-weight-frames", options->full_weight_frames, "waving frames that count fully")
            ->check(CLI::Range(1, 100000))
            ->capture_default_str();
        app.add_option("--half-life-frames", options->half_life_frames,
                       "later frames' weight halves every this many frames (0 = every frame counts fully; "
                       "default: 5; --fit-to footage: 10)")
            ->check(CLI::NonNegativeNumber);
        app.add_option("--min-bending", options->min_bending_N_m,
                       "floor on the fitted bending stiffness, N m (0 = its range): the soft bending that reproduces "
                       "folds at the footage's mesh scale drapes differently on other meshes; with 1e-5 the silk captures' "
                       "preset drapes alike on 12x12 to 48x48 meshes, at a cost in accuracy (docs/cloth_model.md)")
            ->check(CLI::Range(0.0, 1e-3))
            ->capture_default_str();
        app.add_option("--second-drape-mesh", options->second_drape_mesh,
                       "RxC: each static drape is also simulated on this second mesh and compared with the same "
                       "footage or measurements, so that the preset drapes alike on both (a fit that sees one mesh can "
                       "choose a nearly stiffless fabric whose drape holds on that mesh only); costs a drape "
                       "simulation per evaluation. With 12x12 the silk captures' tracks-fitted preset drapes 24 mm (max) apart on "
                       "12x12 and 24x24 instead of 40 (cotton's: 22 instead of 19), at a cost in accuracy "
                       "(docs/cloth_model.md)")
            ->check([](const std::string& text) {
                return text == "none" || cloth::mesh_size_from_text(text) ? std::string()
                                                                          : std::string("expected RxC (2..512 each), e.g. 12x12, or none");
            })
            ->capture_default_str();
        app.add_option("--hold", options->hold,
                       "leave this parameter out of the fit (repeat for several): KEY keeps its start value, for a "
                       "capacity term its neutral one; KEY=VALUE holds it at VALUE (the preset's SI unit) -- an "
                       "ablation, e.g. --hold stretch_warp_compression_ratio --hold stretch_weft_compression_ratio "
                       "fits without soft compression, and `flowvid diagnose` then names compression_softness if the "
                       "footage needs it; or a trade, e.g. --hold shear_stiffness_N_per_m=1e-6: with the shear read "
                       "across each triangle gone, the silk captures' tracks-fitted preset drapes its hem equally wide "
                       "on 12x12, 24x24 and 48x48 meshes and 21 mm (max) apart instead of 34, and misses held-out "
                       "frames 1-10 by 6.8 mm instead of 5.0, its drape by 6.6 instead of 4.5; cotton's, which needs its "
                       "shear, loses both ways (docs/cloth_model.md)");
        app.add_option("--shear-cells", options->shear_cells,
                       "share (0 to 1) of the shear read on the swatch grid's cells, at all four corners, where a fold "
                       "along either diagonal is not shear, instead of across each triangle (the preset keeps it: "
                       "shear_cell_fraction). Default: the --start preset's, else 1 for --fit-to tracks and 0 for scan "
                       "and footage. Measured on the tracks of the public captures: silk's held-out drape 0.8 mm "
                       "instead of 4.5, cotton's held-out trial 20.5 mm instead of 22.3-23.5 (docs/cloth_model.md)")
            ->check(CLI::Range(0.0, 1.0));
        app.add_option("--static-weight", options->static_weight,
                       "weight of each static drape against one full-weight waving frame (default 1; a tracks fit "
                       "of drapes and waving tests: as much as a waving test's frames together, about 15 at 20 "
                       "frames, so that each test counts alike)")
            ->check(CLI::NonNegativeNumber);
        app.add_option("--metric", options->metric, "silhouette term: xor (pixel count) or edge (edge distance, eq. 2.6)")
            ->check(CLI::IsMember({"xor", "edge"}))
            ->capture_default_str();
        app.add_option("--fit-to", options->fit_to,
                       "scan: the swatch's shape the frames' projector stripes measure (depth per pixel; 14 parameters "
                       "with a waving test); footage: the frames' angle maps and silhouettes (the thesis's metric, 9 "
                       "parameters); tracks: the captures' measured 3D points")
            ->check(CLI::IsMember({"footage", "scan", "tracks"}))
            ->capture_default_str();
        app.add_option("--search", options->search,
                       "cmaes (an evolution strategy that simulates a generation of candidates on all threads at once "
                       "and learns which parameters move together) or annealing (the thesis's simplex annealing, one "
                       "candidate at a time, after a larger design): cmaes reached the same error in fewer simulations "
                       "on every fit measured (docs/cloth_fitting.md, \"Search\")")
            ->check(CLI::IsMember({"annealing", "cmaes"}))
            ->capture_default_str();
        app.add_option("--drag", options->drag, "nonlinear (thesis: kN, kf, kT) or linear (the comparison model: kL, kT)")
            ->check(CLI::IsMember({"nonlinear", "linear"}))
            ->capture_default_str();
        add_cloth_run_options(app, options->run);
        CLI::Option* shard = app.add_option(
            "--shard", options->shard,
            "i/n: run only shard i of n (a farm or cluster task): design points i-1, i-1+n, ... and one search; "
            "--out gets its partial result (JSON) for `flowvid merge`; no variability restarts");
        CLI::Option* shards =
            app.add_option("--shards", options->shards,
                           "n: run all n shards here, then merge them: the same preset as n --shard runs + `flowvid merge` "
                           "(variability restarts only with an explicit --variability-runs)")
                ->check(CLI::Range(1, 10000));
        shard->excludes(shards);
        // A shard's options travel as JSON to the merge, which may run on
        // another machine without the preset file: refine unsharded.
        CLI::Option* start =
            app.add_option("--start", options->start,
                           "fabric preset to refine: the search begins at its values (clamped into the ranges) instead of "
                           "the middle of the ranges, and its fabric picks the fold state each trial starts in (e.g. to "
                           "go on from a fit with a small budget); not with --shard/--shards")
                ->check(CLI::ExistingFile);
        start->excludes(shard);
        start->excludes(shards);
        CLI::Option* refine_rounds =
            app.add_option("--refine-rounds", options->refine_rounds,
                           "searches after the first (footage and scan fits), each from the best fabric so far, which "
                           "also picks again the fold state each trial starts in (the first round's is picked by the "
                           "start's fabric, which biases the fit). The rounds share --evaluations and --budget-seconds "
                           "(40 % to the refinement). An experiment: measured with 600 s scan fits it helped in the "
                           "bench and hurt in all four fit cloth runs (docs/cloth_fitting.md). Not with --shard/--shards")
                ->check(CLI::Range(0, 8));
        refine_rounds->excludes(shard);
        refine_rounds->excludes(shards);
        app.add_flag("--json", options->json, "print the summary as JSON");
        CLI::Option* variability_runs = app.get_option("--variability-runs");
        CLI::Option* half_life = app.get_option("--half-life-frames");
        CLI::Option* static_weight = app.get_option("--static-weight");
        CLI::Option* shear_cells = app.get_option("--shear-cells");
        return [options, variability_runs, half_life, static_weight, shear_cells](const GlobalOptions& global) {
            options->variability_runs_given = variability_runs->count() > 0;
            options->static_weight_given = static_weight->count() > 0;
            options->shear_cells_given = shear_cells->count() > 0;
            if (const std::optional<int> count = resolve_waving_frame_count(options->frame_selection, options->captures))
                options->frames = *count;
            if (options->frames < 2) throw UsageError("", "", "a fit needs at least 2 waving frames", "give --frame-count 2 or more");
            apply_shape_target_frame_defaults(cloth_fit::fit_target_from_name(options->fit_to).value_or(cloth_fit::kDefaultFitTarget),
                                              options->frame_selection.given(), half_life->count() > 0, options->frames,
                                              options->half_life_frames);
            return run_fit_cloth(*options, global);
        };
    }}};

}  // namespace
}  // namespace flowvid::cli
