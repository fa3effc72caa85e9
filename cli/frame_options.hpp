#pragma once
// One frame grammar for every command: `--frames A:B` names frames A to B
// (inclusive; "A:" and ":B" leave an end open) and `--frame-count N` the
// first N. A bare `--frames N` is refused with both spellings, so that a
// count is never read as a range or the other way round.
//
// Commands that compare or use frames from the start of a sequence (the
// cloth fits, track, quality) take either spelling, and refuse a range that
// does not start at the sequence's first frame, saying why.

#include "flowvid/formats/capture.hpp"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace flowvid::cli {

struct FrameOptions {
    std::string range;  // --frames as typed; empty: not given
    int count = 0;      // --frame-count; 0: not given
    bool given() const { return !range.empty() || count > 0; }
};

// Adds --frames A:B and --frame-count N (mutually exclusive). `range_help`
// and `count_help` say what the frames are for this command; `default_text`
// (may be empty) what applies when neither is given.
void add_frame_options(CLI::App& app, FrameOptions& options, const std::string& range_help, const std::string& count_help,
                       const std::string& default_text = "");

// Frames first..last for a command that takes any range. Open ends and no
// selection take [default_first, default_last]; --frame-count N is
// default_first..default_first+N-1. `lowest`/`highest` bound what exists
// (highest < 0: no bound). Throws flowvid::UsageError naming the option.
std::pair<int, int> resolve_frame_range(const FrameOptions& options, int default_first, int default_last, int lowest,
                                        int highest);

// Frames first..last of a capture (frame numbers as in its capture.json).
std::pair<int, int> resolve_capture_frames(const FrameOptions& options, const formats::Capture& capture);

// How many frames from the start, for a command that always starts at the
// first frame `first` (why_from_first says why, for the refusal of a range
// that starts elsewhere). nullopt when neither option was given (the
// command's default applies). An open end ("1:") is `open_end_count`, or
// refused when that is nullopt. Throws flowvid::UsageError.
std::optional<int> resolve_frame_count(const FrameOptions& options, int first, const std::string& why_from_first,
                                       std::optional<int> open_end_count = std::nullopt);

// As resolve_frame_count for the waving frames of cloth captures: a range
// must start at each waving capture's first frame (read from its
// capture.json).
std::optional<int> resolve_waving_frame_count(const FrameOptions& options, const std::vector<std::string>& capture_dirs);

}  // namespace flowvid::cli
