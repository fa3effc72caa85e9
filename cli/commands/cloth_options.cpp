#include "commands/cloth_options.hpp"
#include "output.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/cloth/material.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <thread>

namespace flowvid::cli {

const std::map<std::string, cloth::Integrator>& integrators() {
    static const std::map<std::string, cloth::Integrator> table = {
        {"rk4", cloth::Integrator::rk4_adaptive},     {"dopri54", cloth::Integrator::dopri54},
        {"bs32", cloth::Integrator::bogacki_shampine32}, {"implicit", cloth::Integrator::implicit_euler},
        {"bdf2", cloth::Integrator::bdf2}};
    return table;
}

void add_cloth_run_options(CLI::App& app, ClothRunOptions& options) {
    app.add_option("--resolution", options.resolution,
                   "simulation mesh, RxC vertices (parameters are per area: any resolution shows the same fabric)")
        ->capture_default_str();
    std::vector<std::string> names;
    for (const auto& [name, value] : integrators()) names.push_back(name);
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
    int rows = 0, cols = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &rows, &x, &cols, &extra) == 3 && (x == 'x' || x == 'X') && rows >= 2 &&
        cols >= 2 && rows <= 512 && cols <= 512)
        return std::make_pair(rows, cols);
    log_message("error: " + option + " " + text + ": expected ROWSxCOLS with 2..512 each, e.g. 24x24");
    return std::nullopt;
}

std::optional<cloth::SwatchOptions> swatch_options(const ClothRunOptions& options) {
    const auto grid = parse_grid(options.resolution, "--resolution");
    if (!grid) return std::nullopt;
    cloth::SwatchOptions swatch;
    swatch.rows = grid->first;
    swatch.cols = grid->second;
    swatch.simulation.integrator = integrators().at(options.integrator);
    swatch.simulation.threads = thread_count(options.threads);
    swatch.initial_bow = options.initial_bow;
    if (swatch.simulation.integrator == cloth::Integrator::rk4_adaptive ||
        swatch.simulation.integrator == cloth::Integrator::dopri54 ||
        swatch.simulation.integrator == cloth::Integrator::bogacki_shampine32)
        swatch.simulation.position_tolerance_m = 1e-4;
    return swatch;
}

void apply_shape_target_frame_defaults(video::FitTarget target, const CLI::Option* frames_option,
                                       const CLI::Option* half_life_option, int& frames, double& half_life_frames) {
    if (target == video::FitTarget::footage) return;
    if (frames_option->count() == 0) frames = video::kTracksWavingFrames;
    if (half_life_option->count() == 0) half_life_frames = video::kTracksHalfLifeFrames;
}

int thread_count(int requested) { return resolve_thread_count(requested); }

formats::FabricPreset read_preset_for_simulation(const std::string& path) {
    std::vector<Problem> warnings;
    formats::FabricPreset preset = formats::read_fabric_preset(path, &warnings);
    print_problems(warnings);
    const std::vector<Problem> problems = cloth::check_material(cloth::material_from_fabric(preset.parameters));
    if (!problems.empty()) {
        std::vector<Problem> named = problems;
        for (Problem& problem : named) problem.file = path;
        throw ValidationError(named);
    }
    return preset;
}

}  // namespace flowvid::cli
