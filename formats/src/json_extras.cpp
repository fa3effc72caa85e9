#include "json_extras.hpp"

#include <cmath>
#include <limits>

namespace flowvid::formats::detail {

bool check_header_first_files_lacked(const JsonView& root, const std::string& format_name, const FormatVersion& supported) {
    if (root.json().is_object() && !root.json().contains("format")) {
        root.diagnostics().error("/format", "missing: the file does not say which format it is",
                                 "add \"format\": \"" + format_name + "\", \"version\": \"" + supported.to_string() + "\"");
        return false;
    }
    return check_format_header(root, format_name, supported).has_value();
}

bool check_integer_format_header(const JsonView& root, const std::string& format_name, int supported_version) {
    Diagnostics& diag = root.diagnostics();
    const std::string supported = std::to_string(supported_version);
    if (!root.json().is_object()) {
        diag.error(root.pointer().empty() ? "/" : root.pointer(),
                   "the value is " + root.json().dump().substr(0, 20) + ", not a JSON object",
                   "a " + format_name + " file is a JSON object with \"format\": \"" + format_name + "\"");
        return false;
    }
    bool usable = true;
    const std::optional<std::string> name = root.string("format");
    if (!name) {
        usable = false;
    } else if (*name != format_name) {
        diag.error(json_pointer_child(root.pointer(), "format"), "this is a \"" + *name + "\" file, not \"" + format_name + "\"",
                   "use the command or reader for " + *name + ", or set \"format\": \"" + format_name + "\"");
        return false;
    }
    const std::string version_field = json_pointer_child(root.pointer(), "version");
    if (!root.has("version")) {
        diag.error(version_field, "missing", "add \"version\": " + supported);
        return false;
    }
    const nlohmann::json& version = root.json().at("version");
    const bool integral = version.is_number_integer() ||
                          (version.is_number_float() && std::isfinite(version.get<double>()) &&
                           version.get<double>() == std::floor(version.get<double>()));
    if (!integral) {
        diag.error(version_field, "expected an integer version, found " + version.dump().substr(0, 20),
                   "write \"version\": " + supported + " (a number, not a string)");
        return false;
    }
    const double found = version.get<double>();
    if (found != static_cast<double>(supported_version)) {
        diag.error(version_field,
                   "version " + version.dump() + " is not supported (this flowvid reads version " + supported + ")",
                   found > supported_version ? "upgrade flowvid" : "convert the file with an older flowvid");
        return false;
    }
    return usable;
}

NullableNumber nullable_number_value(const JsonView& value, const NumberRange& range) {
    if (value.json().is_null()) return {};
    NullableNumber out;
    out.value = value.as_number(range);
    out.ok = out.value.has_value();
    return out;
}

NullableNumber nullable_number(const JsonView& view, const std::string& key, const NumberRange& range, bool required) {
    if (!view.has(key)) {
        if (!required) return {};
        view.diagnostics().error(json_pointer_child(view.pointer(), key), "missing",
                                 "add \"" + key + "\": a number, or null when it could not be measured");
        return {false, std::nullopt};
    }
    return nullable_number_value(view.child(key), range);
}

std::optional<std::vector<std::string>> string_array(const JsonView& view, const std::string& key, bool required) {
    const std::optional<JsonView> list = view.array(key, required);
    if (!list) return std::nullopt;
    std::vector<std::string> out;
    bool ok = true;
    for (std::size_t i = 0; i < list->size(); ++i) {
        const JsonView element = list->element(i);
        if (!element.json().is_string()) {
            view.diagnostics().error(element.pointer(), std::string("expected a string, found ") + element.json().type_name(),
                                     "write each entry as a string");
            ok = false;
            continue;
        }
        out.push_back(element.json().get<std::string>());
    }
    if (!ok) return std::nullopt;
    return out;
}

std::optional<std::string> non_empty_string(const JsonView& view, const std::string& key, const std::string& fix,
                                            bool required) {
    std::optional<std::string> text = view.string(key, required);
    if (text && text->empty()) {
        view.diagnostics().error(json_pointer_child(view.pointer(), key), "empty", fix);
        return std::nullopt;
    }
    return text;
}

std::optional<Eigen::Vector3d> point_m(const JsonView& point, bool allow_null) {
    if (!point.json().is_array() || point.size() != 3) {
        point.diagnostics().error(point.pointer(), "expected [x, y, z], found " + point.json().dump().substr(0, 40),
                                  "write the position as three numbers in metres");
        return std::nullopt;
    }
    Eigen::Vector3d p;
    bool ok = true;
    for (std::size_t k = 0; k < 3; ++k) {
        const JsonView coordinate = point.element(k);
        if (allow_null && coordinate.json().is_null()) {
            p(static_cast<Eigen::Index>(k)) = std::numeric_limits<double>::quiet_NaN();
            continue;
        }
        const std::optional<double> v = coordinate.as_number(NumberRange{});
        if (v) p(static_cast<Eigen::Index>(k)) = *v;
        else ok = false;
    }
    if (!ok) return std::nullopt;
    return p;
}

bool expect_object(const JsonView& element, const std::string& fix) {
    if (element.json().is_object()) return true;
    element.diagnostics().error(element.pointer(), std::string("expected an object, found ") + element.json().type_name(), fix);
    return false;
}

}  // namespace flowvid::formats::detail
