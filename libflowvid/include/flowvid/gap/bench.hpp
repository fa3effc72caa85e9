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
#include "flowvid/gap/effects.hpp"

#include <cstdint>
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

}  // namespace flowvid::gap
