#include "bindings.hpp"

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <pybind11/stl.h>

namespace py = pybind11;

namespace flowvid::python {

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
}

}  // namespace flowvid::python
