// flowvid diagnose: where a fitted simulation departs from footage, which
// unmodelled effect causes it and how much of the gap it closes
// (libflowvid gap/diagnose.hpp). Writes diagnosis.json and report.html.

#include "commands/cloth_options.hpp"
#include "commands/diagnose.hpp"
#include "commands/diagnose_report.hpp"
#include "commands/fit.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/gap/cloth_model.hpp"
#include "flowvid/gap/diagnose.hpp"
#include "flowvid/gap/rigid_model.hpp"
#include "flowvid/rigid/fit_file.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {

namespace {

nlohmann::json number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

nlohmann::json effect_values_json(const gap::EffectValues& values) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& [name, v] : values) {
        const gap::Effect& effect = gap::find_effect(name);
        for (std::size_t i = 0; i < effect.parameters.size() && i < static_cast<std::size_t>(v.size()); ++i)
            out[name + "." + effect.parameters[i].key] = v(static_cast<Eigen::Index>(i));
    }
    return out;
}

nlohmann::json base_changes_json(const std::vector<gap::BaseParameterChange>& changes) {
    nlohmann::json out = nlohmann::json::array();
    for (const gap::BaseParameterChange& c : changes) out.push_back({{"key", c.key}, {"before", c.before}, {"after", c.after}});
    return out;
}

}  // namespace

nlohmann::json diagnosis_to_json(const gap::Diagnosis& d, const nlohmann::json& model) {
    nlohmann::json out;
    out["format"] = formats::kDiagnosisFormatName;
    out["version"] = formats::kDiagnosisFormatVersion;
    out["kind"] = d.kind;
    out["trials"] = d.trials;
    out["model"] = model;
    out["gap"] = {{"detected", d.gap_detected},
                  {"held_out_error", d.held_out_error},
                  {"held_out_floor", d.held_out_floor},
                  {"ratio", number(d.ratio)},
                  {"threshold", d.threshold},
                  {"held_out_frames", d.held_out_frames}};
    out["verdict"] = {{"status", d.status},
                      {"effects", d.named},
                      {"class", d.named_class},
                      {"message", d.message},
                      {"gap_closed", d.gap_closed ? number(*d.gap_closed) : nlohmann::json()}};
    if (!d.control_description.empty())
        out["discretisation_control"] = {{"refinement", d.control_description},
                                         {"gap_closed", d.control_gap_closed ? number(*d.control_gap_closed) : nlohmann::json()},
                                         {"discounted_effects", d.discounted},
                                         {"failure", d.control_failure.empty() ? nlohmann::json() : nlohmann::json(d.control_failure)}};
    if (d.named_refit) {
        out["verdict"]["parameters"] = effect_values_json(d.named_refit->effects);
        out["verdict"]["base_changes"] = base_changes_json(d.named_refit->base);
    }
    nlohmann::json candidates = nlohmann::json::array();
    for (const gap::CandidateEvidence& c : d.candidates) {
        nlohmann::json j = {{"name", c.name},
                            {"domain", c.domain},
                            {"screen_score", c.screen_score},
                            {"refitted", c.refitted},
                            {"equivalence_class", c.equivalence_class},
                            {"passes", c.passes}};
        if (c.refitted) {
            j["parameters"] = effect_values_json(c.refit.effects);
            j["base_changes"] = base_changes_json(c.refit.base);
            j["held_out_error"] = c.held_out_score;
            j["gap_closed"] = number(c.gap_closed);
            j["effect_share"] = number(c.effect_share);
            j["delta_bic"] = number(c.delta_bic);
            j["bootstrap_stability"] = c.bootstrap_stability;
        } else {
            j["parameters"] = effect_values_json(c.screened);
            j["held_out_error"] = nullptr;
            j["gap_closed"] = nullptr;
            j["delta_bic"] = nullptr;
            j["bootstrap_stability"] = nullptr;
        }
        candidates.push_back(j);
    }
    out["candidates"] = candidates;
    out["null_refit"] = {{"base_changes", base_changes_json(d.null_refit.base)},
                         {"held_out_score", gap::held_out_score(d.null_refit.residuals)}};
    nlohmann::json frames = nlohmann::json::array();
    for (std::size_t i = 0; i < d.base.frames.size(); ++i) {
        const gap::FrameResidual& f = d.base.frames[i];
        nlohmann::json j = {{"trial", f.trial}, {"frame", f.frame}, {"time_s", f.time_s}, {"error", f.error},
                            {"floor", f.floor}, {"held_out", f.held_out}, {"driver", f.driver}};
        j["error_with_effect"] = d.named_refit && i < d.named_refit->residuals.frames.size()
                                     ? number(d.named_refit->residuals.frames[i].error)
                                     : nlohmann::json();
        frames.push_back(j);
    }
    out["frames"] = frames;
    nlohmann::json maps = nlohmann::json::array();
    for (const gap::RegionMap& m : d.maps) {
        nlohmann::json values = nlohmann::json::array();
        for (double v : m.values) values.push_back(number(v));
        maps.push_back({{"name", m.name}, {"units", m.units}, {"rows", m.rows}, {"cols", m.cols}, {"values", values}});
    }
    out["maps"] = maps;
    out["spectrum"] = {{"frequency_hz", d.spectrum.frequency_hz},
                       {"residual_power", d.spectrum.residual_power},
                       {"floor_power", d.spectrum.floor_power}};
    // What one camera cannot tell apart, whatever the verdict.
    nlohmann::json classes = nlohmann::json::array();
    for (const gap::EquivalenceClass& c : gap::equivalence_classes())
        classes.push_back({{"name", c.name}, {"members", c.members}, {"why", c.why}});
    out["equivalence_classes"] = classes;
    out["evaluations"] = d.evaluations;
    out["seconds"] = d.seconds;
    return out;
}

void write_diagnosis(const std::string& folder, const nlohmann::json& diagnosis) {
    std::filesystem::create_directories(folder);
    // Validated against formats/specs/diagnosis.md before it is written.
    formats::write_diagnosis(folder + "/diagnosis.json", diagnosis);
    formats::write_file_atomically(folder + "/report.html",
                                   [&](std::ostream& out) { out << diagnosis_report_html(diagnosis); });
}

std::unique_ptr<gap::GapModel> cloth_gap_model(const std::vector<std::string>& capture_paths, const std::string& preset_path,
                                               const DiagnoseClothOptions& options, nlohmann::json& model_summary) {
    const formats::FabricPreset preset = read_preset_for_simulation(preset_path);
    const std::optional<cloth::SwatchOptions> swatch = swatch_options(options.run);
    if (!swatch) return nullptr;
    video::TrialLoadSettings load;
    load.waving_frames = options.frames;
    load.full_weight_frames = options.frames;  // every frame counts; the floors do the weighting
    std::vector<video::ClothTrial> trials;
    for (const std::string& path : capture_paths) {
        const formats::Capture capture = read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid diagnose");
        trials.push_back(video::load_trial(capture, load));
    }
    gap::ClothGapSettings settings;
    settings.fit.swatch = *swatch;
    settings.fit.swatch.simulation.implicit_substeps_per_frame = options.substeps_per_frame;
    settings.fit.metric.alpha = options.silhouette_weight;
    settings.threads = thread_count(options.run.threads);
    settings.floor_resolution_step = options.floor_resolution_step;
    settings.control_resolution_step = options.control_resolution_step;
    if (options.floor == "chaos") {  // the model's own steps, a 0.5 mm start jitter
        video::FloorSettings chaos;
        chaos.members = settings.floor.members;
        chaos.jitter_m = 5e-4;
        settings.floor = chaos;
    }
    model_summary = {{"preset", preset_path},
                     {"resolution", options.run.resolution},
                     {"integrator", options.run.integrator},
                     {"substeps_per_frame", options.substeps_per_frame},
                     {"frames", options.frames},
                     {"floor", options.floor},
                     {"floor_members", settings.floor.members},
                     {"floor_resolution_step", settings.floor_resolution_step},
                     {"control_resolution_step", settings.control_resolution_step},
                     {"silhouette_weight", options.silhouette_weight}};
    return std::make_unique<gap::ClothGapModel>(std::move(trials), cloth::material_from_fabric(preset.parameters), settings);
}

// With --fit, the first capture starts from that fit (flowvid fit rigid's
// fit.json); a fit that saw the held-out frames makes them look better.
std::unique_ptr<gap::GapModel> rigid_gap_model(const std::vector<std::string>& capture_paths, const std::string& fit_path,
                                               int threads, nlohmann::json& model_summary) {
    std::vector<gap::RigidTrial> trials;
    for (const std::string& path : capture_paths) {
        gap::RigidTrial trial;
        trial.capture = read_capture_of_kind(path, {"rigid.toss"}, "flowvid diagnose");
        if (!fit_path.empty() && trials.empty()) trial.fit = rigid::read_rigid_fit(fit_path).as_fit_result();
        trials.push_back(std::move(trial));
    }
    gap::RigidGapSettings settings;
    settings.threads = thread_count(threads);
    model_summary = {{"model", "rigid free flight fitted on the training frames of each toss"},
                     {"floor", "re-fits to masks rendered from the fitted motion (quantisation)"}};
    return std::make_unique<gap::RigidGapModel>(std::move(trials), settings);
}

namespace {

struct DiagnoseOptions {
    std::vector<std::string> captures;
    std::string preset;
    std::string fit;
    std::string out;
    std::vector<std::string> effects;
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
    prepare_output_folder((std::filesystem::path(options.out) / "diagnosis.json").string());  // the report folder
    Progress progress(global, "diagnose");
    const InterruptWatch interrupt;
    progress.update(0.0, "floors");
    nlohmann::json model_summary;
    const std::unique_ptr<gap::GapModel> model =
        rigid ? rigid_gap_model(options.captures, options.fit, options.cloth.run.threads, model_summary)
              : cloth_gap_model(options.captures, options.preset, options.cloth, model_summary);
    if (!model) return kExitUsage;
    options.settings.effects = options.effects;
    options.settings.progress = [&](const std::string& stage, double fraction) {
        progress.update(fraction, stage);
        return !interrupt.requested();
    };
    gap::Diagnosis diagnosis;
    try {
        diagnosis = gap::diagnose(*model, options.settings);
    } catch (const gap::Cancelled&) {
        progress.done();
        log_message("interrupted: nothing written");
        return kExitInterrupted;
    }
    progress.done();
    const nlohmann::json document = diagnosis_to_json(diagnosis, model_summary);
    write_diagnosis(options.out, document);
    nlohmann::json summary = {{"out", options.out},
                              {"gap_detected", diagnosis.gap_detected},
                              {"held_out_over_floor", number(diagnosis.ratio)},
                              {"verdict", diagnosis.status},
                              {"effects", diagnosis.named},
                              {"message", diagnosis.message},
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
        options->cloth.run.resolution = kDiagnoserResolution;
        app.footer(
            "Cloth: simulates the fitted fabric in each capture's experiment and compares every frame with the\n"
            "footage in units of its floor (how far repeated takes of the experiment spread: what even a\n"
            "perfect model leaves). Frames alternate in blocks of 5 between training and held out. When\n"
            "the held-out residual is beyond --gap-threshold times the floor, the fabric's bend, stretch\n"
            "and drag are refitted alone on training frames (the null refit), every catalogue effect is\n"
            "screened from there, the most promising are refitted jointly with the fabric, and one is\n"
            "named only when it beats the null refit on held-out frames by a clear share of the gap,\n"
            "with a strong BIC margin, in most bootstrap resamples, and closes 10 points more of the gap\n"
            "than the fabric on a finer mesh does (--control-resolution-step: else the gap may be the\n"
            "model's own discretisation, and the verdict is unexplained).\n"
            "Effects: drag_nonlinear wind anisotropy hysteresis pin_lag pin_slip camera_roll\n"
            "lens_distortion rolling_shutter motion_blur (rigid: air_drag inertia_error).\n"
            "camera_roll is reported with gravity_tilt as one class: one camera cannot tell them apart.\n"
            "Writes OUT/diagnosis.json and OUT/report.html (open it in a browser).\n\n"
            "Examples:\n"
            "  flowvid diagnose --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-wind --out diag/\n"
            "  flowvid diagnose --preset silk.fabric.json --capture DIR --effects pin_lag,wind --out diag/\n"
            "  flowvid diagnose --capture ../shared/captures/rigid-toss-major --out diag/   # rigid: fitted on training frames");
        app.add_option("--capture", options->captures, "capture folder (repeat for several)")->required();
        app.add_option("--preset", options->preset, "the fitted fabric (*.fabric.json; cloth captures)");
        app.add_option("--fit", options->fit, "rigid: start from this fit of the first capture (flowvid fit rigid's fit.json)");
        app.add_option("--out", options->out, "report folder (diagnosis.json, report.html)")->required();
        app.add_option("--effects", options->effects, "candidates to consider (default: every applicable one)")->delimiter(',');
        app.add_option("--frames", options->cloth.frames, "frames compared from the first")
            ->check(CLI::Range(4, 100000))
            ->capture_default_str();
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
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_diagnose(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
