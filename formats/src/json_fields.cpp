#include "flowvid/formats/json_fields.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <cmath>
#include <sstream>

namespace flowvid::formats {

namespace {
std::string type_name(const nlohmann::json& value) {
    return value.type_name();
}

std::string format_number(double value) {
    std::ostringstream text;
    text << value;
    return text.str();
}

std::string describe_range(const NumberRange& range) {
    std::string text;
    const bool has_min = std::isfinite(range.min);
    const bool has_max = std::isfinite(range.max);
    if (has_min && has_max)
        text = std::string(range.min_exclusive ? "in (" : "in [") + format_number(range.min) + ", " +
               format_number(range.max) + "]";
    else if (has_min)
        text = std::string(range.min_exclusive ? "> " : ">= ") + format_number(range.min);
    else if (has_max)
        text = "<= " + format_number(range.max);
    else
        text = "finite";
    if (!range.unit.empty()) text += " " + range.unit;
    return text;
}

bool in_range(double value, const NumberRange& range) {
    if (!std::isfinite(value)) return false;
    if (range.min_exclusive ? !(value > range.min) : !(value >= range.min)) return false;
    return value <= range.max;
}
}  // namespace

std::string json_pointer_child(const std::string& parent, const std::string& key) {
    std::string escaped;
    for (char c : key) {
        if (c == '~') escaped += "~0";
        else if (c == '/') escaped += "~1";
        else escaped += c;
    }
    return parent + "/" + escaped;
}

std::string json_pointer_child(const std::string& parent, std::size_t index) {
    return parent + "/" + std::to_string(index);
}

JsonView::JsonView(const nlohmann::json& value, std::string pointer, Diagnostics& diagnostics, Strictness strictness)
    : m_value(&value), m_pointer(std::move(pointer)), m_diagnostics(&diagnostics), m_strictness(strictness) {}

bool JsonView::has(const std::string& key) const {
    return m_value->is_object() && m_value->contains(key);
}

void JsonView::report_type(const std::string& key, const char* expected) const {
    const nlohmann::json& value = m_value->at(key);
    m_diagnostics->error(json_pointer_child(m_pointer, key),
                         std::string("expected ") + expected + ", found " + type_name(value),
                         std::string("write ") + expected + " here");
}

std::optional<JsonView> JsonView::object(const std::string& key, bool required) const {
    if (!has(key)) {
        if (required) m_diagnostics->error(json_pointer_child(m_pointer, key), "missing", "add the object \"" + key + "\"");
        return std::nullopt;
    }
    if (!m_value->at(key).is_object()) {
        report_type(key, "an object");
        return std::nullopt;
    }
    return child(key);
}

std::optional<JsonView> JsonView::array(const std::string& key, bool required) const {
    if (!has(key)) {
        if (required) m_diagnostics->error(json_pointer_child(m_pointer, key), "missing", "add the array \"" + key + "\"");
        return std::nullopt;
    }
    if (!m_value->at(key).is_array()) {
        report_type(key, "an array");
        return std::nullopt;
    }
    return child(key);
}

std::optional<std::string> JsonView::string(const std::string& key, bool required) const {
    if (!has(key)) {
        if (required) m_diagnostics->error(json_pointer_child(m_pointer, key), "missing", "add the string \"" + key + "\"");
        return std::nullopt;
    }
    if (!m_value->at(key).is_string()) {
        report_type(key, "a string");
        return std::nullopt;
    }
    return m_value->at(key).get<std::string>();
}

std::optional<double> JsonView::number(const std::string& key, const NumberRange& range, bool required) const {
    if (!has(key)) {
        if (required)
            m_diagnostics->error(json_pointer_child(m_pointer, key), "missing",
                                 "add \"" + key + "\": a number " + describe_range(range));
        return std::nullopt;
    }
    return child(key).as_number(range);
}

std::optional<double> JsonView::as_number(const NumberRange& range) const {
    if (!m_value->is_number()) {
        // JSON has no NaN or infinity; writers that try produce null.
        const std::string found = m_value->is_null() ? "null (NaN or infinity cannot be stored)" : type_name(*m_value);
        m_diagnostics->error(m_pointer, "expected a number " + describe_range(range) + ", found " + found,
                             "write a finite number");
        return std::nullopt;
    }
    const double value = m_value->get<double>();
    if (!in_range(value, range)) {
        m_diagnostics->error(m_pointer, "value " + format_number(value) + " is out of range",
                             "use a value " + describe_range(range));
        return std::nullopt;
    }
    return value;
}

std::optional<std::int64_t> JsonView::integer(const std::string& key, std::int64_t min, std::int64_t max,
                                              bool required) const {
    const std::string where = json_pointer_child(m_pointer, key);
    const std::string expected = "an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
    if (!has(key)) {
        if (required) m_diagnostics->error(where, "missing", "add \"" + key + "\": " + expected);
        return std::nullopt;
    }
    const nlohmann::json& value = m_value->at(key);
    if (!value.is_number_integer()) {
        if (value.is_number_float() && std::isfinite(value.get<double>()) &&
            value.get<double>() == std::floor(value.get<double>())) {
            // 2.0 where 2 is meant: accept, it is unambiguous.
        } else {
            report_type(key, expected.c_str());
            return std::nullopt;
        }
    }
    const double as_double = value.get<double>();
    if (as_double < static_cast<double>(min) || as_double > static_cast<double>(max)) {
        m_diagnostics->error(where, "value " + value.dump() + " is out of range", "use " + expected);
        return std::nullopt;
    }
    return value.is_number_integer() ? value.get<std::int64_t>() : static_cast<std::int64_t>(as_double);
}

std::optional<bool> JsonView::boolean(const std::string& key, bool required) const {
    if (!has(key)) {
        if (required) m_diagnostics->error(json_pointer_child(m_pointer, key), "missing", "add \"" + key + "\": true or false");
        return std::nullopt;
    }
    if (!m_value->at(key).is_boolean()) {
        report_type(key, "true or false");
        return std::nullopt;
    }
    return m_value->at(key).get<bool>();
}

std::optional<std::vector<double>> JsonView::numbers(const std::string& key, std::size_t count,
                                                     const NumberRange& range, bool required) const {
    std::optional<JsonView> list = array(key, required);
    if (!list) return std::nullopt;
    if (list->size() != count) {
        m_diagnostics->error(list->pointer(),
                             "expected " + std::to_string(count) + " numbers, found " + std::to_string(list->size()),
                             "write exactly " + std::to_string(count) + " numbers");
        return std::nullopt;
    }
    std::vector<double> values;
    bool ok = true;
    for (std::size_t i = 0; i < count; ++i) {
        std::optional<double> value = list->element(i).as_number(range);
        if (!value) ok = false;
        values.push_back(value.value_or(0.0));
    }
    if (!ok) return std::nullopt;
    return values;
}

std::size_t JsonView::size() const {
    return (m_value->is_array() || m_value->is_object()) ? m_value->size() : 0;
}

JsonView JsonView::element(std::size_t index) const {
    return JsonView(m_value->at(index), json_pointer_child(m_pointer, index), *m_diagnostics, m_strictness);
}

JsonView JsonView::child(const std::string& key) const {
    return JsonView(m_value->at(key), json_pointer_child(m_pointer, key), *m_diagnostics, m_strictness);
}

void JsonView::check_known_keys(std::initializer_list<const char*> known) const {
    if (!m_value->is_object()) return;
    for (auto it = m_value->begin(); it != m_value->end(); ++it) {
        bool found = false;
        for (const char* name : known) found = found || it.key() == name;
        if (found) continue;
        std::string list;
        for (const char* name : known) list += (list.empty() ? "" : ", ") + std::string(name);
        const std::string where = json_pointer_child(m_pointer, it.key());
        const std::string fix = "remove it or correct its spelling (known here: " + list + ")";
        if (m_strictness == Strictness::strict) m_diagnostics->error(where, "unknown key", fix);
        else m_diagnostics->warning(where, "unknown key (ignored)", fix);
    }
}

std::optional<FormatVersion> FormatVersion::parse(const std::string& text) {
    const std::size_t dot = text.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 >= text.size()) return std::nullopt;
    for (std::size_t i = 0; i < text.size(); ++i)
        if (i != dot && (text[i] < '0' || text[i] > '9')) return std::nullopt;
    if (dot > 6 || text.size() - dot - 1 > 6) return std::nullopt;
    return FormatVersion{std::stoi(text.substr(0, dot)), std::stoi(text.substr(dot + 1))};
}

std::optional<FormatVersion> check_format_header(const JsonView& root, const std::string& format_name,
                                                 FormatVersion supported) {
    Diagnostics& diag = root.diagnostics();
    // Field names are relative to where the header object sits in its document.
    const std::string format_field = json_pointer_child(root.pointer(), "format");
    const std::string version_field = json_pointer_child(root.pointer(), "version");
    if (!root.json().is_object()) {
        diag.error(root.pointer().empty() ? "/" : root.pointer(), "the value is " + root.json().dump().substr(0, 20) + ", not a JSON object",
                   "a " + format_name + " file is a JSON object with \"format\": \"" + format_name + "\"");
        return std::nullopt;
    }
    std::optional<std::string> name = root.string("format");
    if (name && *name != format_name) {
        diag.error(format_field, "this is a \"" + *name + "\" file, not \"" + format_name + "\"",
                   "use the command or reader for " + *name + ", or set \"format\": \"" + format_name + "\"");
        return std::nullopt;
    }
    std::optional<std::string> text = root.string("version");
    if (!text) return std::nullopt;
    std::optional<FormatVersion> version = FormatVersion::parse(*text);
    if (!version) {
        diag.error(version_field, "\"" + *text + "\" is not MAJOR.MINOR", "write \"" + supported.to_string() + "\"");
        return std::nullopt;
    }
    if (version->major != supported.major) {
        diag.error(version_field,
                   "version " + version->to_string() + " is not supported (this flowvid reads " +
                       std::to_string(supported.major) + ".x)",
                   version->major > supported.major ? "upgrade flowvid" : "convert the file with an older flowvid");
        return std::nullopt;
    }
    if (version->minor > supported.minor)
        diag.warning(version_field,
                     "version " + version->to_string() + " is newer than " + supported.to_string() +
                         "; fields this flowvid does not know are ignored",
                     "upgrade flowvid to use every field");
    return version;
}

std::optional<nlohmann::json> parse_json_text(const std::string& text, Diagnostics& diagnostics) {
    try {
        return nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& error) {
        // Turn the byte offset into line:column, which editors understand.
        std::size_t line = 1, column = 1;
        const std::size_t end = std::min<std::size_t>(error.byte == 0 ? 0 : error.byte - 1, text.size());
        for (std::size_t i = 0; i < end; ++i) {
            if (text[i] == '\n') { ++line; column = 1; }
            else ++column;
        }
        std::string reason = error.what();
        const std::size_t colon = reason.rfind(": ");
        if (colon != std::string::npos) reason = reason.substr(colon + 2);
        diagnostics.error("line " + std::to_string(line) + ", column " + std::to_string(column),
                          "malformed JSON: " + reason, "fix the JSON syntax there (a JSON linter helps)");
        return std::nullopt;
    }
}

std::string read_text_or_throw(const std::string& path) { return read_text_file(path); }

std::optional<std::string> read_text_reporting(const std::string& path, Diagnostics& diagnostics) {
    try {
        return read_text_file(path);
    } catch (const IoError& error) {
        diagnostics.error("", error.what(), error.fix());
        return std::nullopt;
    }
}

std::string dump_json(const nlohmann::json& value) {
    return value.dump(2) + "\n";
}

}  // namespace flowvid::formats
