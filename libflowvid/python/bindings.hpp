#pragma once
#include <pybind11/pybind11.h>

namespace flowvid::python {
void bind_errors(pybind11::module_& module);
void bind_formats(pybind11::module_& module);
void bind_cloth(pybind11::module_& module);
void bind_flow(pybind11::module_& module);
}  // namespace flowvid::python
