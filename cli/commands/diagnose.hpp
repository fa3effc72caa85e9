#pragma once
// What `flowvid diagnose` and `flowvid bench gap` share: the cloth options
// of the gap model (gap/open_model.hpp), and diagnosis.json + report.html output.

#include "commands/cloth_options.hpp"

#include "flowvid/gap/open_model.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::cli {

struct DiagnoseClothOptions {
    ClothRunOptions run;  // the diagnoser's mesh (commands set diagnoser_resolution())
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

// gap::ClothGapRequest's mesh as --resolution text ("20x20").
std::string diagnoser_resolution();

// The cloth part of the gap model request (gap::open_gap_model sets the
// captures and the preset); nullopt (logged) for bad run options.
std::optional<gap::ClothGapRequest> cloth_gap_request(const DiagnoseClothOptions& options);

// Writes FOLDER/diagnosis.json and FOLDER/report.html atomically.
void write_diagnosis(const std::string& folder, const nlohmann::json& diagnosis);

}  // namespace flowvid::cli
