#include "flowvid/formats/diagnosis.hpp"

#include "json_extras.hpp"

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <limits>

namespace flowvid::formats {

namespace {

using detail::expect_object;
using detail::non_empty_string;
using detail::nullable_number;
using detail::nullable_number_value;
using detail::string_array;

constexpr const char* kKinds[] = {"cloth", "rigid"};
constexpr const char* kDomains[] = {"model", "cloth", "camera", "rigid"};
constexpr std::int64_t kMaxCount = std::numeric_limits<std::int32_t>::max();

template <std::size_t N>
bool one_of(const std::string& value, const char* const (&names)[N]) {
    return std::find(std::begin(names), std::end(names), value) != std::end(names);
}

template <std::size_t N>
std::string listed(const char* const (&names)[N]) {
    std::string text;
    for (const char* name : names) text += (text.empty() ? "\"" : ", \"") + std::string(name) + "\"";
    return text;
}

// A string that must be one of `names`.
template <std::size_t N>
std::optional<std::string> enumerated(const JsonView& view, const std::string& key, const char* const (&names)[N]) {
    std::optional<std::string> value = view.string(key);
    if (value && !one_of(*value, names)) {
        view.diagnostics().error(json_pointer_child(view.pointer(), key), "\"" + *value + "\" is not one of " + listed(names),
                                 "write one of " + listed(names));
        return std::nullopt;
    }
    return value;
}

// {"effect.parameter": value, ...}: the values of effect parameters.
void parse_parameter_values(const JsonView& view, const std::string& key) {
    const std::optional<JsonView> values = view.object(key);
    if (!values) return;
    for (auto it = values->json().begin(); it != values->json().end(); ++it) {
        if (it.key().empty())
            values->diagnostics().error(json_pointer_child(values->pointer(), it.key()), "empty parameter name",
                                        "name each value \"effect.parameter\"");
        nullable_number_value(values->child(it.key()), NumberRange{});
    }
}

// [{"key": ..., "before": ..., "after": ...}]: how the base parameters moved.
void parse_base_changes(const JsonView& view, const std::string& key) {
    const std::optional<JsonView> changes = view.array(key);
    if (!changes) return;
    for (std::size_t i = 0; i < changes->size(); ++i) {
        const JsonView change = changes->element(i);
        if (!expect_object(change, "write {\"key\": ..., \"before\": ..., \"after\": ...}")) continue;
        change.check_known_keys({"key", "before", "after"});
        non_empty_string(change, "key", "write the base parameter's name, e.g. \"bend_N_m\"");
        nullable_number(change, "before", NumberRange{});
        nullable_number(change, "after", NumberRange{});
    }
}

std::optional<DiagnosisGap> parse_gap(const JsonView& root) {
    const std::optional<JsonView> gap = root.object("gap");
    if (!gap) return std::nullopt;
    gap->check_known_keys({"detected", "held_out_error", "held_out_floor", "ratio", "threshold", "held_out_frames"});
    DiagnosisGap out;
    const std::optional<bool> detected = gap->boolean("detected");
    const auto error = nullable_number(*gap, "held_out_error", NumberRange::non_negative("(the metric's unit)"));
    const auto floor = nullable_number(*gap, "held_out_floor", NumberRange::non_negative("(the metric's unit)"));
    const auto ratio = nullable_number(*gap, "ratio", NumberRange::non_negative("(floors)"));
    const std::optional<double> threshold = gap->number("threshold", NumberRange::positive("(floors)"));
    const std::optional<std::int64_t> frames = gap->integer("held_out_frames", 0, kMaxCount);
    if (!detected || !error.ok || !floor.ok || !ratio.ok || !threshold || !frames) return std::nullopt;
    out.detected = *detected;
    out.held_out_error = error.value;
    out.held_out_floor = floor.value;
    out.ratio = ratio.value;
    out.threshold = *threshold;
    out.held_out_frames = static_cast<int>(*frames);
    return out;
}

std::optional<DiagnosisVerdict> parse_verdict(const JsonView& root) {
    const std::optional<JsonView> verdict = root.object("verdict");
    if (!verdict) return std::nullopt;
    verdict->check_known_keys({"status", "effects", "class", "message", "next_step", "gap_closed", "parameters", "base_changes",
                               "model_terms", "model_gap_closed", "ratio_with_model_terms", "model_parameters",
                               "model_base_changes"});
    const std::optional<std::string> status = enumerated(*verdict, "status", kDiagnosisStatuses);
    const std::optional<std::vector<std::string>> effects = string_array(*verdict, "effects");
    const std::optional<std::string> effect_class = verdict->string("class");
    const std::optional<std::string> message = verdict->string("message");
    const auto closed = nullable_number(*verdict, "gap_closed", NumberRange{});
    if (verdict->has("parameters")) parse_parameter_values(*verdict, "parameters");
    if (verdict->has("base_changes")) parse_base_changes(*verdict, "base_changes");
    // Since 2026-11-28 (optional: earlier files have none of these).
    if (verdict->has("next_step")) verdict->string("next_step");
    std::vector<std::string> model_terms;
    if (verdict->has("model_terms"))
        if (const auto terms = string_array(*verdict, "model_terms")) model_terms = *terms;
    if (verdict->has("model_gap_closed")) nullable_number(*verdict, "model_gap_closed", NumberRange{});
    if (verdict->has("ratio_with_model_terms"))
        nullable_number(*verdict, "ratio_with_model_terms", NumberRange::non_negative("(floors)"));
    if (verdict->has("model_parameters")) parse_parameter_values(*verdict, "model_parameters");
    if (verdict->has("model_base_changes")) parse_base_changes(*verdict, "model_base_changes");
    if (effects) {
        for (std::size_t i = 0; i < effects->size(); ++i)
            if ((*effects)[i].empty())
                verdict->diagnostics().error(json_pointer_child(json_pointer_child(verdict->pointer(), "effects"), i),
                                             "empty effect name", "write the catalogue name of the effect");
        if (status && (*status == "named") != !effects->empty())
            verdict->diagnostics().error(json_pointer_child(verdict->pointer(), "effects"),
                                         *status == "named" ? "the verdict is \"named\" but names no effect"
                                                            : "the verdict is \"" + *status + "\" but names effects",
                                         "list the named effects exactly when \"status\" is \"named\"");
    }
    if (!status || !effects || !effect_class || !message || !closed.ok) return std::nullopt;
    return DiagnosisVerdict{*status, *effects, *effect_class, *message, closed.value, model_terms};
}

void parse_candidates(const JsonView& root, const std::string& key) {
    const std::optional<JsonView> candidates = root.array(key);
    if (!candidates) return;
    for (std::size_t i = 0; i < candidates->size(); ++i) {
        const JsonView c = candidates->element(i);
        if (!expect_object(c, "write each candidate as an object with \"name\", \"domain\", \"refitted\", ...")) continue;
        c.check_known_keys({"name", "domain", "screen_score", "refitted", "equivalence_class", "passes", "parameters",
                            "base_changes", "held_out_error", "gap_closed", "effect_share", "delta_bic",
                            "bootstrap_stability", "share_of_remaining"});
        non_empty_string(c, "name", "write the catalogue name of the effect");
        enumerated(c, "domain", kDomains);
        nullable_number(c, "screen_score", NumberRange{});
        const std::optional<bool> refitted = c.boolean("refitted");
        c.string("equivalence_class");
        const std::optional<bool> passes = c.boolean("passes");
        parse_parameter_values(c, "parameters");
        nullable_number(c, "held_out_error", NumberRange::non_negative("(floors)"));
        nullable_number(c, "gap_closed", NumberRange{});
        nullable_number(c, "delta_bic", NumberRange{});
        nullable_number(c, "bootstrap_stability", NumberRange::closed(0.0, 1.0));
        // A refitted candidate has its refit's base changes and share; a screened one has neither.
        const bool has_refit = refitted.value_or(false);
        if (has_refit || c.has("base_changes")) parse_base_changes(c, "base_changes");
        if (has_refit || c.has("effect_share")) nullable_number(c, "effect_share", NumberRange{});
        if (c.has("share_of_remaining")) nullable_number(c, "share_of_remaining", NumberRange{});
        if (passes.value_or(false) && refitted && !*refitted)
            c.diagnostics().error(json_pointer_child(c.pointer(), "passes"), "a candidate that was not refitted cannot pass",
                                  "set \"passes\": false, or \"refitted\": true with the refit's evidence");
    }
}

void parse_frames(const JsonView& root, std::size_t trials) {
    const std::optional<JsonView> frames = root.array("frames");
    if (!frames) return;
    for (std::size_t i = 0; i < frames->size(); ++i) {
        const JsonView f = frames->element(i);
        if (!expect_object(f, "write each frame as {\"trial\": ..., \"frame\": ..., \"error\": ..., \"floor\": ..., ...}")) continue;
        f.check_known_keys({"trial", "frame", "time_s", "error", "floor", "held_out", "driver", "error_with_effect"});
        const std::int64_t last_trial = trials > 0 ? static_cast<std::int64_t>(trials) - 1 : kMaxCount;
        f.integer("trial", 0, last_trial);
        f.integer("frame", 0, kMaxCount);
        nullable_number(f, "time_s", NumberRange{});
        nullable_number(f, "error", NumberRange::non_negative("(the metric's unit)"));
        nullable_number(f, "floor", NumberRange::non_negative("(the metric's unit)"));
        f.boolean("held_out");
        nullable_number(f, "driver", NumberRange{});
        nullable_number(f, "error_with_effect", NumberRange::non_negative("(the metric's unit)"));
    }
}

void parse_maps(const JsonView& root) {
    const std::optional<JsonView> maps = root.array("maps");
    if (!maps) return;
    for (std::size_t i = 0; i < maps->size(); ++i) {
        const JsonView m = maps->element(i);
        if (!expect_object(m, "write each map as {\"name\", \"units\", \"rows\", \"cols\", \"values\"}")) continue;
        m.check_known_keys({"name", "units", "rows", "cols", "values"});
        m.string("name");
        m.string("units");
        const std::optional<std::int64_t> rows = m.integer("rows", 0, 1000000);
        const std::optional<std::int64_t> cols = m.integer("cols", 0, 1000000);
        const std::optional<JsonView> values = m.array("values");
        if (!values) continue;
        for (std::size_t k = 0; k < values->size(); ++k) nullable_number_value(values->element(k), NumberRange{});
        if (rows && cols && static_cast<std::int64_t>(values->size()) != *rows * *cols)
            m.diagnostics().error(values->pointer(),
                                  "holds " + std::to_string(values->size()) + " values for a " + std::to_string(*rows) + "x" +
                                      std::to_string(*cols) + " map",
                                  "write rows x cols values, row-major (null where nothing was seen)");
    }
}

void parse_spectrum(const JsonView& root) {
    const std::optional<JsonView> spectrum = root.object("spectrum");
    if (!spectrum) return;
    spectrum->check_known_keys({"frequency_hz", "residual_power", "floor_power"});
    std::optional<std::size_t> length;
    for (const char* key : {"frequency_hz", "residual_power", "floor_power"}) {
        const std::optional<JsonView> list = spectrum->array(key);
        if (!list) continue;
        const NumberRange range = NumberRange::non_negative(std::string(key) == "frequency_hz" ? "Hz" : "");
        for (std::size_t k = 0; k < list->size(); ++k) nullable_number_value(list->element(k), range);
        if (!length) length = list->size();
        else if (*length != list->size())
            spectrum->diagnostics().error(list->pointer(),
                                          "holds " + std::to_string(list->size()) + " values, frequency_hz " +
                                              std::to_string(*length),
                                          "write one power per frequency");
    }
}

void parse_equivalence_classes(const JsonView& root) {
    const std::optional<JsonView> classes = root.array("equivalence_classes");
    if (!classes) return;
    for (std::size_t i = 0; i < classes->size(); ++i) {
        const JsonView c = classes->element(i);
        if (!expect_object(c, "write {\"name\": ..., \"members\": [...], \"why\": ...}")) continue;
        c.check_known_keys({"name", "members", "why"});
        non_empty_string(c, "name", "write the class's name, e.g. \"camera_roll|gravity_tilt\"");
        string_array(c, "members");
        c.string("why");
    }
}

void parse_control(const JsonView& root) {
    const std::optional<JsonView> control = root.object("discretisation_control", false);
    if (!control) return;
    control->check_known_keys({"refinement", "gap_closed", "discounted_effects", "failure"});
    control->string("refinement");
    nullable_number(*control, "gap_closed", NumberRange{});
    string_array(*control, "discounted_effects");
    if (!control->has("failure")) {
        control->diagnostics().error(json_pointer_child(control->pointer(), "failure"), "missing",
                                     "add \"failure\": null, or why the control could not be measured");
    } else if (!control->json().at("failure").is_null()) {
        control->string("failure");
    }
}

}  // namespace

std::optional<Diagnosis> parse_diagnosis(const nlohmann::json& document, Diagnostics& diagnostics, Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!detail::check_integer_format_header(root, kDiagnosisFormatName, kDiagnosisFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "kind", "trials", "model", "gap", "verdict", "discretisation_control",
                           "candidates", "model_candidates", "null_refit", "frames", "maps", "spectrum", "equivalence_classes", "evaluations",
                           "seconds"});
    Diagnosis out;
    const std::optional<std::string> kind = enumerated(root, "kind", kKinds);
    const std::optional<std::vector<std::string>> trials = string_array(root, "trials");
    if (trials && trials->empty())
        diagnostics.error("/trials", "no trials", "list the capture folders that were diagnosed");
    root.object("model");  // free-form: how the base model was set up
    const std::optional<DiagnosisGap> gap = parse_gap(root);
    const std::optional<DiagnosisVerdict> verdict = parse_verdict(root);
    // "no_gap" with a gap detected: the model's own terms closed it (no effect of the world is left).
    if (gap && verdict && gap->detected == (verdict->status == "no_gap") && !(gap->detected && !verdict->model_terms.empty()))
        diagnostics.error("/verdict/status",
                          gap->detected ? "\"no_gap\" although /gap/detected is true and no model term was named"
                                        : "\"" + verdict->status + "\" although /gap/detected is false",
                          "the status is \"no_gap\" exactly when no gap was detected or the named model terms closed it");
    parse_control(root);
    parse_candidates(root, "candidates");
    if (root.has("model_candidates")) parse_candidates(root, "model_candidates");
    if (const std::optional<JsonView> null_refit = root.object("null_refit")) {
        null_refit->check_known_keys({"base_changes", "held_out_score"});
        parse_base_changes(*null_refit, "base_changes");
        nullable_number(*null_refit, "held_out_score", NumberRange::non_negative("(floors)"));
    }
    parse_frames(root, trials ? trials->size() : 0);
    parse_maps(root);
    parse_spectrum(root);
    parse_equivalence_classes(root);
    const std::optional<std::int64_t> evaluations = root.integer("evaluations", 0, std::numeric_limits<std::int64_t>::max());
    const std::optional<double> seconds = root.number("seconds", NumberRange::non_negative("s"));
    if (diagnostics.has_errors() || !kind || !trials || !gap || !verdict || !evaluations || !seconds) return std::nullopt;
    out.kind = *kind;
    out.trials = *trials;
    out.gap = *gap;
    out.verdict = *verdict;
    out.evaluations = *evaluations;
    out.seconds = *seconds;
    out.document = document;
    return out;
}

Diagnosis read_diagnosis(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<Diagnosis>(path, parse_diagnosis, warnings);
}

void write_diagnosis(const std::string& path, const nlohmann::json& document) {
    detail::write_validated_json(path, document, parse_diagnosis);
}

std::vector<Problem> validate_diagnosis_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_diagnosis);
}

nlohmann::json summarize_diagnosis(const Diagnosis& d) {
    const auto number = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
    return {{"format", kDiagnosisFormatName},
            {"diagnosis_kind", d.kind},
            {"trials", d.trials},
            {"gap_detected", d.gap.detected},
            {"held_out_over_floor", number(d.gap.ratio)},
            {"threshold", d.gap.threshold},
            {"verdict", d.verdict.status},
            {"effects", d.verdict.effects},
            {"class", d.verdict.effect_class},
            {"gap_closed", number(d.verdict.gap_closed)},
            {"message", d.verdict.message},
            {"candidates", d.document.contains("candidates") ? d.document.at("candidates").size() : 0},
            {"frames", d.document.contains("frames") ? d.document.at("frames").size() : 0},
            {"evaluations", d.evaluations},
            {"seconds", d.seconds}};
}

}  // namespace flowvid::formats
