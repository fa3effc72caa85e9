#include "flowvid/gap/open_model.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/gap/effects.hpp"
#include "flowvid/gap/rigid_model.hpp"
#include "flowvid/rigid/fit_file.hpp"
#include "flowvid/threads.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"

#include <cmath>
#include <string>

namespace flowvid::gap {

const char* to_string(ClothFloorKind kind) { return kind == ClothFloorKind::chaos ? "chaos" : "repeatability"; }

ClothGapRequest::ClothGapRequest() {
    swatch.rows = kDiagnoserRows;
    swatch.cols = kDiagnoserCols;
    swatch.simulation.integrator = cloth::Integrator::implicit_euler;
}

OpenedGapModel open_cloth_model(const ClothGapRequest& request) {
    OpenedGapModel out;
    const formats::FabricPreset preset = cloth::read_preset_for_simulation(request.preset_path, &out.warnings);
    cloth_fit::TrialLoadSettings load;
    load.waving_frames = request.frames;
    load.full_weight_frames = request.frames;  // every frame counts; the floors do the weighting
    std::vector<cloth_fit::ClothTrial> trials;
    for (const std::string& path : request.capture_paths)
        trials.push_back(cloth_fit::load_trial(
            formats::read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid diagnose"), load));
    ClothGapSettings settings;
    settings.fit.swatch = request.swatch;
    settings.fit.swatch.simulation.implicit_substeps_per_frame = request.substeps_per_frame;
    settings.fit.metric.alpha = request.silhouette_weight;
    settings.threads = resolve_thread_count(request.threads);
    settings.floor_resolution_step = request.floor_resolution_step;
    settings.control_resolution_step = request.control_resolution_step;
    if (request.floor == ClothFloorKind::chaos) {  // the model's own steps, a 0.5 mm start jitter
        cloth_fit::FloorSettings chaos;
        chaos.members = settings.floor.members;
        chaos.jitter_m = 5e-4;
        settings.floor = chaos;
    }
    out.description = {{"preset", request.preset_path},
                       {"resolution", std::to_string(request.swatch.rows) + "x" + std::to_string(request.swatch.cols)},
                       {"integrator", cloth::integrator_short_name(request.swatch.simulation.integrator)},
                       {"substeps_per_frame", request.substeps_per_frame},
                       {"frames", request.frames},
                       {"floor", to_string(request.floor)},
                       {"floor_members", settings.floor.members},
                       {"floor_resolution_step", settings.floor_resolution_step},
                       {"control_resolution_step", settings.control_resolution_step},
                       {"silhouette_weight", request.silhouette_weight}};
    out.model = std::make_unique<ClothGapModel>(std::move(trials), cloth::material_from_fabric(preset.parameters), settings);
    return out;
}

OpenedGapModel open_rigid_model(const RigidGapRequest& request) {
    OpenedGapModel out;
    std::vector<RigidTrial> trials;
    for (const std::string& path : request.capture_paths) {
        RigidTrial trial;
        trial.capture = formats::read_capture_of_kind(path, {"rigid.toss"}, "flowvid diagnose");
        if (!request.fit_path.empty() && trials.empty()) trial.fit = rigid::read_rigid_fit(request.fit_path).as_fit_result();
        trials.push_back(std::move(trial));
    }
    RigidGapSettings settings;
    settings.threads = resolve_thread_count(request.threads);
    out.description = {{"model", "rigid free flight fitted on the training frames of each toss"},
                       {"floor", "re-fits to masks rendered from the fitted motion (quantisation)"}};
    out.model = std::make_unique<RigidGapModel>(std::move(trials), settings);
    return out;
}

OpenedGapModel open_gap_model(const std::vector<std::string>& capture_paths, const std::string& preset_path,
                              const std::string& fit_path, ClothGapRequest cloth) {
    if (capture_paths.empty()) throw UsageError("", "captures", "no captures to diagnose", "give capture folders");
    if (formats::read_capture(capture_paths.front()).is_rigid()) {
        RigidGapRequest rigid;
        rigid.capture_paths = capture_paths;
        rigid.fit_path = fit_path;
        rigid.threads = cloth.threads;
        return open_rigid_model(rigid);
    }
    if (preset_path.empty())
        throw UsageError("", "preset", "a cloth diagnosis needs the fitted fabric",
                         "give the preset (*.fabric.json; `flowvid fit cloth` makes one)");
    cloth.capture_paths = capture_paths;
    cloth.preset_path = preset_path;
    return open_cloth_model(cloth);
}

namespace {

nlohmann::json number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

nlohmann::json effect_values_json(const EffectValues& values) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& [name, v] : values) {
        const Effect& effect = find_effect(name);
        for (std::size_t i = 0; i < effect.parameters.size() && i < static_cast<std::size_t>(v.size()); ++i)
            out[name + "." + effect.parameters[i].key] = v(static_cast<Eigen::Index>(i));
    }
    return out;
}

nlohmann::json base_changes_json(const std::vector<BaseParameterChange>& changes) {
    nlohmann::json out = nlohmann::json::array();
    for (const BaseParameterChange& c : changes) out.push_back({{"key", c.key}, {"before", c.before}, {"after", c.after}});
    return out;
}

nlohmann::json candidates_json(const std::vector<CandidateEvidence>& evidence) {
    nlohmann::json candidates = nlohmann::json::array();
    for (const CandidateEvidence& c : evidence) {
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
            j["share_of_remaining"] = number(c.share_of_remaining);
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
    return candidates;
}

}  // namespace

nlohmann::json diagnosis_document(const Diagnosis& d, const nlohmann::json& model) {
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
                      {"next_step", d.next_step},
                      {"gap_closed", d.gap_closed ? number(*d.gap_closed) : nlohmann::json()},
                      {"model_terms", d.model_terms},
                      {"model_gap_closed", d.model_gap_closed ? number(*d.model_gap_closed) : nlohmann::json()},
                      {"ratio_with_model_terms", d.model_terms.empty() ? nlohmann::json() : number(d.ratio_with_model_terms)}};
    if (d.model_refit) {
        out["verdict"]["model_parameters"] = effect_values_json(d.model_refit->effects);
        out["verdict"]["model_base_changes"] = base_changes_json(d.model_refit->base);
    }
    if (!d.control_description.empty())
        out["discretisation_control"] = {{"refinement", d.control_description},
                                         {"gap_closed", d.control_gap_closed ? number(*d.control_gap_closed) : nlohmann::json()},
                                         {"discounted_effects", d.discounted},  // model terms too
                                         {"failure", d.control_failure.empty() ? nlohmann::json() : nlohmann::json(d.control_failure)}};
    if (d.named_refit) {
        out["verdict"]["parameters"] = effect_values_json(d.named_refit->effects);
        out["verdict"]["base_changes"] = base_changes_json(d.named_refit->base);
    }
    out["candidates"] = candidates_json(d.candidates);
    out["model_candidates"] = candidates_json(d.model_candidates);
    out["null_refit"] = {{"base_changes", base_changes_json(d.null_refit.base)},
                         {"held_out_score", held_out_score(d.null_refit.residuals)}};
    nlohmann::json frames = nlohmann::json::array();
    for (std::size_t i = 0; i < d.base.frames.size(); ++i) {
        const FrameResidual& f = d.base.frames[i];
        nlohmann::json j = {{"trial", f.trial}, {"frame", f.frame}, {"time_s", f.time_s}, {"error", f.error},
                            {"floor", f.floor}, {"held_out", f.held_out}, {"driver", f.driver}};
        j["error_with_effect"] = d.named_refit && i < d.named_refit->residuals.frames.size()
                                     ? number(d.named_refit->residuals.frames[i].error)
                                     : nlohmann::json();
        frames.push_back(j);
    }
    out["frames"] = frames;
    nlohmann::json maps = nlohmann::json::array();
    for (const RegionMap& m : d.maps) {
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
    for (const EquivalenceClass& c : equivalence_classes())
        classes.push_back({{"name", c.name}, {"members", c.members}, {"why", c.why}});
    out["equivalence_classes"] = classes;
    out["evaluations"] = d.evaluations;
    out["seconds"] = d.seconds;
    return out;
}

}  // namespace flowvid::gap
