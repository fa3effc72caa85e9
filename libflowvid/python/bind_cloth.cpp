#include "bindings.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/error.hpp"
#include "flowvid/progress.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"

#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cstdio>
#include <cmath>

namespace py = pybind11;

namespace flowvid::python {

namespace {

// A preset's `parameters` ({"key": {"value": v}} or {"key": v}) -> material.
// Every missing or non-numeric key is reported at once, named by JSON pointer;
// the parameters added after format 1.0 may be missing (their neutral value).
cloth::ClothMaterial material_from_dict(const py::dict& parameters) {
    Diagnostics diagnostics("<parameters>");
    formats::FabricParameters fabric;
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table()) {
        const std::string field = std::string("/parameters/") + info.key;
        if (!parameters.contains(info.key)) {
            if (info.optional()) {
                (fabric.*(info.member)).value = info.neutral;
                continue;
            }
            diagnostics.error(field, "missing", "give every parameter of the fabric preset format");
            continue;
        }
        py::object entry = parameters[info.key];
        if (py::isinstance<py::dict>(entry)) entry = entry.cast<py::dict>()["value"];
        try {
            (fabric.*(info.member)).value = entry.cast<double>();
        } catch (const py::cast_error&) {
            diagnostics.error(field, "not a number", "write the value as a number in SI units");
        }
    }
    diagnostics.throw_if_errors();
    cloth::ClothMaterial material = cloth::material_from_fabric(fabric);
    if (std::vector<Problem> problems = cloth::check_material(material); !problems.empty()) {
        throw ValidationError(problems);
    }
    return material;
}

Eigen::Vector3d vector3(const py::handle& value) {
    auto sequence = value.cast<std::vector<double>>();
    if (sequence.size() != 3) throw Error("<experiment>", "/pins/positions_m", "expected [x, y, z]", "give three numbers in metres");
    return {sequence[0], sequence[1], sequence[2]};
}

cloth::SwatchExperiment experiment_from_dict(const py::dict& experiment) {
    cloth::SwatchExperiment result;
    result.source = "<experiment>";
    result.width_m = experiment["width_m"].cast<double>();
    result.height_m = experiment["height_m"].cast<double>();
    if (experiment.contains("mass_kg")) result.mass_kg = experiment["mass_kg"].cast<double>();
    result.fps = experiment["fps"].cast<double>();
    result.frame_count = experiment["frame_count"].cast<int>();
    for (const py::handle& pin_handle : experiment["pins"].cast<py::list>()) {
        py::dict pin = pin_handle.cast<py::dict>();
        cloth::PinTrajectory trajectory;
        auto uv = pin["uv"].cast<std::vector<double>>();
        trajectory.uv = {uv.at(0), uv.at(1)};
        for (const py::handle& position : pin["positions_m"].cast<py::list>())
            trajectory.positions_m.push_back(vector3(position));
        result.pins.push_back(std::move(trajectory));
    }
    return result;
}

cloth::Integrator integrator_from_name(const std::string& name) {
    if (const std::optional<cloth::Integrator> integrator = cloth::integrator_from_name(name)) return *integrator;
    throw Error("<options>", "integrator", "unknown integrator '" + name + "'",
                "use rk4_adaptive, rk45_adaptive, rk23_adaptive, implicit_euler or bdf2");
}

py::list frames_to_python(const std::vector<Eigen::MatrixX3d>& frames) {
    py::list result;
    for (const Eigen::MatrixX3d& frame : frames) {
        py::list rows;
        for (Eigen::Index i = 0; i < frame.rows(); ++i) rows.append(py::make_tuple(frame(i, 0), frame(i, 1), frame(i, 2)));
        result.append(rows);
    }
    return result;
}

// flowvid fit cloth, in process: captures to a fitted preset (cloth_fit::fit_cloth).
py::object fit_cloth(const std::vector<std::string>& captures, const std::string& out, const std::string& name,
                     long long evaluations, double budget_seconds, std::uint64_t seed, int rows, int cols,
                     const std::string& integrator, const std::string& fit_to, const std::string& search,
                     int variability_runs, int floor_members, int threads, const py::object& progress) {
    cloth_fit::ClothFitRequest request;
    for (const std::string& path : captures)
        request.captures.push_back(formats::read_capture_of_kind(path, {"cloth.static", "cloth.waving"}, "flowvid.cloth.fit"));
    request.name = name;
    request.evaluations = evaluations;
    request.budget_seconds = budget_seconds;
    request.seed = seed;
    const auto named = cloth::integrators_by_short_name().find(integrator);
    if (named == cloth::integrators_by_short_name().end())
        throw Error("<options>", "integrator", "unknown integrator '" + integrator + "'", "use rk4, dopri54, bs32, implicit or bdf2");
    request.problem.swatch = cloth::run_swatch_options(rows, cols, named->second, 1.0, threads);
    const std::optional<cloth_fit::FitTarget> target = cloth_fit::fit_target_from_name(fit_to);
    if (!target) throw Error("<options>", "fit_to", "unknown target '" + fit_to + "'", "use footage, scan or tracks");
    request.load.target = *target;
    if (*target != cloth_fit::FitTarget::footage) {  // shape targets compare fewer, faster-fading frames (as the CLI)
        request.load.waving_frames = cloth_fit::kTracksWavingFrames;
        request.load.half_life_frames = cloth_fit::kTracksHalfLifeFrames;
    }
    request.load.static_weight = cloth_fit::default_static_weight(request.load, request.captures);
    const std::optional<optim::SearchMethod> method = optim::search_method_from_name(search);
    if (!method) throw Error("<options>", "search", "unknown search '" + search + "'", "use cmaes or annealing");
    request.search = *method;
    request.variability_runs = variability_runs;
    request.floor_members = floor_members;
    request.threads = threads;
    request.progress = progress_from_python(progress);
    cloth_fit::ClothFitOutcome outcome;
    {
        py::gil_scoped_release release;  // minutes of simulation: the interpreter (Blender's UI) keeps running
        outcome = cloth_fit::fit_cloth(request);
    }
    if (outcome.status == cloth_fit::ClothFitOutcome::Status::cancelled) throw Cancelled();
    if (!out.empty() && outcome.preset) formats::write_fabric_preset(out, *outcome.preset);
    py::dict result;
    result["preset"] = outcome.preset ? json_to_python(formats::fabric_preset_to_json(*outcome.preset)) : py::none();
    result["start_error"] = outcome.start_evaluation.total;
    result["final_error"] = outcome.final_evaluation.total;
    result["final_error_floor"] = floor_members > 0 ? py::object(py::float_(outcome.total_floor)) : py::none();
    py::list trials;
    for (std::size_t i = 0; i < outcome.final_evaluation.trials.size(); ++i) {
        py::dict trial;
        trial["capture"] = outcome.trial_names[i];
        trial["final_error"] = outcome.final_evaluation.trials[i].error;
        trial["floor"] = i < outcome.floors.size() && outcome.floors[i].weighted ? py::object(py::float_(*outcome.floors[i].weighted))
                                                                                 : py::none();
        trials.append(trial);
    }
    result["trials"] = trials;
    result["evaluations"] = outcome.evaluations;
    result["seconds"] = outcome.seconds;
    return result;
}

}  // namespace

void bind_cloth(py::module_& module) {
    py::module_ cloth_module = module.def_submodule("cloth", "The cloth simulator (swatch experiments)");
    cloth_module.def(
        "simulate_swatch",
        [](const py::dict& experiment, const py::dict& parameters, int rows, int cols, const std::string& integrator,
           int substeps, double initial_bow, const std::vector<double>& gravity, const py::object& progress,
           const std::vector<std::vector<double>>& initial_positions) {
            const cloth::SwatchExperiment parsed = experiment_from_dict(experiment);
            const cloth::ClothMaterial material = material_from_dict(parameters);
            cloth::SwatchOptions options;
            options.rows = rows;
            options.cols = cols;
            options.simulation.integrator = integrator_from_name(integrator);
            options.simulation.implicit_substeps_per_frame = substeps;
            options.initial_bow = initial_bow;
            if (gravity.size() == 3) options.environment.gravity_m_per_s2 = {gravity[0], gravity[1], gravity[2]};
            if (!initial_positions.empty()) {
                if (initial_positions.size() != static_cast<size_t>(rows) * static_cast<size_t>(cols))
                    throw Error("<options>", "initial_positions", "needs rows * cols points",
                                "give one [x, y, z] per vertex r * cols + c");
                options.initial_positions.resize(3 * static_cast<Eigen::Index>(initial_positions.size()));
                for (size_t i = 0; i < initial_positions.size(); ++i) {
                    if (initial_positions[i].size() != 3)
                        throw Error("<options>", "initial_positions", "expected [x, y, z]", "three numbers, metres");
                    for (int k = 0; k < 3; ++k)
                        options.initial_positions[3 * static_cast<Eigen::Index>(i) + k] = initial_positions[i][k];
                }
            }
            Progress callback;  // the module's progress(frame, frame_count), as before
            if (!progress.is_none())
                callback = [&progress, &parsed](const ProgressReport& p) {
                    const int frame = static_cast<int>(std::lround(p.fraction * parsed.frame_count));
                    return progress(frame, parsed.frame_count).cast<bool>();
                };
            const auto start = std::chrono::steady_clock::now();
            cloth::SwatchRun run = cloth::simulate_swatch(parsed, material, options, callback);
            const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            py::dict result;
            result["status"] = cloth::status_name(run.simulation.report.status);
            result["reason"] = run.simulation.report.reason;
            result["equilibrium_converged"] = run.equilibrium.converged;
            result["frames"] = frames_to_python(cloth::sample_frames(run.swatch.mesh, run.simulation.frames, rows, cols));
            py::list pinned;
            for (const cloth::PinnedVertex& pin : run.swatch.pins) pinned.append(pin.vertex);
            result["pinned_vertices"] = pinned;
            result["wall_time_s"] = wall_s;
            return result;
        },
        py::arg("experiment"), py::arg("parameters"), py::arg("rows") = 12, py::arg("cols") = 12,
        py::arg("integrator") = "implicit_euler", py::arg("substeps") = 10, py::arg("initial_bow") = 1.0,
        py::arg("gravity") = std::vector<double>{0.0, 0.0, -9.81}, py::arg("progress") = py::none(),
        py::arg("initial_positions") = std::vector<std::vector<double>>{},
        R"(Static equilibrium under the first pin positions, then frame_count frames.

experiment: {"width_m", "height_m", "fps", "frame_count", "mass_kg" (optional, > 0 overrides the
density), "pins": [{"uv": [u, v], "positions_m": [[x, y, z] per frame]}]}; parameters: a fabric
preset's "parameters". Returns {"status", "reason", "equilibrium_converged", "frames": per frame
rows*cols (x, y, z) tuples (vertex r*cols + c, row 0 at v = 0), "pinned_vertices", "wall_time_s"}.
progress(frame, frame_count) -> bool may cancel (status "cancelled"); initial_positions (rows*cols
[x, y, z]) starts the equilibrium search there instead of the hanging start.)");
    cloth_module.def(
        "check_folds",
        [](const py::dict& parameters, double edge_m, double gravity_m_per_s2) {
            if (!(edge_m > 0.0) || !std::isfinite(edge_m))
                throw Error("<options>", "edge_m", "must be a positive length", "give the mesh's edge in metres");
            const cloth::FoldCheck check = cloth::check_folds(material_from_dict(parameters), edge_m, gravity_m_per_s2);
            py::dict result;
            result["fold_length_m"] = check.fold_length_m;
            result["edge_m"] = check.edge_m;
            result["longest_edge_m"] = check.longest_edge_m;
            result["holds_folds"] = check.holds_folds;
            return result;
        },
        py::arg("parameters"), py::arg("edge_m"), py::arg("gravity_m_per_s2") = 9.81,
        R"(Whether a mesh with edges edge_m long holds the fabric's folds (cloth::check_folds).

parameters: a fabric preset's "parameters". A hanging fabric folds at about its elastogravity
length (B / (rho g))^(1/3); a mesh whose edges are longer than 4/3 of it folds at its own scale,
and a finer mesh drapes differently. Returns {"fold_length_m" (0: no bending or mass),
"edge_m", "longest_edge_m" (the longest edge that holds the folds), "holds_folds"}.)");
    cloth_module.def("fit", &fit_cloth, py::arg("captures"), py::arg("out") = "", py::arg("name") = "fitted fabric",
                     py::arg("evaluations") = 400, py::arg("budget_seconds") = 0.0, py::arg("seed") = 1,
                     py::arg("rows") = 24, py::arg("cols") = 24, py::arg("integrator") = "implicit",
                     py::arg("fit_to") = std::string(cloth_fit::fit_target_name(cloth_fit::kDefaultFitTarget)),
                     py::arg("search") = "cmaes", py::arg("variability_runs") = 4,
                     py::arg("floor_members") = 4, py::arg("threads") = 0, py::arg("progress") = py::none(),
                     R"(Fit a fabric preset to cloth captures, as `flowvid fit cloth` does (cloth_fit::fit_cloth).

captures: the static drape(s) and waving test(s) of one fabric (capture folders); out: write the
preset there too (*.fabric.json); fit_to: scan (the default), footage or tracks; progress(phase, fraction, message)
-> False cancels (flowvid.Cancelled). Returns {"preset": dict, "start_error", "final_error",
"final_error_floor", "trials": [{"capture", "final_error", "floor"}], "evaluations", "seconds"}.)");
}

}  // namespace flowvid::python
