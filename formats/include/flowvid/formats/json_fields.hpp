#pragma once
// Reading JSON with complete diagnostics: every accessor records a problem
// (file, JSON pointer, message, fix) instead of throwing, so a validator walks
// the whole document and reports every mistake at once.

#include "flowvid/error.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

// How strictly unknown keys are judged: a reader tolerates them with a warning
// (files from a newer minor version may add keys); `flowvid validate` refuses them.
enum class Strictness { lenient, strict };

struct NumberRange {
    double min = -std::numeric_limits<double>::infinity();
    double max = std::numeric_limits<double>::infinity();
    bool min_exclusive = false;
    std::string unit;  // shown in messages, e.g. "kg/m^2"

    static NumberRange positive(std::string unit) { return {0.0, std::numeric_limits<double>::infinity(), true, std::move(unit)}; }
    static NumberRange non_negative(std::string unit) { return {0.0, std::numeric_limits<double>::infinity(), false, std::move(unit)}; }
    static NumberRange closed(double lo, double hi, std::string unit = {}) { return {lo, hi, false, std::move(unit)}; }
};

std::string json_pointer_child(const std::string& parent, const std::string& key);
std::string json_pointer_child(const std::string& parent, std::size_t index);

class JsonView {
public:
    JsonView(const nlohmann::json& value, std::string pointer, Diagnostics& diagnostics,
             Strictness strictness = Strictness::lenient);

    const nlohmann::json& json() const { return *m_value; }
    const std::string& pointer() const { return m_pointer; }
    Diagnostics& diagnostics() const { return *m_diagnostics; }
    Strictness strictness() const { return m_strictness; }
    bool has(const std::string& key) const;

    // Each accessor reports a missing (when required) or mistyped field and
    // returns nullopt; a present, well-typed field is returned.
    std::optional<JsonView> object(const std::string& key, bool required = true) const;
    std::optional<JsonView> array(const std::string& key, bool required = true) const;
    std::optional<std::string> string(const std::string& key, bool required = true) const;
    std::optional<double> number(const std::string& key, const NumberRange& range, bool required = true) const;
    std::optional<std::int64_t> integer(const std::string& key, std::int64_t min, std::int64_t max,
                                        bool required = true) const;
    std::optional<bool> boolean(const std::string& key, bool required = true) const;
    // A fixed-length array of numbers, e.g. a 3-vector or a 4x4 matrix row.
    std::optional<std::vector<double>> numbers(const std::string& key, std::size_t count, const NumberRange& range,
                                               bool required = true) const;

    // Elements of an array view.
    std::size_t size() const;
    JsonView element(std::size_t index) const;
    JsonView child(const std::string& key) const;  // key must exist

    // Flags keys that are not in `known`: an error when strict, a warning otherwise.
    void check_known_keys(std::initializer_list<const char*> known) const;

    // The value itself as a number in range (for array elements).
    std::optional<double> as_number(const NumberRange& range) const;

private:
    void report_type(const std::string& key, const char* expected) const;

    const nlohmann::json* m_value;
    std::string m_pointer;
    Diagnostics* m_diagnostics;
    Strictness m_strictness;
};

// read_text_file from atomic_file.hpp, declared here to keep this header light.
std::string read_text_or_throw(const std::string& path);

// "MAJOR.MINOR" as written in flowvid files.
struct FormatVersion {
    int major = 0;
    int minor = 0;
    std::string to_string() const { return std::to_string(major) + "." + std::to_string(minor); }
    static std::optional<FormatVersion> parse(const std::string& text);
};

// Checks "format" and "version": another format name or major version is an
// error; a newer minor version is a warning (read what we know, keep going).
// Returns the version found when usable.
std::optional<FormatVersion> check_format_header(const JsonView& root, const std::string& format_name,
                                                 FormatVersion supported);

// Parses JSON text; a syntax error is recorded with line and column and
// nullopt is returned.
// Deepest nesting of arrays and objects parse_json_text accepts: flowvid's
// files nest a few levels, and refusing deeper input before parsing keeps
// hostile files from overflowing the stack.
inline constexpr std::size_t kMaxJsonNesting = 200;

std::optional<nlohmann::json> parse_json_text(const std::string& text, Diagnostics& diagnostics);

// Pretty JSON (2-space indent, shortest round-trip numbers) followed by a newline.
std::string dump_json(const nlohmann::json& value);

// Reads a file for a validator: an unreadable file becomes a problem (nullopt)
// rather than an exception, so `flowvid validate` lists it with the others.
std::optional<std::string> read_text_reporting(const std::string& path, Diagnostics& diagnostics);

// Reads a JSON file of one flowvid format with its parser
// `parse(document, diagnostics, strictness) -> std::optional<T>`, leniently.
// Throws IoError (unreadable) or ValidationError (every problem); warnings go
// to `warnings` when given.
template <class T, class Parse>
T read_json_format_file(const std::string& path, Parse parse, std::vector<Problem>* warnings) {
    Diagnostics diagnostics(path);
    const std::string text = read_text_or_throw(path);
    std::optional<T> value;
    if (std::optional<nlohmann::json> document = parse_json_text(text, diagnostics))
        value = parse(*document, diagnostics, Strictness::lenient);
    diagnostics.throw_if_errors();
    if (!value) throw ValidationError({Problem{Problem::Severity::error, path, "", "could not be read", ""}});
    if (warnings) *warnings = diagnostics.warnings();
    return std::move(*value);
}

}  // namespace flowvid::formats
