#pragma once
// Fabric preset (*.fabric.json): the portable description of a fitted fabric.
// SI units; every parameter is normalised per rest area (or per edge as stated
// in formats/specs/fabric_preset.md) so that it does not depend on the mesh
// resolution it was fitted on. Format name "flowvid.fabric", version 1.2
// (1.1 and 1.2 added optional parameters whose absence means their neutral
// value, so older files read as the same fabric).

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kFabricFormatName = "flowvid.fabric";
inline constexpr FormatVersion kFabricFormatVersion{1, 2};

// One fitted quantity: its value, an optional 1-sigma uncertainty (same unit),
// and an optional valid range [min, max] it was searched or may be used in.
struct FabricParameter {
    double value = 0.0;
    std::optional<double> uncertainty;
    std::optional<std::array<double, 2>> range;

    bool operator==(const FabricParameter& other) const {
        return value == other.value && uncertainty == other.uncertainty && range == other.range;
    }
};

// The Baraff-Witkin fabric model with the thesis's three-parameter air drag,
// and (since 1.1) softer compression, linear normal drag and a hem, and
// (since 1.2) where a grid mesh reads the shear.
struct FabricParameters {
    FabricParameter areal_density_kg_per_m2;
    FabricParameter stretch_warp_stiffness_N_per_m;   // per rest area: E = k/2 * A * C^2
    FabricParameter stretch_weft_stiffness_N_per_m;
    FabricParameter shear_stiffness_N_per_m;
    FabricParameter bend_stiffness_N_m;               // per edge, scaled by |e|^2 / (A1 + A2)
    FabricParameter stretch_warp_damping_N_s_per_m;
    FabricParameter stretch_weft_damping_N_s_per_m;
    FabricParameter shear_damping_N_s_per_m;
    FabricParameter bend_damping_N_m_s;
    FabricParameter drag_normal_kg_per_m3;            // kN: quadratic normal drag
    FabricParameter drag_degradation_s2_per_m2;       // kf: drag-crisis degradation
    FabricParameter drag_tangential_kg_per_m2_s;      // kT: linear tangential drag
    // Since 1.1; absent in a file = the neutral value given here.
    FabricParameter stretch_warp_compression_ratio{1.0, {}, {}};  // compressive / tensile warp stiffness
    FabricParameter stretch_weft_compression_ratio{1.0, {}, {}};
    FabricParameter drag_linear_normal_kg_per_m2_s{0.0, {}, {}};  // kL: linear drag on the normal relative velocity
    FabricParameter hem_line_density_kg_per_m{0.0, {}, {}};       // extra mass per metre of free boundary
    FabricParameter diagonal_tension_stiffness_N_per_m{0.0, {}, {}};  // tension-only fibres along the weave's diagonals
    // Since 1.2: the share (0..1) of the shear stiffness read on a grid's
    // cells, where a fold along either diagonal is not shear, instead of
    // across each triangle (0: across each triangle, as 1.0 and 1.1 read it).
    FabricParameter shear_cell_fraction{0.0, {}, {}};

    bool operator==(const FabricParameters& other) const;
};

// A table of the parameters: JSON key, unit, whether zero is allowed, and the
// member it fills. One list drives reading, writing, validation and summaries.
// Parameters added after 1.0 are optional: a file without one means its
// neutral value, which reproduces the fabric as that older version read it.
struct FabricParameterInfo {
    const char* key;
    const char* unit;
    bool zero_allowed;
    const char* meaning;
    FabricParameter FabricParameters::*member;
    const char* since = "1.0";  // format version that added it
    double neutral = 0.0;       // the value an absent optional parameter has

    bool optional() const;
};
const std::vector<FabricParameterInfo>& fabric_parameter_table();

struct CaptureReference {
    std::string path;                 // as given to the fit (informative)
    std::string capture_json_sha256;  // 64 lower-case hex digits of capture.json's bytes
    std::string test;                 // "static" or "waving"
    bool operator==(const CaptureReference&) const = default;
};

struct TrialError {
    std::string capture;  // path as in `captures`
    double error = 0.0;   // value of the fit metric on this trial (metric's own unit)
    bool operator==(const TrialError&) const = default;
};

struct FabricProvenance {
    std::string method;                        // "fit", "manual" or "adapter_export"
    std::string created_utc;                   // ISO 8601, e.g. 2026-11-21T10:00:00Z
    std::vector<CaptureReference> captures;    // required for "fit"
    std::string metric;                        // e.g. "angle_map+silhouette"
    std::map<std::string, double> metric_weights;
    std::string optimizer;                     // e.g. "simulated_annealing"
    std::optional<std::uint64_t> seed;
    std::vector<TrialError> final_errors;
    std::string simulator;                     // e.g. "flowvid 0.1.0"
    std::string integrator;                    // e.g. "rk45_adaptive"
    std::optional<double> time_step_s;
    std::optional<double> swatch_edge_length_m;
    std::string notes;
    bool operator==(const FabricProvenance&) const = default;
};

// Simulator-specific settings derived from the preset (e.g. Blender's cloth
// settings) and the conditions they were calibrated for.
struct FabricAdapter {
    nlohmann::json settings = nlohmann::json::object();        // name -> number, bool or string
    nlohmann::json calibrated_for = nlohmann::json::object();  // e.g. mean_edge_length_m, quality, fps
    std::optional<double> rms_vertex_error_m;
    std::string notes;
    bool operator==(const FabricAdapter&) const = default;
};

struct FabricPreset {
    std::string name;
    std::string description;
    FabricParameters parameters;
    FabricProvenance provenance;
    std::map<std::string, FabricAdapter> adapters;  // key: simulator, e.g. "blender"

    bool operator==(const FabricPreset&) const = default;
};

// Validates a parsed document and, when valid, returns the preset. Every
// problem is added to `diagnostics` (errors and warnings).
std::optional<FabricPreset> parse_fabric_preset(const nlohmann::json& document, Diagnostics& diagnostics,
                                                Strictness strictness = Strictness::lenient);
nlohmann::json fabric_preset_to_json(const FabricPreset& preset);

// Reads and validates a file; throws ValidationError (every problem) or IoError.
// Warnings (newer minor version, unknown keys) go to `warnings` when given.
FabricPreset read_fabric_preset(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates, then writes atomically. Throws ValidationError if the preset is
// not valid (e.g. NaN), leaving any previous file untouched.
void write_fabric_preset(const std::string& path, const FabricPreset& preset);
// What every writer of a preset (this format, U3M, USD) checks first: finite
// values and the reader's strict rules on the preset as JSON. Throws
// ValidationError naming `path` and the preset field.
void check_fabric_preset_before_writing(const std::string& path, const FabricPreset& preset);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_fabric_preset_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_fabric_preset(const FabricPreset& preset);

}  // namespace flowvid::formats
