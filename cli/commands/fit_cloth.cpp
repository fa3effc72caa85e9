// flowvid fit cloth: fabric parameters from footage of swatch experiments
// (static drapes and waving tests, fitted jointly), saved as a fabric preset.

#include "commands/cloth_options.hpp"
#include "commands/fit.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/video/cloth_eval.hpp"
#include "flowvid/video/fit_cloth.hpp"

#include <filesystem>
#include <cmath>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct FitClothOptions {
    std::vector<std::string> captures;
    std::string out;
    std::string name;
    std::string drag = "nonlinear";
    std::string metric = "xor";
    std::uint64_t seed = 1;
    long long evaluations = 400;
    int variability_runs = 4;
    long long variability_evaluations = 40;
    double budget_seconds = 0.0;
    int frames = 50;
    int full_weight_frames = 10;
    double half_life_frames = 10.0;
    ClothRunOptions run;
    bool json = false;
};

nlohmann::json material_summary(const cloth::ClothMaterial& material, const std::vector<video::FittedParameter>& parameters,
                                const optim::VariabilityReport* variability) {
    nlohmann::json out = nlohmann::json::object();
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        nlohmann::json entry = {{"value", video::material_parameter(material, parameters[i].key)}};
        if (variability && i < variability->parameters.size()) {
            entry["uncertainty"] = variability->parameters[i].stddev;
            entry["variability_percent"] = variability->parameters[i].variability_percent;
        }
        out[parameters[i].key] = entry;
    }
    return out;
}

int run_fit_cloth(const FitClothOptions& options, const GlobalOptions& global) {
    std::optional<cloth::SwatchOptions> swatch = swatch_options(options.run);
    if (!swatch) return kExitUsage;
    if (options.drag == "linear" && !options.out.empty() && !global.quiet)
        log_message("note: a linear-drag fit has no fabric preset form; --out gets the fit summary (JSON) instead");
    video::ClothFitRequest request;
    for (const std::string& path : options.captures)
        request.captures.push_back(read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid fit cloth"));
    prepare_output_folder(options.out);
    request.name = options.name.empty() ? std::filesystem::path(options.out).stem().stem().string() : options.name;
    request.load.waving_frames = options.frames;
    request.load.full_weight_frames = options.full_weight_frames;
    request.load.half_life_frames = options.half_life_frames;
    request.problem.swatch = *swatch;
    request.problem.metric.silhouette_term =
        options.metric == "edge" ? metrics::SilhouetteTerm::edge_distance : metrics::SilhouetteTerm::pixel_xor;
    request.load.silhouette_term = request.problem.metric.silhouette_term;
    request.drag = options.drag == "linear" ? video::DragModel::linear : video::DragModel::nonlinear;
    request.evaluations = options.evaluations;
    request.variability_runs = options.variability_runs;
    request.variability_evaluations = options.variability_evaluations;
    request.budget_seconds = options.budget_seconds;
    request.seed = options.seed;
    request.threads = thread_count(options.run.threads);

    Progress progress(global, "fit cloth");
    const InterruptWatch interrupt;
    request.progress = [&](const video::ClothFitProgress& p) {
        char detail[160];
        std::snprintf(detail, sizeof detail, "%s, %lld evaluations, best %.4g, T %.3g, ETA %.0f s", p.phase.c_str(),
                      p.evaluations, p.best_error, p.temperature, p.eta_s);
        progress.update(p.fraction, detail);
        return !interrupt.requested();
    };
    const video::ClothFitOutcome outcome = video::fit_cloth(request);
    progress.done();
    if (outcome.status == video::ClothFitOutcome::Status::cancelled) {
        log_message("interrupted: nothing written");
        return kExitInterrupted;
    }

    const optim::VariabilityReport* variability = outcome.variability ? &*outcome.variability : nullptr;
    // Each trial's error next to its predictability floor (a small ensemble
    // at the fitted fabric): an error near the floor is as good as it gets.
    nlohmann::json trials = nlohmann::json::array();
    video::FloorSettings floor;
    floor.members = 4;
    const std::vector<video::ClothTrial>& loaded = outcome.trials;
    video::ClothFitSettings floor_settings = request.problem;
    double total_floor = 0.0;
    for (std::size_t i = 0; i < outcome.final_evaluation.trials.size(); ++i) {
        const video::PredictabilityFloor f =
            video::estimate_floor(loaded[i], outcome.fitted, floor_settings, floor, request.threads);
        const double trial_floor = video::weighted_floor(loaded[i], f);
        total_floor += trial_floor;
        trials.push_back({{"capture", outcome.trial_names[i]},
                          {"start_error", outcome.start_evaluation.trials[i].error},
                          {"final_error", outcome.final_evaluation.trials[i].error},
                          {"floor", trial_floor}});
    }
    nlohmann::json summary = {{"out", options.out},
                              {"drag", video::drag_model_name(request.drag)},
                              {"parameters", material_summary(outcome.fitted, outcome.parameters, variability)},
                              {"start_error", outcome.start_evaluation.total},
                              {"final_error", outcome.final_evaluation.total},
                              {"final_error_floor", total_floor},
                              {"trials", trials},
                              {"evaluations", outcome.evaluations},
                              {"simulations", outcome.simulations},
                              {"seconds", outcome.seconds},
                              {"annealing_status", optim::status_name(outcome.search.annealing.status)}};
    if (outcome.preset) formats::write_fabric_preset(options.out, *outcome.preset);
    else formats::write_file_atomically(options.out, [&](std::ostream& out) { out << summary.dump(2) << '\n'; });
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterFitKind registration{FitKind{
    "cloth", "fabric parameters from static drape and waving captures, saved as a fabric preset",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<FitClothOptions>();
        app.footer(
            "Simulates the capture's swatch experiments with candidate fabrics, renders each frame\n"
            "through the capture's camera under its stripe projector, and compares angle maps and\n"
            "silhouettes with the footage (thesis eq. 2.20-2.24). Several captures are fitted jointly:\n"
            "give the static drape(s) and the waving test(s) of one fabric. Static drapes alone fit the\n"
            "6 stiffness and damping parameters; with a waving test the 3 drag parameters too (9).\n"
            "The search is a Halton design, then simulated annealing from its best point, then a\n"
            "variability analysis (restarts from +-5 % perturbed starts) whose spread becomes the\n"
            "preset's uncertainty. Waving cloth is chaotic: frames after --full-weight-frames count\n"
            "less (halving every --half-life-frames), so the fit does not chase unpredictable folds.\n"
            "Never reads truth/. Same seed and options give the same preset whatever --threads, unless\n"
            "--budget-seconds stops the search early. See docs/cloth_fitting.md.\n\n"
            "Examples:\n"
            "  flowvid fit cloth --capture ../shared/captures/cloth-cotton-static-1 \\\n"
            "                    --capture ../shared/captures/cloth-cotton-waving-1 --out cotton.fabric.json\n"
            "  flowvid fit cloth --capture drape/ --capture wave1/ --capture wave2/ --out silk.fabric.json \\\n"
            "                    --budget-seconds 600 --seed 7\n\n"
            "Exit codes: 0 ok, 2 bad option, 3 invalid capture (each problem names its file and field),\n"
            "4 unreadable or unwritable file, 130 interrupted (nothing written).");
        app.add_option("--capture", options->captures, "cloth capture folder (repeat: static and waving tests of one fabric)")
            ->required();
        app.add_option("--out", options->out, "fabric preset to write (*.fabric.json)")->required();
        app.add_option("--name", options->name, "fabric name in the preset (default: from --out)");
        app.add_option("--seed", options->seed, "random seed (design scrambling, annealing)")->capture_default_str();
        app.add_option("--evaluations", options->evaluations,
                       "simulations of the trial set in the main search (design + annealing)")
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
        app.add_option("--frames", options->frames, "waving frames compared (from the first)")
            ->check(CLI::Range(2, 100000))
            ->capture_default_str();
        app.add_option("--full-weight-frames", options->full_weight_frames, "waving frames that count fully")
            ->check(CLI::Range(1, 100000))
            ->capture_default_str();
        app.add_option("--half-life-frames", options->half_life_frames,
                       "later frames' weight halves every this many frames (0 = every frame counts fully)")
            ->check(CLI::NonNegativeNumber)
            ->capture_default_str();
        app.add_option("--metric", options->metric, "silhouette term: xor (pixel count) or edge (edge distance, eq. 2.6)")
            ->check(CLI::IsMember({"xor", "edge"}))
            ->capture_default_str();
        app.add_option("--drag", options->drag, "nonlinear (thesis) or linear (comparison; writes a summary, not a preset)")
            ->check(CLI::IsMember({"nonlinear", "linear"}))
            ->capture_default_str();
        add_cloth_run_options(app, options->run);
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_fit_cloth(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
