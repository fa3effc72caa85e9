#include "bindings.hpp"

#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

namespace py = pybind11;

namespace flowvid::python {

namespace {

// flowvid synth and flowvid edit, in process.
py::object synthesize(const std::string& bank, const std::string& out, const std::pair<int, int>& frames, bool edit,
                      const std::string& flowlines, const std::string& capture, const std::string& background,
                      const std::string& texture, const py::object& coverage, const py::object& edge_fade,
                      const std::string& mapping,
                      const py::object& carry_background, bool interpolate, bool loop, int threads,
                      const std::string& dense_out, const py::object& progress) {
    flow::SynthesisJob job;
    job.bank_path = bank;
    job.clip_path = capture;
    job.flowlines_path = flowlines;
    job.background = background;
    job.texture_auto = texture == "auto";
    if (!job.texture_auto) job.settings.texture_layer = flow::texture_layer_from_string(texture);
    job.coverage_auto = coverage.is_none();
    if (!coverage.is_none()) job.settings.coverage_weight = coverage.cast<double>();
    job.edge_fade_auto = edge_fade.is_none();
    if (!edge_fade.is_none()) job.settings.edge_fade_px = edge_fade.cast<double>();
    job.edit = edit;
    job.interpolate = interpolate;
    job.settings.mapping = flow::arc_mapping_from_string(mapping);
    // None: carried as the CLI's default (whole textures over what `auto` chose).
    job.carry_background_auto = carry_background.is_none() || carry_background.cast<bool>();
    job.settings.carry_background = !carry_background.is_none() && carry_background.cast<bool>();
    job.edit_settings.threads = threads;
    flow::SynthesisOutput output;
    output.path = out;
    output.first_frame = frames.first;
    output.last_frame = frames.second;
    output.loop = loop;
    output.threads = threads;
    output.dense_lines_path = dense_out;
    const flowvid::Progress report = progress_from_python(progress);
    nlohmann::json summary;
    {
        py::gil_scoped_release release;  // rendering takes seconds to minutes: Blender's UI keeps running
        const flow::SynthesisOutcome outcome = flow::render_synthesis(job, output, report);
        summary = flow::outcome_summary(outcome, job, output);
    }
    return json_to_python(summary);
}

}  // namespace

void bind_flow(py::module_& module) {
    py::module_ flow = module.def_submodule("flow", "Flow-line sets for flow-based video");
    flow.def(
        "read_flowline_set",
        [](const std::string& path) {
            return json_to_python(formats::flowline_set_to_json(formats::read_flowline_drawing(path)));
        },
        py::arg("path"), "Read and validate a *.flowlines.json (or an SVG drawing); returns it as a dict.");
    flow.def(
        "write_flowline_set",
        [](const std::string& path, const py::object& set) {
            Diagnostics diagnostics(path);
            std::optional<formats::FlowLineSet> parsed =
                formats::parse_flowline_set(python_to_json(set), diagnostics, formats::Strictness::strict);
            diagnostics.throw_if_errors();
            formats::write_flowline_set(path, *parsed);
        },
        py::arg("path"), py::arg("set"),
        "Validate a flow-line set dict (every problem, by JSON pointer) and write it atomically.");
    flow.def(
        "validate_flowline_set",
        [](const std::string& path) {
            pybind11::list messages;
            for (const Problem& problem : formats::validate_flowline_set_file(path, formats::Strictness::strict))
                messages.append(text_to_python(problem.to_string()));
            return messages;
        },
        py::arg("path"), "Every problem of a flow-line file, as messages (empty when valid).");
    flow.def("synthesize", &synthesize, py::arg("bank"), py::arg("out"), py::arg("frames") = std::pair<int, int>{1, 100},
             py::arg("edit") = false, py::arg("flowlines") = "", py::arg("capture") = "", py::arg("background") = "auto",
             py::arg("texture") = "auto", py::arg("coverage") = py::none(), py::arg("edge_fade") = py::none(),
             py::arg("mapping") = "equal",
             py::arg("carry_background") = py::none(), py::arg("interpolate") = true, py::arg("loop") = false,
             py::arg("threads") = 0, py::arg("dense_out") = "", py::arg("progress") = py::none(),
             R"(Render frames of the infinite sequence from a particle bank, as `flowvid synth` (edit=False:
along the drawing's input lines) and `flowvid edit` (edit=True: along its output lines, keyed
lines moving) do, through the same library entry point (flow::render_synthesis).

bank: *.bank.exr from `flowvid track`; out: out/%06d.png (.exr, .tif), a folder, a video (.mp4)
or, for one frame, an image; frames: (first, last), 1-based, inclusive; flowlines: the drawing
(default: the capture's); capture: the source clip (default: the one the bank records);
background: auto, median, loop, replay, relit or none; texture: auto, whole or moving;
coverage: None for automatic (0.5 synth, 2 edit); edge_fade: px over which the texture fades
out at its edge, None for automatic (a patch for edits of whole textures, else 0);
carry_background: None = where `auto`
replays the clip; loop: render exactly one period; dense_out: write an edit's dense lines.
progress(stage, fraction, message) -> bool: False cancels (frames written so far are kept;
flowvid.Cancelled before rendering starts). Returns the summary `flowvid synth --json` prints.)");
}

}  // namespace flowvid::python
