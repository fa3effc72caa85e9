#include "flowvid/formats/fabric_u3m.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/sha256.hpp"

#include <cmath>
#include <cstdio>
#include <ostream>

namespace flowvid::formats {
namespace {

constexpr const char* kCustomPointer = "/custom/flowvid";
constexpr double kGramsPerKilogram = 1000.0;

// 16 bytes of the preset's SHA-256 shaped as a UUID version 4, variant 1 (the
// schema's uuid4 pattern): stable for the same preset, distinct for another.
std::string preset_uuid(const FabricPreset& preset) {
    std::array<std::uint8_t, 32> hash = sha256(dump_json(fabric_preset_to_json(preset)));
    hash[6] = static_cast<std::uint8_t>((hash[6] & 0x0f) | 0x40);
    hash[8] = static_cast<std::uint8_t>((hash[8] & 0x3f) | 0x80);
    std::string text;
    char byte[3];
    for (int i = 0; i < 16; ++i) {
        if (i == 4 || i == 6 || i == 8 || i == 10) text += '-';
        std::snprintf(byte, sizeof byte, "%02x", hash[static_cast<std::size_t>(i)]);
        text += byte;
    }
    return text;
}

// The preset's own document with each parameter's unit beside its value.
nlohmann::json custom_block(const FabricPreset& preset) {
    nlohmann::json block = fabric_preset_to_json(preset);
    for (const FabricParameterInfo& info : fabric_parameter_table()) block["parameters"][info.key]["unit"] = info.unit;
    block["units"] = "SI; each parameter states its unit; the keys and their meaning are those of flowvid.fabric "
                     "(formats/specs/fabric_preset.md)";
    return block;
}

std::string prefixed(const std::string& field) { return std::string(kCustomPointer) + field; }

}  // namespace

bool looks_like_u3m(const nlohmann::json& document) {
    return document.is_object() && document.contains("schema") && document["schema"].is_string() &&
           document.contains("material") && document["material"].is_object();
}

nlohmann::json fabric_preset_to_u3m(const FabricPreset& preset) {
    const double weight_g_per_m2 = preset.parameters.areal_density_kg_per_m2.value * kGramsPerKilogram;
    nlohmann::json physics = {
        {"thickness", nullptr},            // mm in U3M; a fit does not measure it
        {"weight", weight_g_per_m2},       // g/m^2 in U3M
        {"composition", nullptr},
        {"devices", {{"fab", "null"}}},    // no FAB measurement file (the schema's "no file" value)
        {"material_type", nullptr},
        {"construction", nullptr},
    };
    nlohmann::json material = {
        {"id", preset_uuid(preset)},
        {"name", preset.name},
        {"description", preset.description},
        {"created", preset.provenance.created_utc},
        {"modified", preset.provenance.created_utc},
        {"front", nullptr},
        {"back", nullptr},
        {"side", nullptr},
        {"physics", physics},
        {"metadata", nullptr},
    };
    return {{"schema", kU3mSchemaVersion},
            {"material", material},
            {"custom", {{kU3mCustomKey, custom_block(preset)}}}};
}

std::optional<FabricPreset> parse_fabric_u3m(const nlohmann::json& document, Diagnostics& diagnostics,
                                             Strictness strictness) {
    JsonView root(document, "", diagnostics, strictness);
    if (!document.is_object()) {
        diagnostics.error("", "expected a U3M document (a JSON object)", "give a .u3m written by flowvid convert");
        return std::nullopt;
    }
    if (std::optional<std::string> schema = root.string("schema"); schema && *schema != kU3mSchemaVersion)
        diagnostics.error("/schema", "U3M schema \"" + *schema + "\" is not the version flowvid reads",
                          "flowvid reads and writes U3M 1.1");
    std::optional<double> weight_g_per_m2;
    if (std::optional<JsonView> material = root.object("material")) {
        material->string("name");
        if (std::optional<JsonView> physics = material->object("physics")) {
            if (physics->has("weight") && !physics->json()["weight"].is_null())
                weight_g_per_m2 = physics->number("weight", NumberRange::non_negative("g/m^2"));
        }
    }
    std::optional<JsonView> custom = root.object("custom");
    std::optional<JsonView> block = custom ? custom->object(kU3mCustomKey) : std::nullopt;
    if (custom && !block) {
        // object() has reported it missing; say what that means for this file.
        diagnostics.error(kCustomPointer, "this U3M carries no flowvid fabric preset",
                          "flowvid reads back the U3M files it wrote (flowvid convert PRESET.fabric.json OUT.u3m); "
                          "U3M's standard physics alone do not describe a fabric preset");
    }
    if (diagnostics.has_errors() || !block) return std::nullopt;

    // The units flowvid writes beside each value must be the SI units of the
    // preset format; then the block is the preset document itself.
    nlohmann::json preset_document = block->json();
    preset_document.erase("units");
    if (preset_document.contains("parameters") && preset_document["parameters"].is_object()) {
        nlohmann::json& parameters = preset_document["parameters"];
        for (const FabricParameterInfo& info : fabric_parameter_table()) {
            auto entry = parameters.find(info.key);
            if (entry == parameters.end() || !entry->is_object() || !entry->contains("unit")) continue;
            const nlohmann::json& unit = (*entry)["unit"];
            if (!unit.is_string() || unit.get<std::string>() != info.unit)
                diagnostics.error(prefixed(std::string("/parameters/") + info.key + "/unit"),
                                  "unit " + unit.dump() + " is not the SI unit of this parameter",
                                  std::string("write the value in ") + info.unit + " and set \"unit\": \"" +
                                      info.unit + "\"");
            entry->erase("unit");
        }
    }
    Diagnostics inner(diagnostics.file());
    std::optional<FabricPreset> preset = parse_fabric_preset(preset_document, inner, strictness);
    std::vector<Problem> problems = inner.problems();
    for (Problem& problem : problems) problem.field = prefixed(problem.field);
    diagnostics.merge(problems);
    if (diagnostics.has_errors() || !preset) return std::nullopt;

    if (weight_g_per_m2) {
        const double expected = preset->parameters.areal_density_kg_per_m2.value * kGramsPerKilogram;
        if (std::abs(*weight_g_per_m2 - expected) > 1e-9 * std::max(1.0, expected))
            diagnostics.warning("/material/physics/weight",
                                "weight " + std::to_string(*weight_g_per_m2) + " g/m^2 differs from the preset's areal "
                                "density (" + std::to_string(expected) + " g/m^2); the preset's value is used",
                                "edit " + prefixed("/parameters/areal_density_kg_per_m2/value") +
                                    " (kg/m^2) to change the fabric's weight");
    }
    return preset;
}

void write_fabric_u3m(const std::string& path, const FabricPreset& preset) {
    check_fabric_preset_before_writing(path, preset);  // finite values, valid ranges, naming the preset field
    const nlohmann::json document = fabric_preset_to_u3m(preset);
    // Read back exactly what will be written, with the reader's rules.
    Diagnostics check(path);
    parse_fabric_u3m(document, check, Strictness::strict);
    check.throw_if_errors();
    const std::string text = dump_json(document);
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

FabricPreset read_fabric_u3m(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<FabricPreset>(path, parse_fabric_u3m, warnings);
}

std::vector<Problem> validate_fabric_u3m_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    if (std::optional<std::string> text = read_text_reporting(path, diagnostics))
        if (std::optional<nlohmann::json> document = parse_json_text(*text, diagnostics))
            parse_fabric_u3m(*document, diagnostics, strictness);
    return diagnostics.problems();
}

}  // namespace flowvid::formats
