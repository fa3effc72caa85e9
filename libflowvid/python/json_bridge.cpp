#include "bindings.hpp"

#include <string>

namespace flowvid::python {

pybind11::object json_to_python(const nlohmann::json& value) {
    return pybind11::module_::import("json").attr("loads")(value.dump());
}

nlohmann::json python_to_json(const pybind11::object& value) {
    return nlohmann::json::parse(pybind11::module_::import("json").attr("dumps")(value).cast<std::string>());
}

}  // namespace flowvid::python
