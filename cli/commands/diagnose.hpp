#pragma once
// What `flowvid diagnose` and `flowvid bench gap` share: the cloth gap model
// of captures and a preset, and diagnosis.json (+ report.html) output.

#include "commands/cloth_options.hpp"

#include "flowvid/gap/cloth_model.hpp"
#include "flowvid/gap/diagnose.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>
#include <vector>

namespace flowvid::cli {

// The diagnoser's default mesh: coarser than footage makers use (bench gap
// makes 24x24), fine enough that its static drape is within reach of a finer
// mesh's. At 16x16 the drape alone sat 7 to 12 times the floor from 24x24
// footage, more than many effects (docs/gap.md).
inline constexpr const char* kDiagnoserResolution = "20x20";

struct DiagnoseClothOptions {
    ClothRunOptions run;  // the diagnoser's mesh (commands set kDiagnoserResolution)
    int frames = 30;      // compared frames from the first (later ones are mostly chaos)
    int floor_resolution_step = 0;  // the floor's finer-mesh member: rows and cols + this (0: none)
    int control_resolution_step = 8;  // the discretisation control's mesh: rows and cols + this (0: none)
    int substeps_per_frame = 5;     // implicit integrators' steps per frame
    // "repeatability" (as eval cloth reports it) or "chaos" (the model's own
    // steps, a 0.5 mm start jitter: far tighter, so discretisation counts as a gap).
    std::string floor = "repeatability";
    // The metric's alpha: a mismatched silhouette pixel against a squared
    // radian of fold orientation (gap/cloth_model.hpp says why not the fit's 0.1).
    double silhouette_weight = gap::kDiagnosisSilhouetteWeight;
};

// nullptr (logged) for bad run options; throws what the readers throw.
std::unique_ptr<gap::GapModel> cloth_gap_model(const std::vector<std::string>& capture_paths, const std::string& preset_path,
                                               const DiagnoseClothOptions& options, nlohmann::json& model_summary);

// The rigid gap model of tosses, each fitted on its training frames (with
// `fit_path`, the first starts from that fit.json). Throws what the readers throw.
std::unique_ptr<gap::GapModel> rigid_gap_model(const std::vector<std::string>& capture_paths, const std::string& fit_path,
                                               int threads, nlohmann::json& model_summary);

// diagnosis.json (format flowvid.diagnosis v1); `model` describes the base model.
nlohmann::json diagnosis_to_json(const gap::Diagnosis& diagnosis, const nlohmann::json& model);
// Writes FOLDER/diagnosis.json and FOLDER/report.html atomically.
void write_diagnosis(const std::string& folder, const nlohmann::json& diagnosis);

}  // namespace flowvid::cli
