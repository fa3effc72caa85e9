#pragma once
// Blender cloth settings (*.blender.json, format "flowvid.blender_cloth",
// version 1.0): what `flowvid convert PRESET OUT.blender.json --mesh
// GARMENT` writes: the Blender 3.4 ClothSettings values a fabric preset maps
// to on one mesh at one frame rate, the mesh statistics and options the
// mapping used, its intermediate values, and what Blender cannot express.
// formats/specs/blender_cloth_settings.md describes every field.
//
// This is the file's content only: libflowvid cloth/blender_cloth.hpp does
// the mapping (the Blender add-on's, docs/blender.md) and fills it in.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kBlenderClothSettingsFormatName = "flowvid.blender_cloth";
inline constexpr FormatVersion kBlenderClothSettingsFormatVersion{1, 0};
inline constexpr const char* kBlenderClothSolver = "3.4 cloth solver (the add-on's mapping, docs/blender.md)";
inline constexpr const char* kBlenderClothUnits =
    "settings in Blender's ClothSettings units (Speed Multiplier time_scale makes Blender's time seconds-true at this "
    "fps; mass in units of 1/mass_scale kg); mesh statistics and options in SI";

// One numeric ClothSettings property the file holds: its name in Blender's
// Python API (bpy.types.ClothSettings) and Blender 3.4's hard limits. The
// file holds every one of them, in this order, and no other.
struct BlenderClothSettingRange {
    const char* name;
    double min;
    double max;
    bool integer;      // "quality" (substeps per frame) is an integer
    const char* unit;  // for messages and the spec
};
const std::vector<BlenderClothSettingRange>& blender_cloth_setting_ranges();
// Blender's ClothSettings.bending_model values.
inline constexpr const char* kBlenderBendingModels[] = {"ANGULAR", "LINEAR"};

// The garment as Blender's cloth sees it (after the object's scale).
struct BlenderClothMesh {
    std::string path;                 // the mesh file as given to --mesh
    int vertex_count = 0;             // >= 3
    double mean_edge_length_m = 0.0;  // > 0: Blender's avg_spring_len
    double area_m2 = 0.0;             // > 0
    double quad_fraction = 1.0;       // faces with 4 corners / all faces, [0, 1]
    double boundary_length_m = 0.0;   // >= 0: edges of one face only

    bool operator==(const BlenderClothMesh&) const = default;
};

struct BlenderClothScene {
    double fps = 24.0;  // scene frames per second, > 0
    int quality = 0;    // the cloth's substeps per frame before the mapping raised it, >= 0

    bool operator==(const BlenderClothScene&) const = default;
};

struct BlenderClothMappingOptions {
    double mass_scale = 1000.0;             // Blender mass units per kg, > 0
    double reference_speed_m_per_s = 0.5;   // where quadratic drag is matched by linear drag, > 0
    int min_quality = 10;                   // substeps per frame the mapping raises quality to, >= 1

    bool operator==(const BlenderClothMappingOptions&) const = default;
};

struct BlenderClothSettings {
    std::string preset;                      // the fabric preset's name
    std::string blender = kBlenderClothSolver;
    std::string units = kBlenderClothUnits;
    // ClothSettings name -> value, in blender_cloth_setting_ranges() order
    // (the add-on's); "quality" holds an integer.
    std::vector<std::pair<std::string, double>> settings;
    std::string bending_model = "ANGULAR";   // written inside "settings"
    BlenderClothMesh mesh;
    BlenderClothScene scene;
    BlenderClothMappingOptions options;
    std::map<std::string, double> derived;   // the mapping's intermediate values (unit in the name), each >= 0
    std::vector<std::string> not_represented;  // notes: what Blender cannot express, each clamp

    // The value of one setting (nullopt when the list does not hold it).
    std::optional<double> setting(const std::string& name) const;

    bool operator==(const BlenderClothSettings&) const = default;
};

// Validates a parsed document (every problem into `diagnostics`, named by its
// JSON pointer with a fix) and returns the settings when valid.
std::optional<BlenderClothSettings> parse_blender_cloth_settings(const nlohmann::json& document, Diagnostics& diagnostics,
                                                                 Strictness strictness = Strictness::lenient);
nlohmann::json blender_cloth_settings_to_json(const BlenderClothSettings& settings);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
BlenderClothSettings read_blender_cloth_settings(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (a non-finite value is named by its field, then the reader's
// strict rules), then writes atomically: on a problem `path` is left as it was.
void write_blender_cloth_settings(const std::string& path, const BlenderClothSettings& settings);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_blender_cloth_settings_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_blender_cloth_settings(const BlenderClothSettings& settings);

}  // namespace flowvid::formats
