// The `flowvid` Python module: one bind_<topic>.cpp per topic, gathered here.
// Built against Blender's interpreter (/usr/bin/python3) so the add-on can import it.

#include "bindings.hpp"
#include "flowvid/version.hpp"

#include <pybind11/pybind11.h>

PYBIND11_MODULE(flowvid, module) {
    module.doc() = "flowvid: realistic animation learned from video (fabric presets, flow-based video)";
    module.attr("__version__") = flowvid::version();
    flowvid::python::bind_errors(module);
    flowvid::python::bind_formats(module);
    flowvid::python::bind_cloth(module);
    flowvid::python::bind_flow(module);
    flowvid::python::bind_gap(module);
    flowvid::python::bind_rigid(module);
}
