// flowvid simulate: a fabric preset driven by a cloth capture's pins (static
// drape or waving test), written as a motion glTF and/or a vertex-animation EXR.

#include "commands/cloth_options.hpp"
#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"
#include "report_html.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"

#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct SimulateOptions {
    std::string preset;
    std::string capture;
    std::string out;
    std::string vat;
    std::string grid;
    FrameOptions frames;  // default: all the pins cover
    ClothRunOptions run;
    bool json = false;
    // Start from the equilibrium branch that matches the footage's first
    // frame (predict; the fit does the same) instead of --initial-bow alone.
    bool match_footage = false;
};

int run_simulate(const SimulateOptions& options, const GlobalOptions& global) {
    if (options.out.empty() && options.vat.empty()) {
        log_message("error: nothing to write: give --out motion.glb and/or --vat positions.exr");
        return kExitUsage;
    }
    const formats::FabricPreset preset = read_preset_for_simulation(options.preset);
    const formats::Capture capture =
        formats::read_capture_of_kind(options.capture, {"cloth.static", "cloth.waving"}, "flowvid simulate");
    std::optional<cloth::SwatchOptions> swatch = swatch_options(options.run);
    if (!swatch) return kExitUsage;
    std::pair<int, int> grid{swatch->rows, swatch->cols};
    if (!options.grid.empty()) {
        const auto parsed = parse_grid(options.grid, "--grid");
        if (!parsed) return kExitUsage;
        grid = *parsed;
    }
    cloth::SwatchExperiment experiment = cloth::experiment_from_capture(capture);
    if (const std::optional<int> count =
            resolve_frame_count(options.frames, capture.frames.first,
                                "the simulation starts from the pins' first positions", experiment.frame_count)) {
        if (*count > experiment.frame_count)
            throw UsageError("", "",
                             std::to_string(*count) + " frames asked, but the capture's pins cover " +
                                 std::to_string(experiment.frame_count),
                             "give at most --frame-count " + std::to_string(experiment.frame_count));
        experiment.frame_count = *count;
        for (cloth::PinTrajectory& pin : experiment.pins) pin.positions_m.resize(static_cast<std::size_t>(*count));
    }

    for (const std::string& path : {options.out, options.vat})
        if (!path.empty()) formats::create_parent_folder(path);
    const cloth::ClothMaterial material = cloth::material_from_fabric(preset.parameters);
    // Ctrl-C is polled inside the equilibrium and every step, so it stops a
    // fine mesh within a step rather than after its frame.
    const InterruptWatch interrupt;
    swatch->equilibrium.cancel = interrupt.flag();
    swatch->simulation.cancel = interrupt.flag();
    if (options.match_footage) {
        cloth_fit::ClothFitSettings settings;
        settings.swatch = *swatch;
        // The fit's and eval's default start: the scanned first frame's fold state.
        cloth_fit::TrialLoadSettings first_frame;
        first_frame.target = cloth_fit::kDefaultFitTarget;
        first_frame.waving_frames = 1;  // only frame 1 picks the start: scan no other
        const Eigen::VectorXd start = cloth_fit::matching_equilibrium(cloth_fit::load_trial(capture, first_frame), material, settings);
        if (start.size() > 0) swatch->initial_positions = start;
    }

    // Per-area parameters give the same fabric on any mesh only where the
    // mesh holds its folds; say so when it does not.
    const cloth::MeshFoldCheck folds =
        cloth::check_mesh_folds(experiment, material, swatch->rows, swatch->cols, swatch->environment.gravity_m_per_s2.norm());
    if (!folds.holds_folds)
        log_message("note: this fabric folds at about " + html::format_number(1e3 * folds.fold_length_m, 2) +
                    " mm (its elastogravity length); the " + std::to_string(swatch->rows) + "x" + std::to_string(swatch->cols) +
                    " mesh's edges are " + html::format_number(1e3 * folds.edge_m, 3) +
                    " mm, so it folds at its own scale and a finer mesh drapes differently; edges of at most " +
                    html::format_number(1e3 * folds.longest_edge_m, 2) + " mm (--resolution " + std::to_string(folds.rows_needed) + "x" +
                    std::to_string(folds.rows_needed) + ") hold the fabric's folds (docs/cloth_model.md, \"Folds finer than the grid\")");

    std::optional<TerminalProgress> progress;
    progress.emplace(global, "simulate");
    const cloth::SwatchRun run = cloth::simulate_swatch(experiment, material, *swatch, progress->callback());
    progress.reset();
    const cloth::SimulationReport& report = run.simulation.report;
    if (report.status == cloth::SimulationReport::Status::cancelled) {
        log_message("interrupted at frame " + std::to_string(report.frame) + ": nothing written");
        return kExitInterrupted;
    }
    if (!report.ok()) {
        log_message(std::string("error: the simulation stopped (") + cloth::status_name(report.status) + ") at frame " +
                    std::to_string(report.frame) + ": " + report.reason + "; nothing written");
        return kExitFailure;
    }

    const cloth::GridFrames frames = cloth::sample_run(run, grid.first, grid.second);
    const std::string name = preset.name.empty() ? "flowvid_cloth" : preset.name;
    if (!options.out.empty())
        formats::write_motion_gltf(options.out, cloth::grid_mesh_animation(frames, grid.first, grid.second, experiment.fps, name));
    if (!options.vat.empty())
        formats::write_vertex_animation(options.vat, cloth::grid_vertex_animation(frames, grid.first, grid.second, experiment.fps));

    nlohmann::json summary = {{"preset", options.preset},
                              {"capture", options.capture},
                              {"frames", static_cast<int>(frames.size())},
                              {"fps", experiment.fps},
                              {"resolution", std::to_string(swatch->rows) + "x" + std::to_string(swatch->cols)},
                              {"grid", std::to_string(grid.first) + "x" + std::to_string(grid.second)},
                              {"integrator", cloth::integrator_name(swatch->simulation.integrator)},
                              {"equilibrium_residual_N", run.equilibrium.max_residual_force_N},
                              {"fold_length_mm", 1e3 * folds.fold_length_m},
                              {"mesh_edge_mm", 1e3 * folds.edge_m},
                              {"mesh_holds_folds", folds.holds_folds},
                              {"simulation_seconds", run.simulation.statistics.wall_time_s},
                              {"steps", run.simulation.statistics.steps}};
    if (!options.out.empty()) summary["gltf"] = options.out;
    if (!options.vat.empty()) summary["vertex_animation"] = options.vat;
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "simulate", "simulate a fabric preset in a capture's static drape or waving test", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<SimulateOptions>();
        app.footer(
            "Builds the capture's swatch (size, mass, pinned corners), solves its static equilibrium\n"
            "under the first pin positions, then moves the pins along the capture's trajectories and\n"
            "simulates the preset's fabric frame by frame (frame 1 = the equilibrium). Never reads\n"
            "truth/. Writes the surface sampled at a regular uv grid (--grid, default the simulation\n"
            "mesh; row 0 at v = 0, the layout of a capture's truth/positions.exr) as a motion glTF\n"
            "(--out, imports in Blender with its animation) and/or a vertex-animation EXR (--vat).\n"
            "A blow-up writes nothing and names the frame and the cause.\n\n"
            "Examples:\n"
            "  flowvid simulate --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-1 --out wave.glb\n"
            "  flowvid simulate --preset silk.fabric.json --capture cloth-silk-static-1/ --vat drape.exr --grid 24x24\n"
            "  flowvid simulate --preset cotton.fabric.json --capture wave/ --out fine.glb --resolution 48x48 --integrator rk4\n\n"
            "Exit codes: 0 ok, 1 the simulation blew up, 2 bad option, 3 invalid preset or capture,\n"
            "4 unreadable or unwritable file, 130 interrupted.");
        app.add_option("--preset", options->preset, "fabric preset (*.fabric.json)")->required();
        app.add_option("--capture", options->capture, "cloth capture folder (cloth.static or cloth.waving): pins, size, fps")
            ->required();
        app.add_option("--out", options->out, "motion glTF to write (.glb)");
        app.add_option("--vat", options->vat, "vertex-animation EXR to write");
        app.add_option("--grid", options->grid, "sample the surface at RxC uv points (default: the simulation mesh)");
        add_frame_options(app, options->frames, "frames A to B; A is the capture's first frame (the simulation starts there)",
                          "only the first N frames", "all the pins cover");
        add_cloth_run_options(app, options->run);
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_simulate(*options, global); };
    }}};

// `flowvid predict cloth`: the same run, written in the truth/positions.exr layout.
const RegisterPredictKind predict_registration{FitKind{
    "cloth", "vertex positions a fabric preset predicts for a cloth capture (truth/positions.exr layout)",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<SimulateOptions>();
        options->grid = "24x24";
        options->match_footage = true;
        app.footer(
            "Drives the preset's fabric with the capture's pins (as `flowvid simulate`, starting from the\n"
            "equilibrium whose first frame matches the footage, as the fit does) and writes the\n"
            "positions at a regular uv grid, row 0 at v = 0, as a vertex-animation EXR in the layout of a\n"
            "capture's truth/positions.exr, so the two compare vertex by vertex. Never reads truth/;\n"
            "`flowvid eval cloth` does the comparison.\n\n"
            "Examples:\n"
            "  flowvid predict cloth --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-2 \\\n"
            "                        --grid 24x24 --out pred.exr");
        app.add_option("--preset", options->preset, "fabric preset (*.fabric.json)")->required();
        app.add_option("--capture", options->capture, "cloth capture folder")->required();
        app.add_option("--out", options->vat, "vertex-animation EXR to write")->required();
        app.add_option("--grid", options->grid, "uv grid RxC")->capture_default_str();
        add_frame_options(app, options->frames, "frames A to B; A is the capture's first frame (the simulation starts there)",
                          "only the first N frames", "all the pins cover");
        add_cloth_run_options(app, options->run);
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_simulate(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
