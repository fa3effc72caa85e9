// flowvid swatch: a fabric preset in a swatch experiment (flowvid.swatch_experiment,
// the experiments the Blender add-on calibrates Blender's cloth against), with
// every simulated frame written as flowvid.swatch_frames; both files are read
// and written by flowvid::formats (formats/specs/swatch_*.md). The command-line twin of the Python
// module's flowvid.cloth.simulate_swatch, same defaults, so the add-on's
// calibration and export run through the tool where the module cannot load.

#include "command.hpp"
#include "commands/cloth_options.hpp"
#include "output.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/swatch_experiment.hpp"
#include "flowvid/formats/swatch_frames.hpp"

#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct SwatchCommandOptions {
    std::string preset;
    std::string experiment;
    std::string out;
    std::string grid = "12x12";
    std::string integrator = "implicit_euler";
    int substeps = 10;
    double initial_bow = 1.0;
    bool json = false;
};

// The file's experiment as the simulator takes it (the file knows nothing of simulators).
cloth::SwatchExperiment swatch_experiment_from_file(const formats::SwatchExperimentFile& file, const std::string& path) {
    cloth::SwatchExperiment experiment;
    experiment.source = path;
    experiment.width_m = file.width_m;
    experiment.height_m = file.height_m;
    experiment.mass_kg = file.mass_kg.value_or(0.0);  // 0: the preset's areal density
    experiment.fps = file.fps;
    experiment.frame_count = file.frame_count;
    for (const formats::SwatchPinTrajectory& pin : file.pins) {
        cloth::PinTrajectory trajectory;
        trajectory.uv = pin.uv;
        trajectory.positions_m = pin.positions_m;
        experiment.pins.push_back(std::move(trajectory));
    }
    return experiment;
}

cloth::Integrator integrator_named(const std::string& name) {
    if (const std::optional<cloth::Integrator> integrator = cloth::integrator_from_name(name)) return *integrator;
    throw UsageError("", "--integrator", "unknown integrator '" + name + "'",
                     "use implicit_euler (implicit), rk4_adaptive (rk4), dopri54, bs32 or bdf2");
}

int run_swatch(const SwatchCommandOptions& options, const GlobalOptions& global) {
    const formats::FabricPreset preset = cloth::read_preset_for_simulation(options.preset);
    std::vector<Problem> warnings;
    const cloth::SwatchExperiment experiment = swatch_experiment_from_file(
        formats::read_swatch_experiment(options.experiment, &warnings), options.experiment);
    print_problems(warnings);
    const std::optional<std::pair<int, int>> grid = parse_grid(options.grid, "--grid");
    if (!grid) return kExitUsage;
    const auto [rows, cols] = *grid;
    // The module's defaults (flowvid.cloth.simulate_swatch), so both backends give the same frames.
    cloth::SwatchOptions swatch;
    swatch.rows = rows;
    swatch.cols = cols;
    swatch.simulation.integrator = integrator_named(options.integrator);
    swatch.simulation.implicit_substeps_per_frame = options.substeps;
    swatch.initial_bow = options.initial_bow;
    formats::create_parent_folder(options.out);

    // Ctrl-C (or the add-on's Esc, a SIGINT) is polled inside the equilibrium and every step.
    const InterruptWatch interrupt;
    swatch.equilibrium.cancel = interrupt.flag();
    swatch.simulation.cancel = interrupt.flag();
    std::optional<TerminalProgress> progress;
    progress.emplace(global, "swatch");
    const cloth::SwatchRun run =
        cloth::simulate_swatch(experiment, cloth::material_from_fabric(preset.parameters), swatch, progress->callback());
    const bool interrupted = progress->interrupted() || interrupt.requested();
    progress.reset();
    const cloth::SimulationReport& report = run.simulation.report;
    if (interrupted || report.status == cloth::SimulationReport::Status::cancelled) {
        log_message("interrupted at frame " + std::to_string(report.frame) + ": nothing written");
        return kExitInterrupted;
    }
    formats::SwatchFramesFile written;
    written.status = cloth::status_name(report.status);
    written.reason = report.reason;
    written.equilibrium_converged = run.equilibrium.converged;
    written.rows = rows;
    written.cols = cols;
    for (const cloth::PinnedVertex& pin : run.swatch.pins) written.pinned_vertices.push_back(pin.vertex);
    written.wall_time_s = run.simulation.statistics.wall_time_s;
    for (const Eigen::MatrixX3d& frame : cloth::sample_frames(run.swatch.mesh, run.simulation.frames, rows, cols)) {
        std::vector<Eigen::Vector3d> points;
        points.reserve(static_cast<std::size_t>(frame.rows()));
        for (Eigen::Index i = 0; i < frame.rows(); ++i) points.push_back(frame.row(i).transpose());
        written.frames_m.push_back(std::move(points));
    }
    // A blow-up is written too (its status says so): the add-on's calibration scores it as a bad guess.
    formats::write_swatch_frames(options.out, written);
    const nlohmann::json summary = {{"status", written.status},
                                    {"frames", static_cast<int>(written.frames_m.size())},
                                    {"grid", options.grid},
                                    {"integrator", cloth::integrator_name(swatch.simulation.integrator)},
                                    {"equilibrium_residual_N", run.equilibrium.max_residual_force_N},
                                    {"out", options.out}};
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    if (!report.ok()) {
        log_message(std::string("error: the simulation stopped (") + cloth::status_name(report.status) + ") at frame " +
                    std::to_string(report.frame) + ": " + report.reason);
        return kExitFailure;
    }
    return kExitOk;
}

const RegisterCommand registration{Command{
    "swatch", "simulate a fabric preset in a swatch experiment written as JSON (frames as JSON)",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<SwatchCommandOptions>();
        app.footer(
            "Builds a width x height swatch whose pins sit at their uv ((0,0) bottom-left as hung,\n"
            "(1,1) top-right), solves its static equilibrium under the pins' first positions, then\n"
            "moves the pins frame by frame and simulates the preset's fabric (frame 1 = the\n"
            "equilibrium). This is the experiment the Blender add-on runs in Blender's solver and in\n"
            "flowvid side by side to calibrate and export presets; `flowvid simulate` runs the same\n"
            "from a capture folder instead.\n\n"
            "The experiment file (flowvid.swatch_experiment, formats/specs/swatch_experiment.md;\n"
            "metres, seconds):\n"
            "  {\"format\": \"flowvid.swatch_experiment\", \"version\": \"1.0\",\n"
            "   \"width_m\": 0.3, \"height_m\": 0.3, \"fps\": 30, \"frame_count\": 2,\n"
            "   \"pins\": [{\"uv\": [0, 1], \"positions_m\": [[0, 0, 1], [0.01, 0, 1]]},\n"
            "            {\"uv\": [1, 1], \"positions_m\": [[0.3, 0, 1], [0.31, 0, 1]]}]}\n"
            "(optional \"mass_kg\" > 0 overrides the preset's areal density). --out receives\n"
            "flowvid.swatch_frames (formats/specs/swatch_frames.md): {\"status\", \"reason\",\n"
            "\"grid\": [rows, cols], \"pinned_vertices\", \"frames\": one [x, y, z] per grid vertex\n"
            "r*cols + c per frame}; a blow-up is written with its status and exits 1. Both files\n"
            "check with `flowvid validate`.\n\n"
            "Examples:\n"
            "  flowvid swatch --preset cotton.fabric.json --experiment drape.swatch_experiment.json \\\n"
            "      --out drape.swatch_frames.json\n"
            "  flowvid swatch --preset silk.fabric.json --experiment wave.json --grid 16x16 --integrator rk4 --out w.json\n\n"
            "Exit codes: 0 ok, 1 the simulation blew up, 2 bad option, 3 invalid preset or experiment,\n"
            "4 unreadable or unwritable file, 130 interrupted.");
        app.add_option("--preset", options->preset, "fabric preset (*.fabric.json)")->required();
        app.add_option("--experiment", options->experiment, "swatch experiment (flowvid.swatch_experiment, see below)")->required();
        app.add_option("--out", options->out, "frames to write (flowvid.swatch_frames)")->required();
        app.add_option("--grid", options->grid, "simulation mesh, rows x cols of vertices")->capture_default_str();
        app.add_option("--integrator", options->integrator,
                       "implicit_euler, rk4_adaptive, dopri54, bogacki_shampine32 or bdf2 (or rk4, bs32, implicit)")
            ->capture_default_str();
        app.add_option("--substeps", options->substeps, "implicit integrators' substeps per frame")->capture_default_str();
        app.add_option("--initial-bow", options->initial_bow,
                       "scale of the start's out-of-plane bow (-1 bows to the back)")->capture_default_str();
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_swatch(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
