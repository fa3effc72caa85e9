#pragma once
// A fabric preset as an OpenUSD physics material in text form (*.usda),
// following the deformable-body physics proposal (OpenUSD-proposals pull
// request 111, proposals/physics_deformables/wp_deformable_physics.md).
// Spec page: formats/specs/fabric_usda.md.
//
// The file is one `def Material "Fabric"` with the proposal's
// PhysicsMaterialAPI and PhysicsSurfaceDeformableMaterialAPI applied:
//   float physics:surfaceStretchStiffness  force/distance (N/m): mean of warp and weft
//   float physics:surfaceShearStiffness    force/distance (N/m)
//   float physics:surfaceBendStiffness     force*distance (N m)
//   float physics:density                  mass/distance^3 (kg/m^3): the areal density over
//                                          the proposal's default shell thickness (1e-3 m)
// with the layer's units stated (metersPerUnit = 1, kilogramsPerUnit = 1).
// The proposal has no damping, drag, compression or hem: every preset
// parameter (SI, unit in the name as in the preset) with its uncertainty and
// range is also written in the `flowvid:` namespace, as doubles, and that is
// what the reader takes back; name, description, provenance and adapters too.
//
// Debian has no USD library, so this module writes the text itself and reads
// it with a small parser of the usda subset that such a file uses (layer
// metadata, prims with metadata, attributes with scalar, tuple and array
// values, dictionaries); anything else is reported with its line.

#include "flowvid/error.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kFabricUsdaPrimName = "Fabric";
inline constexpr const char* kFabricUsdaNamespace = "flowvid:";
// The shell thickness the proposal assumes where physics:thicknesses is not
// authored; physics:density is written for it.
inline constexpr double kUsdDefaultShellThicknessM = 1e-3;

// ---- The usda subset -------------------------------------------------------

struct UsdaAttribute {
    std::string name;     // namespaced, e.g. "physics:surfaceBendStiffness"
    std::string type;     // "float", "double", "double2", "string", "float[]", ...
    bool custom = false;
    bool uniform = false;
    nlohmann::json value; // number, string, bool, array (tuple or array); null when unauthored
    nlohmann::json metadata = nlohmann::json::object();  // e.g. {"doc": "..."}
    int line = 0;
};

struct UsdaPrim {
    std::string specifier;  // "def", "over" or "class"
    std::string type_name;  // e.g. "Material" (empty for a typeless prim)
    std::string name;
    nlohmann::json metadata = nlohmann::json::object();  // e.g. {"apiSchemas": [...], "doc": "..."}
    std::vector<UsdaAttribute> attributes;
    std::vector<UsdaPrim> children;
    int line = 0;

    const UsdaAttribute* attribute(const std::string& attribute_name) const;
};

struct UsdaLayer {
    nlohmann::json metadata = nlohmann::json::object();  // e.g. {"metersPerUnit": 1, "customLayerData": {...}}
    std::vector<UsdaPrim> prims;
};

// Parses usda text; problems name the line ("line 12") and what was expected.
std::optional<UsdaLayer> parse_usda(const std::string& text, Diagnostics& diagnostics);

// ---- Fabric presets --------------------------------------------------------

std::string fabric_preset_to_usda(const FabricPreset& preset);
// The preset in the layer's flowvid: attributes, checked with the preset's own
// rules (problems name the attribute, e.g. /Fabric.flowvid:bend_stiffness_N_m);
// the proposal's attributes are checked against those values in the layer's
// units (a mismatch is a warning: someone edited one of them).
std::optional<FabricPreset> parse_fabric_usda(const std::string& text, Diagnostics& diagnostics,
                                              Strictness strictness = Strictness::lenient);

void write_fabric_usda(const std::string& path, const FabricPreset& preset);
FabricPreset read_fabric_usda(const std::string& path, std::vector<Problem>* warnings = nullptr);
std::vector<Problem> validate_fabric_usda_file(const std::string& path, Strictness strictness);

}  // namespace flowvid::formats
