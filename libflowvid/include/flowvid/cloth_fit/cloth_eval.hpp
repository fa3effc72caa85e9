#pragma once
// How well a fabric reproduces a cloth trial, and how well it *could*: the
// metric error per frame (and the vertex error when the capture has ground
// truth, read only for evaluation), next to the predictability floor --
// the spread of an ensemble of runs whose parameters are drawn within their
// fitted uncertainty and moved by a tiny relative amount, and whose starting
// shape is jittered at the level of measurement noise. Waving cloth is chaotic: an error at or below its floor
// is as good as any model can do in that time window.

#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/formats/vertex_animation.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::cloth_fit {

struct FrameWindow {
    int first = 1;  // 1-based capture frames, inclusive
    int last = 10;
};
// 1-10, 11-25, 26-end (those that exist for `frame_count` frames), then the
// whole trial 1-end.
std::vector<FrameWindow> standard_windows(int frame_count);
std::string window_name(const FrameWindow& window);  // "1-10"

struct FloorSettings {
    int members = 6;
    double relative_perturbation = 1e-6;  // every parameter times (1 + U(-p, p))
    // RMS offset of the starting shape's free vertices. Empty: one pixel's
    // footprint at the swatch (its mean depth / the focal length) -- the
    // footage cannot place the starting shape better than about a pixel.
    std::optional<double> jitter_m;
    std::uint64_t seed = 1;
    // 1-sigma uncertainty per fabric parameter key (its SI unit). Each member
    // draws value * exp(N(0, sigma / value)): positive, and sigma wide for
    // the small relative uncertainties fits produce. Parameters with equal
    // value and sigma (a fit's warp/weft tie) move together. Empty: the floor
    // is the chaos alone.
    std::map<std::string, double> parameter_sigma;
    cloth::SwatchOptions::JitterShape jitter_shape = cloth::SwatchOptions::JitterShape::smooth_normal;
    // The members' integrator and, for the implicit ones, substeps per frame
    // (also their unperturbed reference run's). Empty: the settings' own.
    // Backward Euler's numerical damping at a few substeps per frame hides
    // the fold instabilities that make cloth chaotic; smaller steps or the
    // adaptive rk4 keep them (docs/cloth_fitting.md).
    std::optional<cloth::Integrator> integrator;
    std::optional<int> implicit_substeps_per_frame;
};

struct FloorMember {
    cloth::ClothMaterial material;
    std::uint64_t jitter_seed = 1;
};
// The floor's members as `floor` draws them around `material` (seeded).
std::vector<FloorMember> draw_floor_members(const cloth::ClothMaterial& material, const FloorSettings& floor);

// The floor the commands report next to errors: `members` runs with
// backward Euler at kFloorSubstepsPerFrame substeps a frame, whatever the
// errors' runs use (5 substeps damp the chaos away: docs/cloth_fitting.md).
inline constexpr int kFloorSubstepsPerFrame = 20;
FloorSettings reported_floor(int members);

// The 1-sigma uncertainties a preset carries, for FloorSettings::parameter_sigma.
std::map<std::string, double> preset_uncertainty(const formats::FabricParameters& parameters);

struct PredictabilityFloor {
    int members = 0;
    double jitter_m = 0.0;  // the starting-shape jitter the members had
    cloth::Integrator integrator = cloth::Integrator::implicit_euler;  // the members'
    int implicit_substeps_per_frame = 0;                               // theirs (0: an adaptive integrator)
    // Per simulated frame (index 0 = frame 1): RMS over members of the RMS
    // vertex distance from the unperturbed run, metres (uv grid of the mesh).
    std::vector<double> vertex_rms_m;
    // Per compared frame of the trial: mean over members of E_k, each member
    // compared with the unperturbed run's own renders.
    std::vector<double> metric;
};

// The floor of `material` on `trial`. Members run in parallel on `threads`.
PredictabilityFloor estimate_floor(const ClothTrial& trial, const cloth::ClothMaterial& material,
                                   const ClothFitSettings& settings, const FloorSettings& floor, int threads = 1);

// One pixel's footprint, metres, at the mean camera depth of `positions`
// (3 per vertex, world metres) seen by `camera`.
double pixel_footprint_m(const formats::CameraModel& camera, const Eigen::VectorXd& positions);

// sum over compared frames of w_k * floor E_k: the floor of a trial's weighted error.
double weighted_floor(const ClothTrial& trial, const PredictabilityFloor& floor);

struct TrialAssessment {
    std::string name;
    bool is_static = false;
    cloth::SimulationReport report;
    std::vector<int> frame_numbers;            // compared frames (1-based)
    std::vector<video::FrameError> frames;   // E_k per compared frame
    std::vector<double> weights;               // w_k used by the fit
    double weighted_error = 0.0;               // sum w_k E_k
    cloth::GridFrames predicted;               // the run at the truth's grid (or the mesh's), per simulated frame
    std::vector<double> vertex_rms_m;          // per simulated frame vs truth; empty without truth
    std::optional<PredictabilityFloor> floor;
};

// Simulates `material` in `trial`, compares every compared frame, and (with
// `truth`) the vertices at the truth's grid. With `floor`, also estimates the
// predictability floor.
TrialAssessment assess_trial(const ClothTrial& trial, const cloth::ClothMaterial& material,
                             const ClothFitSettings& settings, const std::optional<formats::VertexAnimation>& truth,
                             const FloorSettings* floor, int threads = 1);

// RMS over every vertex of the window's frames, from per-frame RMS values
// (index 0 = frame 1; frames past the end are left out). NaN when none.
double pooled_rms(const std::vector<double>& per_frame_rms, const FrameWindow& window);

struct WindowSummary {
    FrameWindow window;
    double metric_mean = 0.0;        // mean E_k over the window's compared frames
    double metric_floor_mean = 0.0;  // the same for the floor (NaN without a floor)
    double vertex_rms_m = 0.0;       // pooled over the window (NaN without truth)
    double vertex_floor_m = 0.0;     // pooled over the window (NaN without a floor)
};
std::vector<WindowSummary> summarize_windows(const TrialAssessment& assessment, const std::vector<FrameWindow>& windows);

}  // namespace flowvid::cloth_fit
