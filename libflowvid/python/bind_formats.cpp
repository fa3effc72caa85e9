#include "bindings.hpp"

#include "flowvid/formats/fabric_preset.hpp"

#include <pybind11/stl.h>

namespace py = pybind11;

namespace flowvid::python {

void bind_formats(py::module_& module) {
    py::module_ formats = module.def_submodule("formats", "Portable file formats");
    formats.def(
        "read_fabric_preset",
        [](const std::string& path) {
            return json_to_python(formats::fabric_preset_to_json(formats::read_fabric_preset(path)));
        },
        py::arg("path"), "Read and validate a *.fabric.json; returns it as a dict (raises ValidationError).");
    formats.def(
        "write_fabric_preset",
        [](const std::string& path, const py::object& preset) {
            Diagnostics diagnostics(path);
            std::optional<formats::FabricPreset> parsed =
                formats::parse_fabric_preset(python_to_json(preset), diagnostics, formats::Strictness::strict);
            diagnostics.throw_if_errors();
            formats::write_fabric_preset(path, *parsed);
        },
        py::arg("path"), py::arg("preset"), "Validate a preset dict and write it atomically.");
    formats.def(
        "validate_fabric_preset",
        [](const std::string& path) {
            pybind11::list messages;
            for (const Problem& problem : formats::validate_fabric_preset_file(path, formats::Strictness::strict))
                messages.append(text_to_python(problem.to_string()));
            return messages;
        },
        py::arg("path"), "Every problem of a preset file, as messages (empty when valid).");
}

}  // namespace flowvid::python
