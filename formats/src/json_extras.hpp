#pragma once
// Small helpers shared by the readers of the gap-diagnosis, gap-bench and
// rigid formats (diagnosis.cpp, gap_bench_labels.cpp, rigid_fit.cpp,
// rectification.cpp) on top of json_fields.hpp. Private to flowvid::formats.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats::detail {

// "format" and an integer "version" (the formats that have written
// "version": 1 since their first file): another format or another version
// is an error naming /format or /version. Returns whether both are usable.
bool check_integer_format_header(const JsonView& root, const std::string& format_name, int supported_version);

// The header of a format whose first files had none (flowvid swatch's first
// release): a document without "format" is refused with a fix naming the
// header to add; otherwise check_format_header. Returns whether it is usable.
bool check_header_first_files_lacked(const JsonView& root, const std::string& format_name, const FormatVersion& supported);

// A number that may be null: JSON cannot hold NaN or infinity, so a writer
// stores them (and "not measured") as null. `present` tells whether a
// usable number came back; a null sets it false without a problem. A value
// of another type or out of range is an error.
struct NullableNumber {
    bool ok = true;                 // false: a problem was recorded
    std::optional<double> value;    // nullopt: null (or absent when optional)
};
NullableNumber nullable_number(const JsonView& view, const std::string& key, const NumberRange& range,
                               bool required = true);
// The same for an array element (the view itself).
NullableNumber nullable_number_value(const JsonView& value, const NumberRange& range);

// An array of strings (each element checked); nullopt when absent or mistyped.
std::optional<std::vector<std::string>> string_array(const JsonView& view, const std::string& key, bool required = true);

// A non-empty string (empty is an error naming the field with `fix`).
std::optional<std::string> non_empty_string(const JsonView& view, const std::string& key, const std::string& fix,
                                            bool required = true);

// A point [x, y, z] in metres (the view itself, an array element), finite; a
// null coordinate reads as NaN where `allow_null` (a writer's NaN). nullopt
// after an error naming the element.
std::optional<Eigen::Vector3d> point_m(const JsonView& point, bool allow_null = false);

// An element of an array that must be an object: false (and an error) otherwise.
bool expect_object(const JsonView& element, const std::string& fix);

// Every problem of a JSON file of one format, for `flowvid validate`:
// never throws on bad content (unreadable files become a problem).
template <class Parse>
std::vector<Problem> validate_json_file(const std::string& path, Strictness strictness, Parse parse) {
    Diagnostics diagnostics(path);
    if (std::optional<std::string> text = read_text_reporting(path, diagnostics))
        if (std::optional<nlohmann::json> document = parse_json_text(*text, diagnostics))
            parse(*document, diagnostics, strictness);
    return diagnostics.problems();
}

// Dumps `document` as the file will hold it, checks what a reader will see
// (strictly: a writer writes no unknown key) and writes it atomically. On a
// problem throws ValidationError naming `path`, and `path` is left as it was.
template <class Parse>
void write_validated_json(const std::string& path, const nlohmann::json& document, Parse parse);

}  // namespace flowvid::formats::detail

#include "flowvid/formats/atomic_file.hpp"

#include <ostream>

namespace flowvid::formats::detail {

template <class Parse>
void write_validated_json(const std::string& path, const nlohmann::json& document, Parse parse) {
    // Judge the bytes that will be on disk (NaN and infinity become null there).
    const std::string text = dump_json(document);
    Diagnostics diagnostics(path);
    if (std::optional<nlohmann::json> reread = parse_json_text(text, diagnostics))
        parse(*reread, diagnostics, Strictness::strict);
    diagnostics.throw_if_errors();
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace flowvid::formats::detail
