#include "frame_options.hpp"

#include "flowvid/error.hpp"

#include <algorithm>

namespace flowvid::cli {

namespace {

struct ParsedRange {
    std::optional<int> first, last;
};

bool digits(const std::string& text) {
    return text.size() <= 9 && std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// "A:B", "A:", ":B"; nullopt for anything else.
std::optional<ParsedRange> parse(const std::string& text) {
    const std::size_t colon = text.find(':');
    if (colon == std::string::npos || text.find(':', colon + 1) != std::string::npos) return std::nullopt;
    const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
    if (!digits(a) || !digits(b) || (a.empty() && b.empty())) return std::nullopt;
    ParsedRange range;
    if (!a.empty()) range.first = std::stoi(a);
    if (!b.empty()) range.last = std::stoi(b);
    return range;
}

std::string bare_number_message(const std::string& text) {
    return "--frames takes a range A:B (frames A to B, inclusive, e.g. 1:" + text + "); for a number of frames give " +
           "--frame-count " + text;
}

}  // namespace

void add_frame_options(CLI::App& app, FrameOptions& options, const std::string& range_help, const std::string& count_help,
                       const std::string& default_text) {
    const std::string tail = default_text.empty() ? "" : " (default: " + default_text + ")";
    CLI::Option* range = app.add_option("--frames", options.range, range_help + "; also --frame-count N" + tail)
                             ->type_name("A:B")
                             ->check(CLI::Validator(
                                 [](std::string& text) -> std::string {
                                     if (parse(text)) return "";
                                     if (digits(text) && !text.empty()) return bare_number_message(text);
                                     return "--frames " + text + ": expected A:B (e.g. 1:50; A: and :B leave an end open)";
                                 },
                                 ""));
    CLI::Option* count =
        app.add_option("--frame-count", options.count, count_help)->type_name("N")->check(CLI::Range(1, 1000000));
    count->excludes(range);
}

std::pair<int, int> resolve_frame_range(const FrameOptions& options, int default_first, int default_last, int lowest,
                                        int highest) {
    int first = default_first, last = default_last;
    std::string given = "--frames " + options.range;
    if (options.count > 0) {
        last = first + options.count - 1;
        given = "--frame-count " + std::to_string(options.count);
    } else if (!options.range.empty()) {
        const std::optional<ParsedRange> range = parse(options.range);
        if (!range) throw UsageError("", "", bare_number_message(options.range), "give --frames A:B or --frame-count N");
        first = range->first.value_or(first);
        last = range->last.value_or(last);
    }
    const std::string exists = std::to_string(lowest) + ":" + (highest >= 0 ? std::to_string(highest) : "");
    if (first > last || first < lowest || (highest >= 0 && last > highest))
        throw UsageError("", "", given + ": frames " + std::to_string(first) + ":" + std::to_string(last) +
                                           (first > last ? " is an empty range" : " are not all within " + exists),
                         first > last ? "give A:B with A <= B" : "give a range within " + exists);
    return {first, last};
}

std::pair<int, int> resolve_capture_frames(const FrameOptions& options, const formats::Capture& capture) {
    return resolve_frame_range(options, capture.frames.first, capture.frames.last(), capture.frames.first,
                               capture.frames.last());
}

std::optional<int> resolve_frame_count(const FrameOptions& options, int first, const std::string& why_from_first,
                                       std::optional<int> open_end_count) {
    if (options.count > 0) return options.count;
    if (options.range.empty()) return std::nullopt;
    const std::optional<ParsedRange> range = parse(options.range);
    if (!range) throw UsageError("", "", bare_number_message(options.range), "give --frames A:B or --frame-count N");
    if (range->first && *range->first != first)
        throw UsageError("", "",
                         "--frames " + options.range + ": this command uses frames from the first one, " +
                             std::to_string(first) + " (" + why_from_first + ")",
                         "give --frames " + std::to_string(first) + ":B or --frame-count N");
    if (!range->last) {
        if (!open_end_count)
            throw UsageError("", "", "--frames " + options.range + ": an open end is not taken here",
                             "give --frames " + std::to_string(first) + ":B or --frame-count N");
        return *open_end_count;
    }
    if (*range->last < first)
        throw UsageError("", "", "--frames " + options.range + " is an empty range", "give A:B with A <= B");
    return *range->last - first + 1;
}

std::optional<int> resolve_waving_frame_count(const FrameOptions& options, const std::vector<std::string>& capture_dirs) {
    if (options.range.empty() || options.count > 0) return resolve_frame_count(options, 1, "");
    std::optional<int> count;
    std::string first_capture;
    int first = 1;
    for (const std::string& dir : capture_dirs) {
        const formats::Capture capture = formats::read_capture(dir);
        if (capture.kind != "cloth.waving") continue;
        if (first_capture.empty()) {
            first_capture = dir;
            first = capture.frames.first;
        } else if (capture.frames.first != first) {
            throw UsageError(dir, "frames.first",
                             "waving captures start at different frames (" + std::to_string(first) + " in " +
                                 first_capture + ", " + std::to_string(capture.frames.first) + " here), so a range " +
                                 options.range + " cannot start at both",
                             "give --frame-count N (the first N frames of each)");
        }
    }
    return resolve_frame_count(options, first,
                               "waving frames are compared from the start of the wave, where the fabric is predictable");
}

}  // namespace flowvid::cli
