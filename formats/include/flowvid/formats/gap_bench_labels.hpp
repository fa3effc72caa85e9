#pragma once
// Gap-bench labels (labels.json, format "flowvid.gap_bench_labels", version
// 1): the hidden truth of the sealed cases `flowvid bench gap --out DIR`
// makes (which effect each case holds, at which values, how strong against
// the noise floor). Only `flowvid bench gap --score` reads it; the
// diagnoser never does. formats/specs/gap_bench_labels.md describes every field.
//
// Effect names and parameter keys are those of the gap catalogue
// (libflowvid gap/effects.hpp); this reader checks their form, the command
// that scores checks them against the catalogue.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kGapBenchLabelsFormatName = "flowvid.gap_bench_labels";
inline constexpr int kGapBenchLabelsFormatVersion = 1;  // written as the JSON integer 1

struct GapBenchLabel {
    std::string id;                        // "case": the folder under cases/ and results/, e.g. "case-001"
    std::string kind;                      // "cloth" or "rigid"
    std::string effect;                    // the hidden effect (catalogue name), or "none"
    std::map<std::string, double> values;  // its parameters (SI, unit in the key); empty for "none"
    std::string scene;                     // the capture the case's camera (and body) came from
    std::optional<std::string> fabric;     // cloth: the fabric preset the footage was made with
    double effect_to_noise = 0.0;          // mean error/floor of the effect-free model on the case (floors)
    std::optional<int> weakened;           // cloth: times the effect was halved to make footage (0-3)

    bool operator==(const GapBenchLabel&) const = default;
};

struct GapBenchLabels {
    std::uint64_t seed = 1;                 // the draw's seed
    std::string footage_mesh = "24x24";     // "RxC" of the footage maker's cloth mesh
    std::string footage_integrator;         // the footage maker's integrator, e.g. "implicit"
    int footage_substeps_per_frame = 10;
    int frames = 30;                        // frames per case
    double strength = 1.0;                  // multiplier of every drawn effect magnitude
    std::vector<GapBenchLabel> cases;

    bool operator==(const GapBenchLabels&) const = default;
};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the labels when valid.
std::optional<GapBenchLabels> parse_gap_bench_labels(const nlohmann::json& document, Diagnostics& diagnostics,
                                                     Strictness strictness = Strictness::lenient);
nlohmann::json gap_bench_labels_to_json(const GapBenchLabels& labels);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
GapBenchLabels read_gap_bench_labels(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates (a NaN is named by its field), then writes atomically.
void write_gap_bench_labels(const std::string& path, const GapBenchLabels& labels);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_gap_bench_labels_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_gap_bench_labels(const GapBenchLabels& labels);

}  // namespace flowvid::formats
