#include "bindings.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/gap/open_model.hpp"
#include "flowvid/threads.hpp"

#include <pybind11/stl.h>

#include <filesystem>
#include <stdexcept>

namespace py = pybind11;

namespace flowvid::python {

namespace {

// flowvid diagnose, in process: the gap model opened as the CLI opens it
// (gap::open_cloth_model / open_rigid_model), then gap::diagnose.
py::object diagnose(const std::vector<std::string>& captures, const std::string& preset, const std::string& fit,
                    const std::string& out, int frames, const std::vector<std::string>& effects, std::uint64_t seed,
                    int threads, const py::object& progress) {
    for (const std::string& name : effects) {  // unknown names fail before the work
        try {
            gap::find_effect(name);
        } catch (const std::invalid_argument& error) {
            throw UsageError("<options>", "effects", error.what(), "name effects of the catalogue");
        }
    }
    gap::DiagnoseSettings settings;
    settings.effects = effects;
    settings.seed = seed;
    settings.progress = progress_from_python(progress);
    if (!out.empty()) formats::create_parent_folder((std::filesystem::path(out) / "diagnosis.json").string());
    nlohmann::json document;
    {
        py::gil_scoped_release release;  // floors and refits take minutes
        gap::ClothGapRequest cloth;
        cloth.frames = frames;
        cloth.threads = threads;
        cloth.swatch.simulation.threads = resolve_thread_count(threads);
        const gap::OpenedGapModel opened = gap::open_gap_model(captures, preset, fit, cloth);
        document = gap::diagnosis_document(gap::diagnose(*opened.model, settings), opened.description);
    }
    if (!out.empty()) formats::write_diagnosis((std::filesystem::path(out) / "diagnosis.json").string(), document);
    return json_to_python(document);
}

}  // namespace

void bind_gap(py::module_& module) {
    py::module_ gap_module = module.def_submodule("gap", "Sim-to-real gap diagnosis");
    gap_module.def("diagnose", &diagnose, py::arg("captures"), py::arg("preset") = "", py::arg("fit") = "",
                   py::arg("out") = "", py::arg("frames") = 30, py::arg("effects") = std::vector<std::string>{},
                   py::arg("seed") = 1, py::arg("threads") = 0, py::arg("progress") = py::none(),
                   R"(Where a fitted simulation departs from footage, which unmodelled effect causes it and how far
the gap shrinks, as `flowvid diagnose` decides it (the library's gap::open_cloth_model or
open_rigid_model, then gap::diagnose), on the diagnoser's default mesh.

captures: cloth captures with preset= (the fitted *.fabric.json), or rigid tosses (fit= an optional
fit.json of the first); out: also write out/diagnosis.json; effects: candidates (default: all);
progress(stage, fraction, message) -> False cancels (flowvid.Cancelled). Returns the diagnosis
document (format flowvid.diagnosis, formats/specs/diagnosis.md) as a dict.)");
}

}  // namespace flowvid::python
