#include "commands/cloth_options.hpp"
#include "output.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"

#include <algorithm>
#include <map>
#include <thread>

namespace flowvid::cli {

void add_cloth_run_options(CLI::App& app, ClothRunOptions& options) {
    app.add_option("--resolution", options.resolution,
                   "simulation mesh, RxC vertices (parameters are per area: any mesh whose edges hold the fabric's "
                   "folds shows the same fabric; simulate says when they do not)")
        ->capture_default_str();
    std::vector<std::string> names;
    for (const auto& [name, value] : cloth::integrators_by_short_name()) names.push_back(name);
    app.add_option("--integrator", options.integrator,
                   "rk4: adaptive Runge-Kutta (accurate, keeps folds; the thesis's choice); implicit: backward Euler "
                   "(fast, damps); bdf2: implicit, damps less; dopri54, bs32: other adaptive Runge-Kutta pairs")
        ->check(CLI::IsMember(names))
        ->capture_default_str();
    app.add_option("--initial-bow", options.initial_bow,
                   "start of the equilibrium solve: the slack between the pins bows to the swatch's front (1) or back "
                   "(-1); hung cloth has several equilibria and this picks one")
        ->check(CLI::Range(-2.0, 2.0))
        ->capture_default_str();
    app.add_option("--threads", options.threads, "worker threads (0 = all cores); results do not depend on it")
        ->check(CLI::Range(0, 256))
        ->capture_default_str();
}

std::optional<std::pair<int, int>> parse_grid(const std::string& text, const std::string& option) {
    if (const auto mesh = cloth::mesh_size_from_text(text)) return mesh;
    log_message("error: " + option + " " + text + ": expected ROWSxCOLS with 2..512 each, e.g. 24x24");
    return std::nullopt;
}

std::optional<cloth::SwatchOptions> swatch_options(const ClothRunOptions& options) {
    const auto grid = parse_grid(options.resolution, "--resolution");
    if (!grid) return std::nullopt;
    return cloth::run_swatch_options(grid->first, grid->second, cloth::integrators_by_short_name().at(options.integrator),
                                     options.initial_bow, options.threads);
}

void apply_shape_target_frame_defaults(cloth_fit::FitTarget target, bool frames_given, bool half_life_given, int& frames,
                                       double& half_life_frames) {
    if (target == cloth_fit::FitTarget::footage) return;
    if (!frames_given) frames = cloth_fit::kTracksWavingFrames;
    if (!half_life_given) half_life_frames = cloth_fit::kTracksHalfLifeFrames;
}

int thread_count(int requested) { return resolve_thread_count(requested); }

formats::FabricPreset read_preset_for_simulation(const std::string& path) {
    std::vector<Problem> warnings;
    formats::FabricPreset preset = cloth::read_preset_for_simulation(path, &warnings);
    print_problems(warnings);
    return preset;
}

std::optional<cloth::FoldCheck> fitting_swatch_folds(const formats::FabricPreset& preset) {
    const std::optional<double> edge_m = preset.provenance.swatch_edge_length_m;
    if (!edge_m || !(*edge_m > 0.0)) return std::nullopt;
    return cloth::check_folds(cloth::material_from_fabric(preset.parameters), *edge_m);
}

}  // namespace flowvid::cli
