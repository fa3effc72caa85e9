#pragma once
#include "flowvid/progress.hpp"

#include <nlohmann/json.hpp>
#include <pybind11/pybind11.h>

#include <string>

namespace flowvid::python {
// JSON crosses into Python as text parsed by Python's json module, so the
// add-on receives plain dicts without a C++ JSON binding (json_bridge.cpp).
pybind11::object json_to_python(const nlohmann::json& value);
nlohmann::json python_to_json(const pybind11::object& value);

// Messages quote bytes from the files they describe, which need not be
// UTF-8: they cross as str with undecodable bytes replaced, never as an
// exception of their own (UnicodeDecodeError would hide the real problem).
pybind11::str text_to_python(const std::string& text);

// A Python progress(stage, fraction, message) as the library's Progress: it
// runs with the interpreter's lock held (the work itself runs without), and
// returning False cancels (None or True go on). None: no progress.
Progress progress_from_python(const pybind11::object& progress);

void bind_errors(pybind11::module_& module);
void bind_formats(pybind11::module_& module);
void bind_cloth(pybind11::module_& module);
void bind_flow(pybind11::module_& module);
void bind_gap(pybind11::module_& module);
void bind_rigid(pybind11::module_& module);
}  // namespace flowvid::python
