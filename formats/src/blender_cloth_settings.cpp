#include "flowvid/formats/blender_cloth_settings.hpp"

#include "json_extras.hpp"

#include <cmath>

namespace flowvid::formats {

namespace {

constexpr std::int64_t kMaxInt = 2147483647;
constexpr double kMaxFloat = 3.4e38;  // Blender's float properties

const char* const kSettingsFix = "write the settings with `flowvid convert PRESET OUT.blender.json --mesh GARMENT`";

// Refuses a derived value that is not a number >= 0, naming it.
std::map<std::string, double> parse_derived(const JsonView& derived) {
    std::map<std::string, double> out;
    for (auto it = derived.json().begin(); it != derived.json().end(); ++it) {
        if (it.key().empty()) {
            derived.diagnostics().error(json_pointer_child(derived.pointer(), it.key()), "empty name",
                                        "key each derived value by its name with its unit, e.g. \"tau_s\"");
            continue;
        }
        if (const std::optional<double> value = derived.child(it.key()).as_number(NumberRange::non_negative("")))
            out[it.key()] = *value;
    }
    return out;
}

void parse_settings(const JsonView& root, BlenderClothSettings& out) {
    const std::optional<JsonView> settings = root.object("settings");
    if (!settings) return;
    settings->check_known_keys({"quality", "time_scale", "mass", "tension_stiffness", "compression_stiffness",
                                "shear_stiffness", "bending_stiffness", "tension_damping", "compression_damping",
                                "shear_damping", "bending_damping", "air_damping", "bending_model"});
    for (const BlenderClothSettingRange& range : blender_cloth_setting_ranges()) {
        std::optional<double> value;
        if (range.integer) {
            if (const std::optional<std::int64_t> v = settings->integer(range.name, static_cast<std::int64_t>(range.min),
                                                                        static_cast<std::int64_t>(range.max)))
                value = static_cast<double>(*v);
        } else {
            value = settings->number(range.name, NumberRange::closed(range.min, range.max, range.unit));
        }
        if (value) out.settings.emplace_back(range.name, *value);
    }
    if (const std::optional<std::string> model = settings->string("bending_model")) {
        bool known = false;
        for (const char* name : kBlenderBendingModels) known = known || *model == name;
        if (known) out.bending_model = *model;
        else
            root.diagnostics().error(json_pointer_child(settings->pointer(), "bending_model"),
                                     "\"" + *model + "\" is not a Blender bending model",
                                     "write \"ANGULAR\" (what the mapping is made for) or \"LINEAR\"");
    }
}

void parse_mesh(const JsonView& root, BlenderClothMesh& mesh) {
    const std::optional<JsonView> view = root.object("mesh");
    if (!view) return;
    view->check_known_keys({"path", "vertex_count", "mean_edge_length_m", "area_m2", "quad_fraction", "boundary_length_m"});
    mesh.path = detail::non_empty_string(*view, "path", "write the mesh file the settings were mapped for").value_or("");
    mesh.vertex_count = static_cast<int>(view->integer("vertex_count", 3, kMaxInt).value_or(0));
    mesh.mean_edge_length_m = view->number("mean_edge_length_m", NumberRange::positive("m")).value_or(0.0);
    mesh.area_m2 = view->number("area_m2", NumberRange::positive("m^2")).value_or(0.0);
    mesh.quad_fraction = view->number("quad_fraction", NumberRange::closed(0.0, 1.0)).value_or(0.0);
    mesh.boundary_length_m = view->number("boundary_length_m", NumberRange::non_negative("m")).value_or(0.0);
}

// Values JSON cannot hold: named before they would become null.
void check_finite(const BlenderClothSettings& s, Diagnostics& diagnostics) {
    const std::string fix = "the mapping gave no finite value: check the preset's parameters and the mesh (in metres)";
    const auto finite = [&](double value, const std::string& field) {
        if (!std::isfinite(value)) diagnostics.error(field, "not finite", fix);
    };
    for (const auto& [name, value] : s.settings) finite(value, json_pointer_child("/settings", name));
    finite(s.mesh.mean_edge_length_m, "/mesh/mean_edge_length_m");
    finite(s.mesh.area_m2, "/mesh/area_m2");
    finite(s.mesh.quad_fraction, "/mesh/quad_fraction");
    finite(s.mesh.boundary_length_m, "/mesh/boundary_length_m");
    finite(s.scene.fps, "/scene/fps");
    finite(s.options.mass_scale, "/options/mass_scale");
    finite(s.options.reference_speed_m_per_s, "/options/reference_speed_m_per_s");
    for (const auto& [name, value] : s.derived) finite(value, json_pointer_child("/derived", name));
}

}  // namespace

const std::vector<BlenderClothSettingRange>& blender_cloth_setting_ranges() {
    // The add-on's order and Blender 3.4's hard limits of the ClothSettings RNA properties.
    static const std::vector<BlenderClothSettingRange> ranges = {
        {"quality", 1.0, static_cast<double>(kMaxInt), true, "substeps per frame"},
        {"time_scale", 0.0, kMaxFloat, false, "(Speed Multiplier)"},
        {"mass", 0.0, kMaxFloat, false, "(1/mass_scale kg per vertex)"},
        {"tension_stiffness", 0.0, 10000.0, false, "(Blender stiffness)"},
        {"compression_stiffness", 0.0, 10000.0, false, "(Blender stiffness)"},
        {"shear_stiffness", 0.0, 10000.0, false, "(Blender stiffness)"},
        {"bending_stiffness", 0.0, 10000.0, false, "(Blender stiffness)"},
        {"tension_damping", 0.0, 50.0, false, "(Blender damping)"},
        {"compression_damping", 0.0, 50.0, false, "(Blender damping)"},
        {"shear_damping", 0.0, 50.0, false, "(Blender damping)"},
        {"bending_damping", 0.0, 1000.0, false, "(Blender damping)"},
        {"air_damping", 0.0, 10.0, false, "(Blender air viscosity)"},
    };
    return ranges;
}

std::optional<double> BlenderClothSettings::setting(const std::string& name) const {
    for (const auto& [key, value] : settings)
        if (key == name) return value;
    return std::nullopt;
}

std::optional<BlenderClothSettings> parse_blender_cloth_settings(const nlohmann::json& document, Diagnostics& diagnostics,
                                                                 Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!document.is_object()) {
        diagnostics.error("", "a Blender cloth settings file is a JSON object", kSettingsFix);
        return std::nullopt;
    }
    if (!check_format_header(root, kBlenderClothSettingsFormatName, kBlenderClothSettingsFormatVersion))
        return std::nullopt;
    root.check_known_keys({"format", "version", "preset", "blender", "settings", "units", "mesh", "scene", "options",
                           "derived", "not_represented"});
    BlenderClothSettings out;
    out.preset = detail::non_empty_string(root, "preset", "write the fabric preset's name").value_or("");
    out.blender = detail::non_empty_string(root, "blender", "write the Blender solver the settings are for, e.g. \"" +
                                                                std::string(kBlenderClothSolver) + "\"")
                      .value_or("");
    out.units = detail::non_empty_string(root, "units", "write what the settings' units are").value_or("");
    parse_settings(root, out);
    parse_mesh(root, out.mesh);
    if (const std::optional<JsonView> scene = root.object("scene")) {
        scene->check_known_keys({"fps", "quality"});
        out.scene.fps = scene->number("fps", NumberRange::positive("frames/s")).value_or(0.0);
        out.scene.quality = static_cast<int>(scene->integer("quality", 0, kMaxInt).value_or(0));
    }
    if (const std::optional<JsonView> options = root.object("options")) {
        options->check_known_keys({"mass_scale", "reference_speed_m_per_s", "min_quality"});
        out.options.mass_scale = options->number("mass_scale", NumberRange::positive("Blender mass units per kg")).value_or(0.0);
        out.options.reference_speed_m_per_s =
            options->number("reference_speed_m_per_s", NumberRange::positive("m/s")).value_or(0.0);
        out.options.min_quality = static_cast<int>(options->integer("min_quality", 1, kMaxInt).value_or(0));
    }
    if (const std::optional<JsonView> derived = root.object("derived")) out.derived = parse_derived(*derived);
    if (std::optional<std::vector<std::string>> notes = detail::string_array(root, "not_represented"))
        out.not_represented = std::move(*notes);
    if (diagnostics.has_errors()) return std::nullopt;
    return out;
}

nlohmann::json blender_cloth_settings_to_json(const BlenderClothSettings& s) {
    nlohmann::json settings = nlohmann::json::object();
    for (const auto& [name, value] : s.settings) {
        // quality is an integer in Blender: written as one when it is one (else the reader names it).
        if (name == "quality" && std::isfinite(value) && value == std::floor(value) && std::abs(value) < 9e15)
            settings[name] = static_cast<long long>(value);
        else
            settings[name] = value;
    }
    settings["bending_model"] = s.bending_model;
    nlohmann::json derived = nlohmann::json::object();
    for (const auto& [name, value] : s.derived) derived[name] = value;
    // nlohmann objects sort their keys: the file's key order is fixed.
    return {
        {"format", kBlenderClothSettingsFormatName},
        {"version", kBlenderClothSettingsFormatVersion.to_string()},
        {"preset", s.preset},
        {"blender", s.blender},
        {"settings", settings},
        {"units", s.units},
        {"mesh",
         {{"path", s.mesh.path},
          {"vertex_count", s.mesh.vertex_count},
          {"mean_edge_length_m", s.mesh.mean_edge_length_m},
          {"area_m2", s.mesh.area_m2},
          {"quad_fraction", s.mesh.quad_fraction},
          {"boundary_length_m", s.mesh.boundary_length_m}}},
        {"scene", {{"fps", s.scene.fps}, {"quality", s.scene.quality}}},
        {"options",
         {{"mass_scale", s.options.mass_scale},
          {"reference_speed_m_per_s", s.options.reference_speed_m_per_s},
          {"min_quality", s.options.min_quality}}},
        {"derived", derived},
        {"not_represented", s.not_represented},
    };
}

BlenderClothSettings read_blender_cloth_settings(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<BlenderClothSettings>(path, parse_blender_cloth_settings, warnings);
}

void write_blender_cloth_settings(const std::string& path, const BlenderClothSettings& settings) {
    Diagnostics diagnostics(path);
    check_finite(settings, diagnostics);
    diagnostics.throw_if_errors();
    detail::write_validated_json(path, blender_cloth_settings_to_json(settings), parse_blender_cloth_settings);
}

std::vector<Problem> validate_blender_cloth_settings_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_blender_cloth_settings);
}

nlohmann::json summarize_blender_cloth_settings(const BlenderClothSettings& s) {
    return {{"format", kBlenderClothSettingsFormatName},
            {"preset", s.preset},
            {"blender", s.blender},
            {"mesh", s.mesh.path},
            {"vertex_count", s.mesh.vertex_count},
            {"mean_edge_length_mm", s.mesh.mean_edge_length_m * 1000.0},
            {"area_m2", s.mesh.area_m2},
            {"fps", s.scene.fps},
            {"settings", blender_cloth_settings_to_json(s)["settings"]},
            {"not_represented", s.not_represented.size()}};
}

}  // namespace flowvid::formats
