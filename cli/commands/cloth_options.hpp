#pragma once
// Options the cloth commands share (simulate, fit/predict/eval cloth,
// recognize): simulation mesh, integrator, threads, and "RxC" grids.

#include "command.hpp"

#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"

#include <CLI/CLI.hpp>

#include <map>
#include <optional>
#include <string>
#include <utility>

namespace flowvid::cli {

struct ClothRunOptions {
    std::string resolution = "24x24";  // simulation mesh, rows x cols of vertices
    std::string integrator = "implicit";
    int threads = 0;                   // 0 = all cores
    double initial_bow = 1.0;          // which way the slack between the pins bows at the start
};

// Whether the swatch a fitted preset was fitted on (its provenance's
// swatch_edge_length_m) held the fitted fabric's folds (cloth::check_folds);
// nullopt where the preset does not record it. Where it did not, the preset
// reproduces the filmed drape on meshes like that swatch.
std::optional<cloth::FoldCheck> fitting_swatch_folds(const formats::FabricPreset& preset);

// Adds --resolution, --integrator and --threads to a command.
void add_cloth_run_options(CLI::App& app, ClothRunOptions& options);

// "RxC" (also "R×C" is not accepted: ASCII x only), both 2..512. nullopt,
// after logging which option is wrong and what it expects, otherwise.
std::optional<std::pair<int, int>> parse_grid(const std::string& text, const std::string& option);

// The swatch options of a command's flags; nullopt (logged) for a bad --resolution.
std::optional<cloth::SwatchOptions> swatch_options(const ClothRunOptions& options);

// Tracks and scan targets compare point distances that grow with chaos:
// unless the frames or the half-life were given, they take
// cloth_fit::kTracksWavingFrames and kTracksHalfLifeFrames.
void apply_shape_target_frame_defaults(cloth_fit::FitTarget target, bool frames_given, bool half_life_given, int& frames,
                                       double& half_life_frames);

// Threads to use: the option, or every core for 0.
int thread_count(int requested);

// cloth::read_preset_for_simulation with its warnings in the log.
formats::FabricPreset read_preset_for_simulation(const std::string& path);

}  // namespace flowvid::cli
