#pragma once
// A fabric preset as a U3M 1.1 material (*.u3m), for garment tools that read
// the Unified 3D Material format (schema: github.com/vizoogmbh/u3m,
// u3m1.1/spec/u3m_schema.json). Spec page: formats/specs/fabric_u3m.md.
//
// Why plain JSON: in U3M 1.1 a *.u3m is the JSON document the schema
// describes, and *.u3ma is the zip archive packing one *.u3m with the images
// it references (u3m1.1/readme.txt, spec/u3m_additional_spec_u3ma.txt). A
// preset references no image, so a *.u3m alone carries everything.
//
// What goes where: the schema's physics object is closed (no extra keys) and
// has one field a preset maps to honestly, "weight" (areal density, in g/m^2
// as the schema states); thickness, composition, material and construction
// type are not known from a fit and are written as null. The preset itself
// (every parameter in SI with its unit, uncertainty and range, the
// provenance and the adapters) goes into the document's top-level "custom"
// object under the key "flowvid", the place U3M gives a company's own data.

#include "flowvid/error.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kU3mSchemaVersion = "1.1";
inline constexpr const char* kU3mCustomKey = "flowvid";  // our block: /custom/flowvid

// The U3M 1.1 document for a preset. The material id is a UUID4-shaped
// identifier derived from the SHA-256 of the preset, so the same preset always
// gives the same file; created/modified are the preset's provenance time.
nlohmann::json fabric_preset_to_u3m(const FabricPreset& preset);

// Reads back a U3M written by fabric_preset_to_u3m: the preset in
// /custom/flowvid, checked with the fabric preset's own rules (problems name
// their field inside the U3M, e.g. /custom/flowvid/parameters/.../value), each
// unit checked against the SI unit flowvid writes, and physics.weight checked
// against the areal density (a mismatch is a warning: someone edited one).
std::optional<FabricPreset> parse_fabric_u3m(const nlohmann::json& document, Diagnostics& diagnostics,
                                             Strictness strictness = Strictness::lenient);

// Validates the preset, then writes atomically. Throws ValidationError.
void write_fabric_u3m(const std::string& path, const FabricPreset& preset);
// Throws IoError (unreadable) or ValidationError (every problem).
FabricPreset read_fabric_u3m(const std::string& path, std::vector<Problem>* warnings = nullptr);
std::vector<Problem> validate_fabric_u3m_file(const std::string& path, Strictness strictness);

// True when a JSON document looks like a U3M (a "schema" string and a
// "material" object at the top level).
bool looks_like_u3m(const nlohmann::json& document);

}  // namespace flowvid::formats
