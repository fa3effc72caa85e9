// flowvid diagnose: where a fitted simulation departs from footage, which
// unmodelled effect causes it and how much of the gap it closes
// (libflowvid gap/diagnose.hpp). Writes diagnosis.json and report.html.

#include "commands/cloth_options.hpp"
#include "commands/diagnose.hpp"
#include "commands/diagnose_report.hpp"
#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/gap/open_model.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>

namespace flowvid::cli {

namespace {
nlohmann::json number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }
}  // namespace

void write_diagnosis(const std::string& folder, const nlohmann::json& diagnosis) {
    std::filesystem::create_directories(folder);
    // Validated against formats/specs/diagnosis.md before it is written.
    formats::write_diagnosis(folder + "/diagnosis.json", diagnosis);
    formats::write_file_atomically(folder + "/report.html",
                                   [&](std::ostream& out) { out << diagnosis_report_html(diagnosis); });
}

std::string diagnoser_resolution() { return std::to_string(gap::kDiagnoserRows) + "x" + std::to_string(gap::kDiagnoserCols); }

std::optional<gap::ClothGapRequest> cloth_gap_request(const DiagnoseClothOptions& options) {
    const std::optional<cloth::SwatchOptions> swatch = swatch_options(options.run);
    if (!swatch) return std::nullopt;
    gap::ClothGapRequest request;
    request.swatch = *swatch;
    request.frames = options.frames;
    request.substeps_per_frame = options.substeps_per_frame;
    request.floor_resolution_step = options.floor_resolution_step;
    request.control_resolution_step = options.control_resolution_step;
    request.floor = options.floor == "chaos" ? gap::ClothFloorKind::chaos : gap::ClothFloorKind::repeatability;
    request.silhouette_weight = options.silhouette_weight;
    request.threads = options.run.threads;
    return request;
}

namespace {

struct DiagnoseOptions {
    std::vector<std::string> captures;
    std::string preset;
    std::string fit;
    std::string out;
    std::vector<std::string> effects;
    FrameOptions frame_selection;  // resolved into cloth.frames
    DiagnoseClothOptions cloth;
    gap::DiagnoseSettings settings;
    bool json = false;
};

// The rigid gap model of tosses: each is fitted on its own training frames
// (a fit that saw the held-out frames would flatter them).
int run_diagnose(DiagnoseOptions& options, const GlobalOptions& global) {
    const bool rigid = formats::read_capture(options.captures.front()).is_rigid();
    if (!rigid && options.preset.empty()) {
        log_message("flowvid diagnose: give --preset P (the fitted fabric; `flowvid fit cloth` makes one)");
        return kExitUsage;
    }
    for (const std::string& name : options.effects) gap::find_effect(name);  // unknown names fail before the work
    formats::create_parent_folder((std::filesystem::path(options.out) / "diagnosis.json").string());  // the report folder
    const std::optional<gap::ClothGapRequest> cloth = cloth_gap_request(options.cloth);
    if (!cloth) return kExitUsage;
    ProgressBar floors(global, "diagnose");  // the floors are computed as the model opens
    floors.update(0.0, "floors");
    const gap::OpenedGapModel opened = gap::open_gap_model(options.captures, options.preset, options.fit, *cloth);
    floors.done();
    print_problems(opened.warnings);
    options.settings.effects = options.effects;
    TerminalProgress progress(global, "diagnose");
    options.settings.progress = progress.callback();
    gap::Diagnosis diagnosis;
    try {
        diagnosis = gap::diagnose(*opened.model, options.settings);
    } catch (const flowvid::Cancelled&) {
        progress.finish();
        log_message("interrupted: nothing written");
        return kExitInterrupted;
    }
    progress.finish();
    write_diagnosis(options.out, gap::diagnosis_document(diagnosis, opened.description));
    nlohmann::json summary = {{"out", options.out},
                              {"gap_detected", diagnosis.gap_detected},
                              {"held_out_over_floor", number(diagnosis.ratio)},
                              {"verdict", diagnosis.status},
                              {"effects", diagnosis.named},
                              {"message", diagnosis.message},
                              {"next_step", diagnosis.next_step},
                              {"model_terms", diagnosis.model_terms},
                              {"model_gap_closed", diagnosis.model_gap_closed ? number(*diagnosis.model_gap_closed) : nlohmann::json()},
                              {"gap_closed", diagnosis.gap_closed ? number(*diagnosis.gap_closed) : nlohmann::json()},
                              {"evaluations", diagnosis.evaluations},
                              {"seconds", diagnosis.seconds}};
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "diagnose", "where a fitted simulation departs from footage, which unmodelled effect causes it, how far it shrinks",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<DiagnoseOptions>();
        options->cloth.run.resolution = diagnoser_resolution();
        app.footer(
            "Cloth: simulates the fitted fabric in each capture's experiment and compares every frame with the\n"
            "footage in units of its floor (how far repeated takes of the experiment spread: what even a\n"
            "perfect model leaves). Frames alternate in blocks of 5 between training and held out. When\n"
            "the held-out residual is beyond --gap-threshold times the floor, the fabric's bend, stretch\n"
            "and drag are refitted alone on training frames (the null refit). First the model's own terms\n"
            "that the preset was fitted without (soft compression, hem, diagonal fibres, linear drag: a\n"
            "preset from `fit cloth --fit-to scan` has them) are tried: a term that closes the gap is\n"
            "named first and the effects are judged on top of it. Then every catalogue effect is\n"
            "screened, the most promising are refitted jointly with the fabric, and one is\n"
            "named only when it beats the null refit on held-out frames by a clear share of the gap,\n"
            "with a strong BIC margin, in most bootstrap resamples, and closes 10 points more of the gap\n"
            "than the fabric on a finer mesh does (--control-resolution-step: else the gap may be the\n"
            "model's own discretisation, and the verdict is unexplained).\n"
            "Model terms: compression_softness hem_mass diagonal_fibres drag_linear.\n"
            "Effects: drag_nonlinear wind anisotropy hysteresis pin_lag pin_slip camera_roll\n"
            "lens_distortion rolling_shutter motion_blur (rigid: air_drag inertia_error).\n"
            "camera_roll is reported with gravity_tilt as one class: one camera cannot tell them apart.\n"
            "The verdict is one sentence with its figures and a next step (refit with ..., check the\n"
            "camera calibration, ...). Writes OUT/diagnosis.json and OUT/report.html (open it in a browser).\n\n"
            "Examples:\n"
            "  flowvid diagnose --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-wind --out diag/\n"
            "  flowvid diagnose --preset silk.fabric.json --capture DIR --effects pin_lag,wind --out diag/\n"
            "  flowvid diagnose --capture ../shared/captures/rigid-toss-major --out diag/   # rigid: fitted on training frames");
        app.add_option("--capture", options->captures, "capture folder (repeat for several)")->required();
        app.add_option("--preset", options->preset, "the fitted fabric (*.fabric.json; cloth captures)");
        app.add_option("--fit", options->fit, "rigid: start from this fit of the first capture (flowvid fit rigid's fit.json)");
        app.add_option("--out", options->out, "report folder (diagnosis.json, report.html)")->required();
        app.add_option("--effects", options->effects, "candidates to consider (default: every applicable one)")->delimiter(',');
        add_frame_options(app, options->frame_selection,
                          "cloth: waving frames A to B compared; A is the wave's first frame (later frames are mostly chaos)",
                          "the first N waving frames", "the first 30");
        app.add_option("--floor-resolution-step", options->cloth.floor_resolution_step,
                       "the floor also holds a run on a mesh this many rows and columns finer (0: none)")
            ->check(CLI::Range(0, 64))
            ->capture_default_str();
        app.add_option("--control-resolution-step", options->cloth.control_resolution_step,
                       "the discretisation control: the base on a mesh this many rows and columns finer; named effects "
                       "must close 10 points more of the gap than it does (0: no control)")
            ->check(CLI::Range(0, 64))
            ->capture_default_str();
        app.add_option("--floor", options->cloth.floor,
                       "repeatability: how far repeated takes of the experiment spread (a pixel's start jitter, 20 "
                       "substeps a frame; what eval cloth reports); chaos: the model's own steps and a 0.5 mm jitter "
                       "(much tighter: mesh and step differences then count as gaps)")
            ->check(CLI::IsMember({"repeatability", "chaos"}))
            ->capture_default_str();
        app.add_option("--silhouette-weight", options->cloth.silhouette_weight,
                       "weight of a mismatched silhouette pixel against a squared radian of fold orientation "
                       "(the fit's is 0.1; where folds form depends on the mesh far more than the outline does)")
            ->check(CLI::NonNegativeNumber)
            ->capture_default_str();
        app.add_option("--substeps", options->cloth.substeps_per_frame, "steps per frame of the implicit integrators")
            ->check(CLI::Range(1, 1000))
            ->capture_default_str();
        app.add_option("--gap-threshold", options->settings.gap_threshold,
                       "held-out error over floor (mean per frame) above which a gap is structural")
            ->check(CLI::PositiveNumber)
            ->capture_default_str();
        app.add_option("--refit-evaluations", options->settings.refit_evaluations, "simulations per refit")
            ->check(CLI::Range(4, 100000))
            ->capture_default_str();
        app.add_option("--candidates", options->settings.refitted_candidates, "screened candidates that are refitted")
            ->check(CLI::Range(1, 20))
            ->capture_default_str();
        app.add_option("--seed", options->settings.seed, "bootstrap seed")->capture_default_str();
        add_cloth_run_options(app, options->cloth.run);
        // Not the fits' 24x24: said where a user compares the defaults.
        app.get_option("--resolution")
            ->description("the diagnoser's mesh, RxC vertices: coarser than the fits' 24x24 so that its many refits stay "
                          "quick, fine enough that its drape stays within reach of a finer mesh's (docs/gap.md)");
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) {
            if (const std::optional<int> count = resolve_waving_frame_count(options->frame_selection, options->captures))
                options->cloth.frames = *count;
            if (options->cloth.frames < 4)
                throw UsageError("", "", "a diagnosis needs at least 4 frames", "give --frame-count 4 or more");
            return run_diagnose(*options, global);
        };
    }}};

}  // namespace
}  // namespace flowvid::cli
