#include "bindings.hpp"

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <string>

namespace flowvid::python {

pybind11::object json_to_python(const nlohmann::json& value) {
    return pybind11::module_::import("json").attr("loads")(value.dump());
}

// Through the same parser as files, so a dict holding NaN, infinity, a lone
// surrogate or deep nesting becomes a flowvid ValidationError naming the
// problem, not a raw parser exception.
nlohmann::json python_to_json(const pybind11::object& value) {
    const std::string text = pybind11::module_::import("json").attr("dumps")(value).cast<std::string>();
    Diagnostics diagnostics("the Python value");
    std::optional<nlohmann::json> parsed = formats::parse_json_text(text, diagnostics);
    diagnostics.throw_if_errors();
    return parsed ? *parsed : nlohmann::json();
}

Progress progress_from_python(const pybind11::object& progress) {
    if (progress.is_none()) return {};
    return [progress](const ProgressReport& report) {
        pybind11::gil_scoped_acquire hold;
        const pybind11::object answer = progress(report.stage, report.fraction, text_to_python(report.message));
        return answer.is_none() || answer.cast<bool>();
    };
}

}  // namespace flowvid::python
