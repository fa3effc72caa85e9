#include "flowvid/formats/json_fields.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <algorithm>
#include <cctype>
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

// A few characters of a value for a message, without dumping a whole
// (possibly huge) document.
std::string describe_value_briefly(const nlohmann::json& value) {
    if (value.is_array()) return "an array of " + std::to_string(value.size()) + " elements";
    if (value.is_object()) return "an object";
    std::string text = value.dump();
    if (text.size() > 20) text = text.substr(0, 20) + "...";
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
        diag.error(root.pointer().empty() ? "/" : root.pointer(), "the value is " + describe_value_briefly(root.json()) + ", not a JSON object",
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

namespace {
struct TextPosition {
    std::size_t line = 1;
    std::size_t column = 1;
    std::string describe() const { return "line " + std::to_string(line) + ", column " + std::to_string(column); }
};

TextPosition position_of(const std::string& text, std::size_t offset) {
    TextPosition position;
    const std::size_t end = std::min(offset, text.size());
    for (std::size_t i = 0; i < end; ++i) {
        if (text[i] == '\n') { ++position.line; position.column = 1; }
        else ++position.column;
    }
    return position;
}

// The offset of the first array or object nested deeper than kMaxJsonNesting,
// or npos. Checked before parsing because a recursive parser (and any
// recursive walk of the result) would overflow the stack on hostile input.
std::size_t first_too_deep(const std::string& text) {
    std::size_t depth = 0;
    bool in_string = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (in_string) {
            if (c == '\\') ++i;  // skip the escaped character
            else if (c == '"') in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            if (++depth > kMaxJsonNesting) return i;
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    return std::string::npos;
}

// JSON has no NaN or Infinity, though many writers (Python's json among them)
// emit them; say so instead of "invalid literal".
bool is_non_finite_literal_at(const std::string& text, std::size_t offset) {
    std::size_t start = std::min(offset, text.size());
    while (start > 0 && (std::isalpha(static_cast<unsigned char>(text[start - 1])) || text[start - 1] == '-')) --start;
    std::size_t end = start;
    while (end < text.size() && (std::isalpha(static_cast<unsigned char>(text[end])) || text[end] == '-')) ++end;
    std::string word = text.substr(start, end - start);
    if (!word.empty() && word[0] == '-') word.erase(0, 1);
    for (char& c : word) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return word == "nan" || word == "infinity" || word == "inf";
}
}  // namespace

std::optional<nlohmann::json> parse_json_text(const std::string& text, Diagnostics& diagnostics) {
    if (const std::size_t too_deep = first_too_deep(text); too_deep != std::string::npos) {
        diagnostics.error(position_of(text, too_deep).describe(),
                          "arrays and objects nest deeper than " + std::to_string(kMaxJsonNesting) + " levels",
                          "this is not a flowvid file (they nest a few levels); check what wrote it");
        return std::nullopt;
    }
    try {
        return nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& error) {
        // Turn the byte offset into line:column, which editors understand.
        const std::size_t offset = error.byte == 0 ? 0 : error.byte - 1;
        if (is_non_finite_literal_at(text, offset)) {
            diagnostics.error(position_of(text, offset).describe(), "JSON has no NaN or Infinity",
                              "write a finite number there (flowvid's writers never write NaN or Infinity)");
            return std::nullopt;
        }
        std::string reason = error.what();
        const std::size_t colon = reason.rfind(": ");
        if (colon != std::string::npos) reason = reason.substr(colon + 2);
        diagnostics.error(position_of(text, offset).describe(), "malformed JSON: " + reason,
                          "fix the JSON syntax there (a JSON linter helps)");
        return std::nullopt;
    } catch (const nlohmann::json::out_of_range& error) {
        // nlohmann reports a number beyond double range (1e999) without its
        // position; its message quotes the token, so find that.
        std::string token;
        const std::string what = error.what();
        if (const std::size_t open = what.find('\''); open != std::string::npos)
            if (const std::size_t close = what.find('\'', open + 1); close != std::string::npos)
                token = what.substr(open + 1, close - open - 1);
        const std::size_t at = token.empty() ? std::string::npos : text.find(token);
        diagnostics.error(at == std::string::npos ? std::string("the document") : position_of(text, at).describe(),
                          "the number " + (token.empty() ? std::string() : token + " ") +
                              "is beyond the range of a double (about 1.8e308)",
                          "write a finite number in SI units there");
        return std::nullopt;
    } catch (const nlohmann::json::exception& error) {
        diagnostics.error("the document", std::string("unreadable JSON: ") + error.what(),
                          "rewrite the file with a JSON writer");
        return std::nullopt;
    }
}

std::string read_text_or_throw(const std::string& path) { return read_text_file(path); }

std::optional<std::string> read_text_reporting(const std::string& path, Diagnostics& diagnostics) {
    try {
        return read_text_file(path);
    } catch (const IoError& error) {
        diagnostics.error(error.field(), error.message(), error.fix());
        return std::nullopt;
    }
}

std::string dump_json(const nlohmann::json& value) {
    return value.dump(2) + "\n";
}

}  // namespace flowvid::formats
