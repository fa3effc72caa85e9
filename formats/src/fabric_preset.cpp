#include "flowvid/formats/fabric_preset.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <cmath>
#include <ostream>
#include <regex>
#include <string>

namespace flowvid::formats {

const std::vector<FabricParameterInfo>& fabric_parameter_table() {
    using P = FabricParameters;
    static const std::vector<FabricParameterInfo> table = {
        {"areal_density_kg_per_m2", "kg/m^2", false, "mass per rest area", &P::areal_density_kg_per_m2},
        {"stretch_warp_stiffness_N_per_m", "N/m", false, "stretch stiffness along warp (u), per rest area",
         &P::stretch_warp_stiffness_N_per_m},
        {"stretch_weft_stiffness_N_per_m", "N/m", false, "stretch stiffness along weft (v), per rest area",
         &P::stretch_weft_stiffness_N_per_m},
        {"shear_stiffness_N_per_m", "N/m", false, "in-plane shear stiffness, per rest area", &P::shear_stiffness_N_per_m},
        {"bend_stiffness_N_m", "N m", true, "bending stiffness per edge, scaled by |e|^2/(A1+A2)", &P::bend_stiffness_N_m},
        {"stretch_warp_damping_N_s_per_m", "N s/m", true, "stretch damping along warp, per rest area",
         &P::stretch_warp_damping_N_s_per_m},
        {"stretch_weft_damping_N_s_per_m", "N s/m", true, "stretch damping along weft, per rest area",
         &P::stretch_weft_damping_N_s_per_m},
        {"shear_damping_N_s_per_m", "N s/m", true, "shear damping, per rest area", &P::shear_damping_N_s_per_m},
        {"bend_damping_N_m_s", "N m s", true, "bending damping per edge, scaled like bend stiffness", &P::bend_damping_N_m_s},
        {"drag_normal_kg_per_m3", "kg/m^3", true, "kN: quadratic drag on the normal relative velocity", &P::drag_normal_kg_per_m3},
        {"drag_degradation_s2_per_m2", "s^2/m^2", true, "kf: how the normal drag saturates at speed (drag crisis)",
         &P::drag_degradation_s2_per_m2},
        {"drag_tangential_kg_per_m2_s", "kg/(m^2 s)", true, "kT: linear drag on the tangential relative velocity",
         &P::drag_tangential_kg_per_m2_s},
        {"stretch_warp_compression_ratio", "1", false,
         "compressive over tensile warp stiffness (1: symmetric; woven fabric buckles, so < 1)",
         &P::stretch_warp_compression_ratio, "1.1", 1.0},
        {"stretch_weft_compression_ratio", "1", false, "compressive over tensile weft stiffness",
         &P::stretch_weft_compression_ratio, "1.1", 1.0},
        {"drag_linear_normal_kg_per_m2_s", "kg/(m^2 s)", true, "kL: linear drag on the normal relative velocity",
         &P::drag_linear_normal_kg_per_m2_s, "1.1", 0.0},
        {"hem_line_density_kg_per_m", "kg/m", true,
         "extra mass per metre of the cloth's free boundary (a hem or selvedge), on top of the areal density",
         &P::hem_line_density_kg_per_m, "1.1", 0.0},
        {"diagonal_tension_stiffness_N_per_m", "N/m", true,
         "tension-only fibres along both diagonals of the weave (they resist shear where pulled, not in folds)",
         &P::diagonal_tension_stiffness_N_per_m, "1.1", 0.0},
        {"shear_cell_fraction", "1", true,
         "share (0..1) of the shear stiffness read on a grid mesh's cells, at all four corners, where a fold along "
         "either diagonal is not shear, instead of across each triangle (0: across each triangle)",
         &P::shear_cell_fraction, "1.2", 0.0},
    };
    return table;
}

bool FabricParameterInfo::optional() const { return std::string(since) != "1.0"; }

bool FabricParameters::operator==(const FabricParameters& other) const {
    for (const FabricParameterInfo& info : fabric_parameter_table())
        if (!(this->*info.member == other.*info.member)) return false;
    return true;
}

namespace {

constexpr const char* kMethods[] = {"fit", "manual", "adapter_export"};

std::optional<FabricParameter> parse_parameter(const JsonView& parameters, const FabricParameterInfo& info) {
    if (info.optional() && !parameters.has(info.key)) return FabricParameter{info.neutral, {}, {}};
    std::optional<JsonView> entry = parameters.object(info.key);
    if (!entry) return std::nullopt;
    entry->check_known_keys({"value", "uncertainty", "range"});
    const NumberRange value_range =
        info.zero_allowed ? NumberRange::non_negative(info.unit) : NumberRange::positive(info.unit);
    FabricParameter parameter;
    std::optional<double> value = entry->number("value", value_range);
    std::optional<double> uncertainty = entry->number("uncertainty", NumberRange::non_negative(info.unit), false);
    std::optional<std::vector<double>> range = entry->numbers("range", 2, NumberRange::non_negative(info.unit), false);
    if (!value) return std::nullopt;
    parameter.value = *value;
    parameter.uncertainty = uncertainty;
    if (range) {
        const std::string where = json_pointer_child(entry->pointer(), "range");
        if ((*range)[0] > (*range)[1]) {
            entry->diagnostics().error(where, "min is greater than max", "write [min, max] with min <= max");
            return std::nullopt;
        }
        if (*value < (*range)[0] || *value > (*range)[1]) {
            entry->diagnostics().error(json_pointer_child(entry->pointer(), "value"),
                                       "value lies outside its own valid range",
                                       "widen \"range\" or correct \"value\"");
            return std::nullopt;
        }
        parameter.range = std::array<double, 2>{(*range)[0], (*range)[1]};
    }
    return parameter;
}

std::optional<FabricProvenance> parse_provenance(const JsonView& root) {
    std::optional<JsonView> view = root.object("provenance");
    if (!view) return std::nullopt;
    view->check_known_keys({"method", "created_utc", "captures", "metric", "metric_weights", "optimizer", "seed",
                            "final_errors", "simulator", "integrator", "time_step_s", "swatch_edge_length_m",
                            "notes"});
    Diagnostics& diag = view->diagnostics();
    FabricProvenance provenance;
    const std::size_t problems_before = diag.problems().size();

    provenance.method = view->string("method").value_or("");
    if (view->has("method") && !provenance.method.empty()) {
        bool known = false;
        for (const char* method : kMethods) known = known || provenance.method == method;
        if (!known)
            diag.error(view->pointer() + "/method", "unknown method \"" + provenance.method + "\"",
                       "use \"fit\", \"manual\" or \"adapter_export\"");
    }
    provenance.created_utc = view->string("created_utc").value_or("");
    static const std::regex iso8601(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z)");
    if (view->has("created_utc") && view->json()["created_utc"].is_string() &&
        !std::regex_match(provenance.created_utc, iso8601))
        diag.error(view->pointer() + "/created_utc", "\"" + provenance.created_utc + "\" is not an ISO 8601 UTC time",
                   "write it as YYYY-MM-DDThh:mm:ssZ");

    const bool fitted = provenance.method == "fit";
    if (std::optional<JsonView> captures = view->array("captures", fitted)) {
        if (fitted && captures->size() == 0)
            diag.error(captures->pointer(), "a fitted preset names no capture", "list the captures the fit used");
        static const std::regex sha256(R"([0-9a-f]{64})");
        for (std::size_t i = 0; i < captures->size(); ++i) {
            JsonView item = captures->element(i);
            if (!item.json().is_object()) {
                diag.error(item.pointer(), "expected an object", "write {\"path\", \"capture_json_sha256\", \"test\"}");
                continue;
            }
            item.check_known_keys({"path", "capture_json_sha256", "test"});
            CaptureReference reference;
            reference.path = item.string("path").value_or("");
            reference.capture_json_sha256 = item.string("capture_json_sha256").value_or("");
            if (item.has("capture_json_sha256") && item.json()["capture_json_sha256"].is_string() &&
                !std::regex_match(reference.capture_json_sha256, sha256))
                diag.error(item.pointer() + "/capture_json_sha256", "not 64 lower-case hex digits",
                           "write the SHA-256 of the capture's capture.json (sha256sum prints it)");
            reference.test = item.string("test").value_or("");
            if (!reference.test.empty() && reference.test != "static" && reference.test != "waving")
                diag.error(item.pointer() + "/test", "unknown test \"" + reference.test + "\"",
                           "use \"static\" or \"waving\"");
            provenance.captures.push_back(reference);
        }
    }
    provenance.metric = view->string("metric", fitted).value_or("");
    if (std::optional<JsonView> weights = view->object("metric_weights", false)) {
        for (auto it = weights->json().begin(); it != weights->json().end(); ++it) {
            if (std::optional<double> weight = weights->number(it.key(), NumberRange::non_negative("")))
                provenance.metric_weights[it.key()] = *weight;
        }
    }
    provenance.optimizer = view->string("optimizer", fitted).value_or("");
    if (std::optional<std::int64_t> seed = view->integer("seed", 0, INT64_MAX, fitted))
        provenance.seed = static_cast<std::uint64_t>(*seed);
    if (std::optional<JsonView> errors = view->array("final_errors", fitted)) {
        for (std::size_t i = 0; i < errors->size(); ++i) {
            JsonView item = errors->element(i);
            if (!item.json().is_object()) {
                diag.error(item.pointer(), "expected an object", "write {\"capture\": ..., \"error\": ...}");
                continue;
            }
            item.check_known_keys({"capture", "error"});
            TrialError trial;
            trial.capture = item.string("capture").value_or("");
            trial.error = item.number("error", NumberRange::non_negative("")).value_or(0.0);
            provenance.final_errors.push_back(trial);
        }
    }
    provenance.simulator = view->string("simulator", fitted).value_or("");
    provenance.integrator = view->string("integrator", fitted).value_or("");
    provenance.time_step_s = view->number("time_step_s", NumberRange::positive("s"), false);
    provenance.swatch_edge_length_m = view->number("swatch_edge_length_m", NumberRange::positive("m"), fitted);
    provenance.notes = view->string("notes", false).value_or("");

    for (std::size_t i = problems_before; i < diag.problems().size(); ++i)
        if (diag.problems()[i].severity == Problem::Severity::error) return std::nullopt;
    return provenance;
}

std::optional<FabricAdapter> parse_adapter(const JsonView& adapter) {
    adapter.check_known_keys({"settings", "calibrated_for", "rms_vertex_error_m", "notes"});
    Diagnostics& diag = adapter.diagnostics();
    const std::size_t problems_before = diag.problems().size();
    FabricAdapter result;
    auto scalar_object = [&](const char* key, bool required, nlohmann::json& out) {
        std::optional<JsonView> values = adapter.object(key, required);
        if (!values) return;
        for (auto it = values->json().begin(); it != values->json().end(); ++it) {
            const nlohmann::json& value = it.value();
            if (value.is_number()) values->number(it.key(), NumberRange{});
            else if (!value.is_boolean() && !value.is_string())
                diag.error(json_pointer_child(values->pointer(), it.key()),
                           std::string("expected a number, true/false or a string, found ") + value.type_name(),
                           "adapter settings are flat: one scalar per setting");
        }
        out = values->json();
    };
    scalar_object("settings", true, result.settings);
    scalar_object("calibrated_for", false, result.calibrated_for);
    result.rms_vertex_error_m = adapter.number("rms_vertex_error_m", NumberRange::non_negative("m"), false);
    result.notes = adapter.string("notes", false).value_or("");
    for (std::size_t i = problems_before; i < diag.problems().size(); ++i)
        if (diag.problems()[i].severity == Problem::Severity::error) return std::nullopt;
    return result;
}

nlohmann::json parameter_to_json(const FabricParameter& parameter) {
    nlohmann::json entry = {{"value", parameter.value}};
    if (parameter.uncertainty) entry["uncertainty"] = *parameter.uncertainty;
    if (parameter.range) entry["range"] = {(*parameter.range)[0], (*parameter.range)[1]};
    return entry;
}

}  // namespace

std::optional<FabricPreset> parse_fabric_preset(const nlohmann::json& document, Diagnostics& diagnostics,
                                                Strictness strictness) {
    JsonView root(document, "", diagnostics, strictness);
    if (!check_format_header(root, kFabricFormatName, kFabricFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "name", "description", "parameters", "provenance", "adapters"});

    FabricPreset preset;
    preset.name = root.string("name").value_or("");
    if (root.has("name") && root.json()["name"].is_string() && preset.name.empty())
        diagnostics.error("/name", "empty name", "name the fabric, e.g. \"cotton poplin\"");
    preset.description = root.string("description", false).value_or("");

    if (std::optional<JsonView> parameters = root.object("parameters")) {
        std::vector<const char*> known;
        for (const FabricParameterInfo& info : fabric_parameter_table()) {
            known.push_back(info.key);
            if (std::optional<FabricParameter> parameter = parse_parameter(*parameters, info))
                preset.parameters.*info.member = *parameter;
        }
        // check_known_keys takes an initializer list; compare against the table directly.
        for (auto it = parameters->json().begin(); it != parameters->json().end(); ++it) {
            bool found = false;
            for (const char* key : known) found = found || it.key() == key;
            if (found) continue;
            const std::string where = json_pointer_child(parameters->pointer(), it.key());
            const std::string fix = "remove it or use one of the parameters listed in formats/specs/fabric_preset.md";
            if (strictness == Strictness::strict) diagnostics.error(where, "unknown parameter", fix);
            else diagnostics.warning(where, "unknown parameter (ignored)", fix);
        }
    }
    if (std::optional<FabricProvenance> provenance = parse_provenance(root)) preset.provenance = *provenance;
    if (std::optional<JsonView> adapters = root.object("adapters", false)) {
        for (auto it = adapters->json().begin(); it != adapters->json().end(); ++it) {
            JsonView adapter = adapters->child(it.key());
            if (!adapter.json().is_object()) {
                diagnostics.error(adapter.pointer(), "expected an object", "write {\"settings\": {...}}");
                continue;
            }
            if (std::optional<FabricAdapter> parsed = parse_adapter(adapter)) preset.adapters[it.key()] = *parsed;
        }
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return preset;
}

nlohmann::json fabric_preset_to_json(const FabricPreset& preset) {
    nlohmann::json document = nlohmann::json::object();
    document["format"] = kFabricFormatName;
    document["version"] = kFabricFormatVersion.to_string();
    document["name"] = preset.name;
    if (!preset.description.empty()) document["description"] = preset.description;
    nlohmann::json parameters = nlohmann::json::object();
    for (const FabricParameterInfo& info : fabric_parameter_table())
        parameters[info.key] = parameter_to_json(preset.parameters.*info.member);
    document["parameters"] = parameters;

    const FabricProvenance& p = preset.provenance;
    nlohmann::json provenance = {{"method", p.method}, {"created_utc", p.created_utc}};
    if (!p.captures.empty() || p.method == "fit") {
        provenance["captures"] = nlohmann::json::array();
        for (const CaptureReference& c : p.captures)
            provenance["captures"].push_back({{"path", c.path}, {"capture_json_sha256", c.capture_json_sha256}, {"test", c.test}});
    }
    if (!p.metric.empty()) provenance["metric"] = p.metric;
    if (!p.metric_weights.empty()) provenance["metric_weights"] = p.metric_weights;
    if (!p.optimizer.empty()) provenance["optimizer"] = p.optimizer;
    if (p.seed) provenance["seed"] = *p.seed;
    if (!p.final_errors.empty() || p.method == "fit") {
        provenance["final_errors"] = nlohmann::json::array();
        for (const TrialError& e : p.final_errors) provenance["final_errors"].push_back({{"capture", e.capture}, {"error", e.error}});
    }
    if (!p.simulator.empty()) provenance["simulator"] = p.simulator;
    if (!p.integrator.empty()) provenance["integrator"] = p.integrator;
    if (p.time_step_s) provenance["time_step_s"] = *p.time_step_s;
    if (p.swatch_edge_length_m) provenance["swatch_edge_length_m"] = *p.swatch_edge_length_m;
    if (!p.notes.empty()) provenance["notes"] = p.notes;
    document["provenance"] = provenance;

    if (!preset.adapters.empty()) {
        nlohmann::json adapters = nlohmann::json::object();
        for (const auto& [simulator, adapter] : preset.adapters) {
            nlohmann::json entry = {{"settings", adapter.settings}};
            if (!adapter.calibrated_for.empty()) entry["calibrated_for"] = adapter.calibrated_for;
            if (adapter.rms_vertex_error_m) entry["rms_vertex_error_m"] = *adapter.rms_vertex_error_m;
            if (!adapter.notes.empty()) entry["notes"] = adapter.notes;
            adapters[simulator] = entry;
        }
        document["adapters"] = adapters;
    }
    return document;
}

namespace {
// JSON cannot hold NaN or infinity (they turn into null), so check them on the
// values before conversion, naming the parameter.
void check_finite_before_writing(const FabricPreset& preset, Diagnostics& diagnostics) {
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        const FabricParameter& p = preset.parameters.*info.member;
        const std::string where = std::string("/parameters/") + info.key;
        if (!std::isfinite(p.value)) diagnostics.error(where + "/value", "not a finite number", "fix the value before saving");
        if (p.uncertainty && !std::isfinite(*p.uncertainty))
            diagnostics.error(where + "/uncertainty", "not a finite number", "drop the uncertainty or fix it");
    }
}
}  // namespace

FabricPreset read_fabric_preset(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<FabricPreset>(path, parse_fabric_preset, warnings);
}

void check_fabric_preset_before_writing(const std::string& path, const FabricPreset& preset) {
    Diagnostics diagnostics(path);
    check_finite_before_writing(preset, diagnostics);
    diagnostics.throw_if_errors();
    parse_fabric_preset(fabric_preset_to_json(preset), diagnostics, Strictness::strict);
    diagnostics.throw_if_errors();
}

void write_fabric_preset(const std::string& path, const FabricPreset& preset) {
    // Validated exactly as it will be written, with the reader's own rules.
    check_fabric_preset_before_writing(path, preset);
    const std::string text = dump_json(fabric_preset_to_json(preset));
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

std::vector<Problem> validate_fabric_preset_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    if (std::optional<std::string> text = read_text_reporting(path, diagnostics))
        if (std::optional<nlohmann::json> document = parse_json_text(*text, diagnostics))
            parse_fabric_preset(*document, diagnostics, strictness);
    return diagnostics.problems();
}

nlohmann::json summarize_fabric_preset(const FabricPreset& preset) {
    nlohmann::json summary = {{"format", kFabricFormatName}, {"name", preset.name}};
    if (!preset.description.empty()) summary["description"] = preset.description;
    nlohmann::json parameters = nlohmann::json::object();
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        const FabricParameter& p = preset.parameters.*info.member;
        nlohmann::json entry = {{"value", p.value}, {"unit", info.unit}};
        if (p.uncertainty) entry["uncertainty"] = *p.uncertainty;
        parameters[info.key] = entry;
    }
    summary["parameters"] = parameters;
    summary["provenance"] = {{"method", preset.provenance.method},
                             {"created_utc", preset.provenance.created_utc},
                             {"captures", preset.provenance.captures.size()}};
    if (!preset.provenance.optimizer.empty()) summary["provenance"]["optimizer"] = preset.provenance.optimizer;
    nlohmann::json adapters = nlohmann::json::array();
    for (const auto& [simulator, adapter] : preset.adapters) adapters.push_back(simulator);
    summary["adapters"] = adapters;
    return summary;
}

}  // namespace flowvid::formats
