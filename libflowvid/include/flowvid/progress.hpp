#pragma once
// How long work reports progress and is cancelled, one shape for the whole
// library: the work calls a Progress with the stage it is in ("read clip",
// "render"), the fraction of that stage done, and now and then a line for
// the user's log (what was chosen and why, warnings). The callback returns
// false to cancel; the work then stops at its next report and throws
// Cancelled, unless its entry point says it returns what it finished (a
// render returns the frames it wrote).

#include <functional>
#include <stdexcept>
#include <string>

namespace flowvid {

struct ProgressReport {
    std::string stage;
    // Of this stage, 0..1. Negative: no update, `message` is a line for the
    // log (report_message).
    double fraction = 0.0;
    // With a fraction: a detail shown beside it ("frame 12"), may be empty.
    std::string message;
};

// Returns false to cancel. An empty Progress reports nowhere and never cancels.
using Progress = std::function<bool(const ProgressReport&)>;

// Thrown by work that was cancelled through its Progress.
struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
};

// Reports `fraction` of `stage`; throws Cancelled when the callback says stop.
void report_progress(const Progress& progress, const std::string& stage, double fraction);
// Passes a line to the log (it does not cancel: a message is not a checkpoint).
void report_message(const Progress& progress, const std::string& stage, const std::string& message);

}  // namespace flowvid
