#pragma once
// The gap diagnosis's entry points: a gap model opened from files, as
// `flowvid diagnose`, `flowvid bench gap` and the Python module open it.
//   open_cloth_model: a fitted fabric (*.fabric.json) in the experiments of
//     cloth captures (static drapes, waving tests);
//   open_rigid_model: tosses, each fitted on its own training frames.
// Then gap::diagnose (gap/diagnose.hpp) and diagnosis_document for
// diagnosis.json (formats/specs/diagnosis.md).

#include "flowvid/cloth/swatch.hpp"
#include "flowvid/error.hpp"
#include "flowvid/gap/cloth_model.hpp"
#include "flowvid/gap/diagnose.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>
#include <vector>

namespace flowvid::gap {

// The diagnoser's default mesh: coarser than footage makers use (bench gap
// makes 24x24), fine enough that its static drape is within reach of a finer
// mesh's. At 16x16 the drape alone sat 7 to 12 times the floor from 24x24
// footage, more than many effects (docs/gap.md).
inline constexpr int kDiagnoserRows = 20;
inline constexpr int kDiagnoserCols = 20;

enum class ClothFloorKind {
    // How far repeated takes of the experiment spread, as eval cloth reports
    // it (a pixel's start jitter, 20 substeps a frame).
    repeatability,
    // The model's own steps and a 0.5 mm start jitter: far tighter, so mesh
    // and step differences count as gaps.
    chaos,
};
const char* to_string(ClothFloorKind kind);

struct ClothGapRequest {
    ClothGapRequest();
    std::vector<std::string> capture_paths;  // cloth.static / cloth.waving capture folders
    std::string preset_path;                 // the fitted fabric
    cloth::SwatchOptions swatch;             // mesh (default: the diagnoser's), integrator, simulation threads
    int frames = 30;                         // compared frames from the first (later ones are mostly chaos)
    int substeps_per_frame = 5;              // implicit integrators' steps per frame
    int floor_resolution_step = 0;           // the floor's finer-mesh member: rows and cols + this (0: none)
    int control_resolution_step = 8;         // the discretisation control's mesh: rows and cols + this (0: none)
    ClothFloorKind floor = ClothFloorKind::repeatability;
    // The metric's alpha: a mismatched silhouette pixel against a squared
    // radian of fold orientation (gap/cloth_model.hpp says why not the fit's 0.1).
    double silhouette_weight = kDiagnosisSilhouetteWeight;
    int threads = 0;  // flowvid/threads.hpp
};

struct RigidGapRequest {
    std::vector<std::string> capture_paths;  // rigid.toss capture folders
    // With a fit (flowvid fit rigid's fit.json), the first toss starts from
    // it; a fit that saw the held-out frames makes them look better.
    std::string fit_path;
    int threads = 0;
};

struct OpenedGapModel {
    std::unique_ptr<GapModel> model;
    nlohmann::json description;     // diagnosis.json's "model": what the base model is and how it was run
    std::vector<Problem> warnings;  // from reading the files
};

// Throw the readers' errors (a capture of another kind, a preset the
// simulator cannot use: ValidationError naming file and field).
OpenedGapModel open_cloth_model(const ClothGapRequest& request);
OpenedGapModel open_rigid_model(const RigidGapRequest& request);

// The model the captures call for, by the first one's kind: rigid tosses
// (open_rigid_model, with `fit_path` when given), else cloth captures with
// the preset (open_cloth_model; `cloth` gives the mesh, floors and threads,
// the captures and preset are set here). Throws UsageError for cloth
// captures without a preset.
OpenedGapModel open_gap_model(const std::vector<std::string>& capture_paths, const std::string& preset_path,
                              const std::string& fit_path, ClothGapRequest cloth);

// diagnosis.json (format flowvid.diagnosis v1) of a diagnosis; `model` is
// OpenedGapModel::description.
nlohmann::json diagnosis_document(const Diagnosis& diagnosis, const nlohmann::json& model);

}  // namespace flowvid::gap
