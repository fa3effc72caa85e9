// flowvid eval cloth and flowvid recognize: how well fabric presets match
// cloth captures -- the metric error per time window next to the
// predictability floor, the vertex error where a capture has ground truth
// (read for evaluation only), and the cross-error matrix of thesis fig. 2.21.

#include "commands/cloth_options.hpp"
#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"
#include "report_html.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

namespace flowvid::cli {
namespace {

struct TrialOptions {
    FrameOptions frame_selection;  // --frames / --frame-count as given
    int frames = 50;               // waving frames compared, once resolved
    int full_weight_frames = 10;
    double half_life_frames = 10.0;
    std::string metric = "xor";
    std::string compare = cloth_fit::fit_target_name(cloth_fit::kDefaultFitTarget);  // scan or footage (angle maps)
};

void add_trial_options(CLI::App& app, TrialOptions& options) {
    add_frame_options(app, options.frame_selection,
                      "waving frames A to B compared; A is the wave's first frame (the start is what is predictable)",
                      "the first N waving frames", "the first 20; --compare footage: 50");
    app.add_option("--full-weight-frames", options.full_weight_frames, "frames with full weight in the weighted error")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    app.add_option("--half-life-frames", options.half_life_frames,
                   "later frames' weight halves every this many frames (default: 5; --compare footage: 10)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--metric", options.metric, "silhouette term: xor or edge")
        ->check(CLI::IsMember({"xor", "edge"}))
        ->capture_default_str();
    app.add_option("--compare", options.compare,
                   "scan: the swatch's shape the projector's stripes measure (RMS depth error, mm; fit cloth's "
                   "default); footage: angle maps and silhouettes (the thesis's metric; 50 waving frames, half-life "
                   "10 unless given)")
        ->check(CLI::IsMember({"footage", "scan"}))
        ->capture_default_str();
}

cloth_fit::FitTarget compared_target(const TrialOptions& options) {
    return cloth_fit::fit_target_from_name(options.compare).value_or(cloth_fit::kDefaultFitTarget);
}

// The waving frames compared: as given, else the default (--compare scan:
// the scan fits' frame defaults unless --frames or --half-life-frames were given).
void apply_frame_choices(const std::vector<std::string>& captures, const CLI::Option* half_life, TrialOptions& options) {
    if (const std::optional<int> count = resolve_waving_frame_count(options.frame_selection, captures)) options.frames = *count;
    if (options.frames < 2) throw UsageError("", "", "a comparison needs at least 2 waving frames", "give --frame-count 2 or more");
    apply_shape_target_frame_defaults(compared_target(options), options.frame_selection.given(), half_life->count() > 0,
                                      options.frames, options.half_life_frames);
}

cloth_fit::TrialLoadSettings load_settings(const TrialOptions& options) {
    cloth_fit::TrialLoadSettings load;
    load.target = compared_target(options);
    load.waving_frames = options.frames;
    load.full_weight_frames = options.full_weight_frames;
    load.half_life_frames = options.half_life_frames;
    load.silhouette_term = options.metric == "edge" ? video::SilhouetteTerm::edge_distance : video::SilhouetteTerm::pixel_xor;
    return load;
}

std::optional<cloth_fit::ClothFitSettings> fit_settings(const ClothRunOptions& run, const TrialOptions& trial) {
    const std::optional<cloth::SwatchOptions> swatch = swatch_options(run);
    if (!swatch) return std::nullopt;
    cloth_fit::ClothFitSettings settings;
    settings.swatch = *swatch;
    settings.metric.silhouette_term = load_settings(trial).silhouette_term;
    return settings;
}

nlohmann::json number_or_null(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

// ---------------------------------------------------------------- eval cloth

struct EvalClothOptions {
    std::string preset;
    std::vector<std::string> captures;
    int floor_members = 6;
    std::string floor_kind = "full";
    std::string floor_integrator = "implicit";
    int floor_substeps = cloth_fit::kFloorSubstepsPerFrame;
    std::string report;
    ClothRunOptions run;
    TrialOptions trial;
    bool json = false;
};

// Per-frame error next to its floor (frames are 1-based); no floor, no floor line.
std::string frame_plot(const std::string& title, const std::string& y_label, const std::vector<double>& error,
                       const std::vector<double>& floor) {
    const auto frame_numbers = [](std::size_t count) {
        std::vector<double> x(count);
        for (std::size_t i = 0; i < count; ++i) x[i] = static_cast<double>(i + 1);
        return x;
    };
    html::LinePlot plot;
    plot.title = title;
    plot.x_label = "frame";
    plot.y_label = y_label;
    plot.width_px = 640;
    plot.height_px = 250;
    plot.series.push_back({"error", "#c0392b", frame_numbers(error.size()), error});
    if (!floor.empty()) plot.series.push_back({"predictability floor", "#2e86c1", frame_numbers(floor.size()), floor});
    return html::line_plot_svg(plot);
}

std::string one_decimal(double value) {
    if (!std::isfinite(value)) return html::format_number(value);
    char text[48];
    std::snprintf(text, sizeof text, "%.1f", value);
    return text;
}

int run_eval_cloth(const EvalClothOptions& options, const GlobalOptions& global) {
    const formats::FabricPreset preset = read_preset_for_simulation(options.preset);
    const std::optional<cloth_fit::ClothFitSettings> settings = fit_settings(options.run, options.trial);
    if (!settings) return kExitUsage;
    std::vector<formats::Capture> captures;
    for (const std::string& path : options.captures)
        captures.push_back(formats::read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid eval cloth"));
    if (!options.report.empty()) formats::create_parent_folder(options.report + "/eval.json");
    const cloth::ClothMaterial material = cloth::material_from_fabric(preset.parameters);
    cloth_fit::FloorSettings floor = cloth_fit::reported_floor(options.floor_members);
    if (options.floor_kind == "full") floor.parameter_sigma = cloth_fit::preset_uncertainty(preset.parameters);
    if (options.floor_integrator == "same") {
        floor.integrator.reset();
        floor.implicit_substeps_per_frame.reset();
    } else {
        floor.integrator = cloth::integrators_by_short_name().at(options.floor_integrator);
        floor.implicit_substeps_per_frame = options.floor_substeps;
    }
    const bool floor_has_uncertainty = !floor.parameter_sigma.empty();
    if (options.floor_kind == "full" && !floor_has_uncertainty && floor.members > 0)
        log_message("the preset carries no uncertainty: its floor is the chaos alone");
    const int threads = thread_count(options.run.threads);

    ProgressBar progress(global, "eval cloth");
    nlohmann::json results = nlohmann::json::array();
    std::ostringstream body;
    body << html::element("h1", preset.name) << html::element("p", "preset " + options.preset);
    for (std::size_t i = 0; i < captures.size(); ++i) {
        progress.update(static_cast<double>(i) / captures.size(), captures[i].folder);
        const cloth_fit::ClothTrial trial = cloth_fit::load_trial(captures[i], load_settings(options.trial));
        const std::optional<formats::VertexAnimation> truth = formats::read_capture_truth_positions(captures[i]);
        const cloth_fit::TrialAssessment a =
            cloth_fit::assess_trial(trial, material, *settings, truth, floor.members > 0 ? &floor : nullptr, threads);
        const std::vector<cloth_fit::WindowSummary> windows =
            cloth_fit::summarize_windows(a, cloth_fit::standard_windows(static_cast<int>(trial.frames.size())));
        nlohmann::json window_json = nlohmann::json::array();
        // A scan's E_k is a mean square depth error (mm^2): people read its root, in mm.
        const bool shape = trial.measures_shape();
        const auto shown = [shape](double e) { return shape ? std::sqrt(e) : e; };
        const std::string metric_name = shape ? "RMS depth error (mm)" : "metric E_k (mean)";
        html::Table table;
        table.header = {"frames", metric_name, "floor", "vertex RMS (mm)", "floor (mm)"};
        for (const cloth_fit::WindowSummary& w : windows) {
            nlohmann::json row = {{"frames", cloth_fit::window_name(w.window)},
                                  {"metric_mean", number_or_null(w.metric_mean)},
                                  {"metric_floor", number_or_null(w.metric_floor_mean)},
                                  {"vertex_rms_mm", number_or_null(1e3 * w.vertex_rms_m)},
                                  {"vertex_floor_mm", number_or_null(1e3 * w.vertex_floor_m)}};
            if (shape) {
                row["metric_rms_mm"] = number_or_null(std::sqrt(w.metric_mean));
                row["metric_floor_rms_mm"] = number_or_null(std::sqrt(w.metric_floor_mean));
            }
            window_json.push_back(row);
            table.rows.push_back({cloth_fit::window_name(w.window), one_decimal(shown(w.metric_mean)),
                                  one_decimal(shown(w.metric_floor_mean)), one_decimal(1e3 * w.vertex_rms_m),
                                  one_decimal(1e3 * w.vertex_floor_m)});
        }
        body << html::element("h2", captures[i].folder) << html::table(table);
        if (a.floor)
            body << html::element("p", "floor runs: " + std::string(cloth::integrator_name(a.floor->integrator)) +
                                           (a.floor->implicit_substeps_per_frame > 0
                                                ? " at " + std::to_string(a.floor->implicit_substeps_per_frame) + " substeps a frame"
                                                : std::string()) +
                                           ", start jittered by " + html::format_number(1e3 * a.floor->jitter_m) + " mm",
                                  "muted");
        std::vector<double> metric, metric_floor, vertex_mm, vertex_floor_mm;
        for (const auto& e : a.frames) metric.push_back(shown(e.total));
        if (a.floor)
            for (double e : a.floor->metric) metric_floor.push_back(shown(e));
        for (double v : a.vertex_rms_m) vertex_mm.push_back(1e3 * v);
        if (a.floor) for (double v : a.floor->vertex_rms_m) vertex_floor_mm.push_back(1e3 * v);
        body << frame_plot(shape ? "RMS depth error against the footage's stripe scan per frame (mm)" : "metric E_k per frame",
                           shape ? "RMS depth error (mm)" : "metric E_k", metric, metric_floor);
        if (!vertex_mm.empty())
            body << frame_plot("vertex RMS vs ground truth per frame (mm)", "vertex RMS (mm)", vertex_mm, vertex_floor_mm);
        nlohmann::json entry = {{"capture", captures[i].folder},
                                {"test", a.is_static ? "static" : "waving"},
                                {"weighted_floor", a.floor ? nlohmann::json(cloth_fit::weighted_floor(trial, *a.floor)) : nlohmann::json()},
                                {"simulation", a.report.ok() ? std::string("ok") : std::string(cloth::status_name(a.report.status)) +
                                                                                       " at frame " + std::to_string(a.report.frame)},
                                {"weighted_error", a.weighted_error},
                                {"windows", window_json}};
        if (trial.measures_shape()) entry["rms_mm"] = cloth_fit::tracks_rms_mm(trial, a.weighted_error);  // E_k in mm^2
        if (!a.vertex_rms_m.empty())
            entry["vertex_rms_mm_all_frames"] = 1e3 * cloth_fit::pooled_rms(a.vertex_rms_m, {1, static_cast<int>(a.vertex_rms_m.size())});
        if (a.floor)
            entry["floor"] = {{"integrator", cloth::integrator_name(a.floor->integrator)},
                              {"implicit_substeps_per_frame", a.floor->implicit_substeps_per_frame},
                              {"start_jitter_mm", 1e3 * a.floor->jitter_m},
                              {"includes_uncertainty", floor_has_uncertainty}};
        results.push_back(entry);
    }
    progress.done();
    body << html::element("p", "The predictability floor is the spread of " + std::to_string(floor.members) + " runs whose parameters " +
                                   (floor_has_uncertainty ? "are drawn within the preset's uncertainty and " : "") +
                                   "differ by one part in a million and whose starting shape is jittered "
                                   "by one pixel's footprint at the swatch, run as each capture's note says: "
                                   "no model can be expected to match a chaotic trial better than that.");
    const nlohmann::json summary = {{"preset", options.preset},
                                    {"compared", cloth_fit::fit_target_name(compared_target(options.trial))},
                                    {"floor_members", floor.members},
                                    {"floor_includes_uncertainty", floor_has_uncertainty},
                                    {"captures", results}};
    if (!options.report.empty()) {
        formats::write_file_atomically(options.report + "/eval.json", [&](std::ostream& out) { out << summary.dump(2) << '\n'; });
        formats::write_file_atomically(options.report + "/eval.html", [&](std::ostream& out) {
            out << html::page("flowvid eval cloth", body.str());
        });
    }
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterEvalKind eval_registration{FitKind{
    "cloth", "metric and vertex error of a fabric preset on cloth captures, next to the predictability floor",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<EvalClothOptions>();
        app.footer(
            "Simulates the preset in each capture's experiment and reports, per time window (frames 1-10,\n"
            "11-25, 26-end, and the whole trial), the error E_k against the footage (by default the RMS\n"
            "depth error against the swatch's shape its stripes measure, mm^2; --compare footage: the\n"
            "angle-map metric) and --\n"
            "when the capture has ground truth (truth/positions.exr, read here for evaluation only, never\n"
            "by a fit) -- the RMS vertex error. Next to each: the predictability floor, the spread of an\n"
            "ensemble of runs whose parameters are drawn within the preset's uncertainty (--floor full;\n"
            "--floor chaos leaves that out) and moved by one part in a million, and whose start is\n"
            "jittered by one pixel's footprint at the swatch (the footage places it no better), run\n"
            "with --floor-integrator at --floor-substeps (small steps: large ones damp the chaos away).\n"
            "Waving cloth is chaotic, so an error near its floor is as good as any model can do.\n"
            "--report DIR writes eval.json and eval.html (tables and plots).\n\n"
            "Examples:\n"
            "  flowvid eval cloth --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-2\n"
            "  flowvid eval cloth --preset silk.fabric.json --capture wave1/ --capture wave2/ --out eval/ --json");
        app.add_option("--preset", options->preset, "fabric preset (*.fabric.json)")->required();
        app.add_option("--capture", options->captures, "cloth capture folder (repeat for several)")->required();
        app.add_option("--floor-members", options->floor_members, "ensemble size of the predictability floor (0 = none)")
            ->check(CLI::Range(0, 64))
            ->capture_default_str();
        app.add_option("--floor", options->floor_kind,
                       "full: the floor's runs also draw the parameters within the preset's uncertainty; chaos: only "
                       "the tiny perturbation and the jitter (what the captures' README measured for Blender)")
            ->check(CLI::IsMember({"full", "chaos"}))
            ->capture_default_str();
        std::vector<std::string> floor_integrators = {"same"};
        for (const auto& [name, value] : cloth::integrators_by_short_name()) floor_integrators.push_back(name);
        app.add_option("--floor-integrator", options->floor_integrator,
                       "integrator of the floor's runs: implicit at --floor-substeps (default) or rk4 keep the folds "
                       "whose instability makes cloth chaotic (rk4 is the reference, but slow on stiff fabrics); "
                       "same: --integrator's own steps (quick; at 5 substeps a frame backward Euler damps the chaos "
                       "and claims a predictability the footage lacks)")
            ->check(CLI::IsMember(floor_integrators))
            ->capture_default_str();
        app.add_option("--floor-substeps", options->floor_substeps,
                       "substeps a frame of an implicit floor integrator (the error's runs keep their 5)")
            ->check(CLI::Range(1, 1000))
            ->capture_default_str();
        add_out_option(app, options->report, "folder for eval.json and eval.html", "--report");
        add_trial_options(app, options->trial);
        add_cloth_run_options(app, options->run);
        app.add_flag("--json", options->json, "print the summary as JSON");
        const CLI::Option* half_life = app.get_option("--half-life-frames");
        return [options, half_life](const GlobalOptions& global) {
            apply_frame_choices(options->captures, half_life, options->trial);
            return run_eval_cloth(*options, global);
        };
    }}};

// ---------------------------------------------------------------- recognize

struct RecognizeOptions {
    std::vector<std::string> presets;
    std::vector<std::string> captures;
    ClothRunOptions run;
    TrialOptions trial;
    bool json = false;
};

int run_recognize(const RecognizeOptions& options, const GlobalOptions& global) {
    const std::optional<cloth_fit::ClothFitSettings> settings = fit_settings(options.run, options.trial);
    if (!settings) return kExitUsage;
    std::vector<formats::FabricPreset> presets;
    for (const std::string& path : options.presets) presets.push_back(read_preset_for_simulation(path));
    std::vector<cloth_fit::ClothTrial> trials;
    std::vector<std::optional<formats::VertexAnimation>> truths;
    for (const std::string& path : options.captures) {
        const formats::Capture capture = formats::read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid recognize");
        trials.push_back(cloth_fit::load_trial(capture, load_settings(options.trial)));
        truths.push_back(formats::read_capture_truth_positions(capture));
    }
    const std::size_t cells = presets.size() * trials.size();
    std::vector<cloth_fit::TrialAssessment> assessments(cells);
    ProgressBar progress(global, "recognize");
    const InterruptWatch interrupt;
    std::atomic<std::size_t> done{0};
    flowvid::ThreadPool pool(thread_count(options.run.threads));
    pool.run(cells, [&](std::size_t cell, int) {
        if (interrupt.requested()) return;
        const std::size_t p = cell / trials.size(), c = cell % trials.size();
        assessments[cell] = cloth_fit::assess_trial(trials[c], cloth::material_from_fabric(presets[p].parameters), *settings,
                                                truths[c], nullptr, 1);
        ++done;
    });
    progress.done();
    if (interrupt.requested()) return kExitInterrupted;

    nlohmann::json rows = nlohmann::json::array();
    std::ostringstream table;
    const bool scan = options.trial.compare == "scan";
    table << (scan ? "RMS depth error against the footage's stripe scan, mm"
                   : "weighted metric error")
          << " (rows: captures, columns: presets; * = lowest; the floor is the spread of\n"
             "runs of the lowest preset changed by one part in a million)\n";
    for (std::size_t c = 0; c < trials.size(); ++c) {
        std::size_t best = 0;
        for (std::size_t p = 1; p < presets.size(); ++p)
            if (assessments[p * trials.size() + c].weighted_error < assessments[best * trials.size() + c].weighted_error) best = p;
        nlohmann::json errors = nlohmann::json::object(), vertex = nlohmann::json::object();
        table << std::filesystem::path(trials[c].name).filename().string() << ':';
        for (std::size_t p = 0; p < presets.size(); ++p) {
            const cloth_fit::TrialAssessment& a = assessments[p * trials.size() + c];
            errors[options.presets[p]] = a.weighted_error;
            char cell[64];
            const double shown = scan ? cloth_fit::tracks_rms_mm(trials[c], a.weighted_error) : a.weighted_error;
            std::snprintf(cell, sizeof cell, scan ? "  %8.2f%s" : "  %12.1f%s", shown, p == best ? "*" : " ");
            table << cell;
            if (!a.vertex_rms_m.empty())
                vertex[options.presets[p]] = 1e3 * cloth_fit::pooled_rms(a.vertex_rms_m, {1, static_cast<int>(a.vertex_rms_m.size())});
        }
        // The floor of the recognised preset on this capture: differences
        // between presets below it mean nothing.
        const cloth_fit::FloorSettings floor = cloth_fit::reported_floor(4);
        const double floor_error = cloth_fit::weighted_floor(
            trials[c], cloth_fit::estimate_floor(trials[c], cloth::material_from_fabric(presets[best].parameters), *settings, floor,
                                             thread_count(options.run.threads)));
        char floor_text[48];
        std::snprintf(floor_text, sizeof floor_text, scan ? "  (floor %.2f)" : "  (floor %.1f)",
                      scan ? cloth_fit::tracks_rms_mm(trials[c], floor_error) : floor_error);
        table << floor_text;
        // Recognised only where the runner-up is further than the floor, in
        // the units the table shows (RMS mm for the scan): chaos moves each
        // run's RMS error by up to the floor, so closer than that it could
        // swap the two, and the footage cannot tell the fabrics apart.
        const auto shown = [&](double error) { return scan ? cloth_fit::tracks_rms_mm(trials[c], error) : error; };
        std::optional<double> margin;
        for (std::size_t p = 0; p < presets.size(); ++p)
            if (p != best) {
                const double gap = shown(assessments[p * trials.size() + c].weighted_error) -
                                   shown(assessments[best * trials.size() + c].weighted_error);
                margin = margin ? std::min(*margin, gap) : gap;
            }
        const bool decided = !margin || *margin > shown(floor_error);
        table << (decided ? "  recognised: " + std::filesystem::path(options.presets[best]).filename().string()
                          : std::string("  undecided: the lowest two differ by less than the floor"))
              << '\n';
        nlohmann::json row = {{"capture", trials[c].name}, {"metric_error", errors}, {"recognized_as", options.presets[best]},
                              {"floor", floor_error}, {"decided", decided}};
        row["margin"] = margin ? nlohmann::json(*margin) : nlohmann::json(nullptr);
        if (!vertex.empty()) row["vertex_rms_mm_vs_truth"] = vertex;
        rows.push_back(row);
    }
    const nlohmann::json summary = {{"presets", options.presets}, {"captures", rows}};
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << table.str();
    return kExitOk;
}

const RegisterCommand recognize_registration{Command{
    "recognize", "which fabric preset matches each cloth capture best (thesis fig. 2.21)", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<RecognizeOptions>();
        app.footer(
            "Simulates every preset in every capture's experiment and prints the matrix of RMS depth\n"
            "errors (mm) against the swatch's shape measured from the footage's projector stripes;\n"
            "each capture is recognised as the preset with the lowest error. With --compare footage\n"
            "the matrix holds weighted angle-map errors instead. With --json, also the RMS vertex error\n"
            "against captures' ground truth where it exists (evaluation only).\n"
            "Beside each capture: the floor, what runs of the lowest preset changed by one part in a\n"
            "million differ by (chaos alone). Where the runner-up's error is within the floor of the\n"
            "lowest, the capture is \"undecided\": the footage cannot tell those fabrics apart, and a\n"
            "longer trial or another experiment is needed (JSON: \"decided\", \"margin\" = the\n"
            "runner-up's error minus the lowest as the table shows them, RMS mm for the scan, compared\n"
            "with the floor in the same units; recognized_as stays the lowest).\n\n"
            "Examples:\n"
            "  flowvid recognize --preset cotton.fabric.json --preset silk.fabric.json \\\n"
            "                    --capture ../shared/captures/cloth-cotton-waving-2 --capture ../shared/captures/cloth-silk-waving-2");
        app.add_option("--preset", options->presets, "fabric presets to compare (repeat)")->required();
        app.add_option("--capture", options->captures, "cloth capture folders (repeat)")->required();
        add_trial_options(app, options->trial);
        add_cloth_run_options(app, options->run);
        app.add_flag("--json", options->json, "print the matrix as JSON");
        const CLI::Option* half_life = app.get_option("--half-life-frames");
        return [options, half_life](const GlobalOptions& global) {
            apply_frame_choices(options->captures, half_life, options->trial);
            return run_recognize(*options, global);
        };
    }}};

}  // namespace
}  // namespace flowvid::cli
