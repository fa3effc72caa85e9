#pragma once
// Sealed benchmark cases for the gap diagnosis (`flowvid bench gap`): cloth
// captures made by this project's simulator at a finer mesh and a smaller
// time step than the diagnoser uses (so it does not invert itself), each with
// one hidden effect or none, filmed through the capture's camera with the
// projector's stripes and sensor noise like ../shared/captures'. The labels
// (effect, values, effect-to-noise) are returned to the caller, who keeps
// them apart from the cases: nothing in a case folder names its effect.

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/simulator.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/gap_bench_labels.hpp"
#include "flowvid/gap/effects.hpp"
#include "flowvid/gap/open_model.hpp"
#include "flowvid/progress.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace flowvid::gap {

struct BenchCase {
    std::string id;              // "case-007"
    bool rigid = false;          // a rigid toss (else a cloth swatch)
    std::string effect = "none"; // catalogue name or "none"
    EffectValues values;         // the hidden effect's parameters (empty for none)
    int scene = 0;               // index of the template capture
    int fabric = 0;              // index of the fabric
    double effect_to_noise = 0.0;  // measured after writing: see measure_effect_to_noise
};

struct BenchSettings {
    int rows = 24;                 // the footage maker's mesh (the diagnoser's default is 20x20)
    int cols = 24;
    cloth::Integrator integrator = cloth::Integrator::implicit_euler;  // the footage maker's
    int implicit_substeps = 10;    // per frame, for an implicit integrator (the diagnoser's default is 5)
    int frames = 30;
    double noise_sigma = 1.0 / 255.0;  // per pixel, after the sRGB encoding, correlated over 3x3 pixels
    double none_share = 0.25;
    double strength = 1.0;         // multiplies every drawn effect magnitude (not rates or directions)
    std::vector<std::string> effects;  // drawn from (empty: every cloth and camera effect, and the rigid ones with rigid scenes)
};

// The cases of a benchmark: effects, strengths (log-uniform over what a
// swatch test can meet), scenes and fabrics drawn from `seed`.
// With `rigid_scenes` > 0, rigid effects are drawn too and an effect-free
// case is a toss as often as rigid effects are among all effects.
std::vector<BenchCase> draw_bench_cases(int count, std::uint64_t seed, int scenes, int fabrics,
                                        const BenchSettings& settings, int rigid_scenes = 0);

// The effect at half its strength (towards neutral): for a case whose
// footage cannot be simulated (e.g. no equilibrium in too strong a wind).
EffectValues weakened(const EffectValues& values);

// The base model the diagnoser is given for a case: the fabric itself,
// except that a drag_nonlinear case gets it without its nonlinear drag.
cloth::ClothMaterial bench_base_material(const BenchCase& c, const cloth::ClothMaterial& fabric);

// Writes the case's capture folder (capture.json, frames/, masks/,
// background.png): the scene's experiment and calibration, the footage made
// with the effect. Overwrites what is there.
void write_cloth_case(const std::string& folder, const BenchCase& c, const formats::Capture& scene,
                      const cloth::ClothMaterial& fabric, const BenchSettings& settings, int threads);

// The effect's size in units of the floor: the mean over frames of
// error/floor of the neutral base model against the case's footage, at the
// footage maker's own mesh (so only the effect and the noise count).
double measure_effect_to_noise(const std::string& folder, const BenchCase& c, const cloth::ClothMaterial& fabric,
                               const BenchSettings& settings, int threads);

// ---- the benchmark as `flowvid bench gap` runs it: make, diagnose, score.
// DIR/cases/case-NNN/ hold captures and base.fabric.json (what the diagnoser
// gets); DIR/labels.json the hidden effects (flowvid.gap_bench_labels; only
// score_bench reads it); DIR/results/case-NNN/diagnosis.json the diagnoses.

struct BenchMakeRequest {
    std::string out_dir;
    int cases = 24;
    std::uint64_t seed = 1;
    std::vector<std::string> scene_paths;        // cloth.waving captures: camera, projector, pins
    std::vector<std::string> rigid_scene_paths;  // rigid.toss captures: body and camera (adds rigid effects)
    std::vector<std::string> fabric_paths;       // fabric presets the footage is made with
    BenchSettings settings;                      // footage mesh, integrator, strength, effects drawn from
    std::string footage_integrator_name = "implicit";  // as labels.json records it
    int threads = 0;
};

// Draws the cases, writes their folders and DIR/labels.json; returns the
// labels. Progress: stage "making cases", a case's id and effect as the
// message; a case halved to make its footage is logged. Throws the readers'
// errors, UsageError without scenes or fabrics, and flowvid::Cancelled
// (the cases written so far stay, without labels).
formats::GapBenchLabels make_bench_cases(const BenchMakeRequest& request, const Progress& progress = {});

// The case folders of a bench (DIR/cases/*/capture.json), sorted.
std::vector<std::string> bench_case_folders(const std::string& dir);

// How the diagnoser sees a case: its cloth captures with DIR/cases/ID/base.fabric.json,
// `cloth` giving the rest (mesh, floors); a rigid case as open_rigid_model.
OpenedGapModel open_bench_case(const std::string& case_folder, const ClothGapRequest& cloth, int threads);

struct BenchScoreRequest {
    std::string dir;
    // Also the share of the held-out gap the true effect closes in the
    // diagnoser's model (simulated; the most a diagnosis could close).
    bool oracle = false;
    ClothGapRequest cloth;  // the diagnoser's model, for the oracle
    int threads = 0;
};

struct BenchTally {
    int correct = 0;
    int cases = 0;
};

struct BenchScore {
    int cases_scored = 0;
    int missing = 0;                              // labelled cases without a diagnosis
    std::map<std::string, BenchTally> per_effect;  // top-1: the first named effect or its class
    std::map<std::string, BenchTally> per_bin;     // by effect-to-noise: <1, 1-2, 2-4, 4-8, >=8
    BenchTally strong;                             // effect-to-noise >= 4
    BenchTally false_alarms;                       // effect-free cases with an effect named
    int gap_detected_on_none = 0;
    double median_gap_closed_strong = 0.0;  // NaN when none (0 counted where not named)
    double median_gap_closed_named = 0.0;
    double median_oracle_gap_closed_strong = 0.0;  // with oracle
    std::map<std::string, double> oracle_by_case;  // with oracle: NaN where it could not run
    std::vector<Problem> warnings;                 // from reading labels and diagnoses
};
// The effect-to-noise bins in order, as BenchScore::per_bin names them.
const std::vector<std::string>& effect_to_noise_bins();

// Reads DIR/labels.json and every DIR/results/*/diagnosis.json there is,
// all validated before any work (every problem named by file and field, the
// labels' effects against the catalogue), scores them and writes
// DIR/score.json. Throws ValidationError and IoError.
BenchScore score_bench(const BenchScoreRequest& request);
nlohmann::json bench_score_json(const BenchScore& score, bool oracle);

}  // namespace flowvid::gap
