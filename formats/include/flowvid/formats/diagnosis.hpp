#pragma once
// Gap diagnosis (diagnosis.json, format "flowvid.diagnosis", version 1):
// what `flowvid diagnose` and `flowvid bench gap --diagnose` find about where
// a fitted simulation departs from footage (the gap, the verdict, the
// candidates' evidence, per-frame residuals, maps, spectrum). It is read back
// by `flowvid bench gap --score` and turned into report.html.
// formats/specs/diagnosis.md describes every field.
//
// The reader validates the whole document and gives the verdict and the gap
// typed (what scoring needs); the rest stays in `document`, already checked.
// JSON cannot hold NaN or infinity: measured numbers are null when they were
// not finite or not measured, and readers accept that.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kDiagnosisFormatName = "flowvid.diagnosis";
inline constexpr int kDiagnosisFormatVersion = 1;  // written as the JSON integer 1

struct DiagnosisGap {
    bool detected = false;                 // held-out residual beyond threshold x floor (or the base failed)
    std::optional<double> held_out_error;  // sum over held-out frames, the metric's unit
    std::optional<double> held_out_floor;  // sum of their floors, same unit
    std::optional<double> ratio;           // mean held-out error/floor; null without held-out frames
    double threshold = 3.0;                // the ratio above which a gap is structural
    int held_out_frames = 0;
};

struct DiagnosisVerdict {
    std::string status;                 // "no_gap", "named", "unexplained"
    std::vector<std::string> effects;   // named effects, greedy order (non-empty exactly when "named")
    std::string effect_class;           // "class": equivalence class of the first named effect, or ""
    std::string message;                // one sentence for people
    std::optional<double> gap_closed;   // share of the held-out gap the named effects close (null unless named)
    // "model_terms": the cloth model's own terms named before any effect
    // (the preset was fitted without them); optional, empty in older files.
    std::vector<std::string> model_terms;
};

struct Diagnosis {
    std::string kind;                   // "cloth" or "rigid"
    std::vector<std::string> trials;    // the captures diagnosed
    DiagnosisGap gap;
    DiagnosisVerdict verdict;
    long long evaluations = 0;
    double seconds = 0.0;
    nlohmann::json document;            // the whole file, validated
};

inline constexpr const char* kDiagnosisStatuses[] = {"no_gap", "named", "unexplained"};

// Validates a parsed document (every problem into `diagnostics`) and returns
// the diagnosis when valid.
std::optional<Diagnosis> parse_diagnosis(const nlohmann::json& document, Diagnostics& diagnostics,
                                         Strictness strictness = Strictness::lenient);
// Reads and validates; throws IoError (unreadable) or ValidationError (every problem).
Diagnosis read_diagnosis(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates `document` as it will be on disk (non-finite numbers become
// null), strictly, then writes it atomically: 2-space indent, keys sorted, a
// final newline. ValidationError leaves any previous file untouched.
void write_diagnosis(const std::string& path, const nlohmann::json& document);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_diagnosis_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_diagnosis(const Diagnosis& diagnosis);

}  // namespace flowvid::formats
