#include "flowvid/progress.hpp"

namespace flowvid {

void report_progress(const Progress& progress, const std::string& stage, double fraction) {
    if (progress && !progress(ProgressReport{stage, fraction, {}})) throw Cancelled();
}

void report_message(const Progress& progress, const std::string& stage, const std::string& message) {
    if (progress) progress(ProgressReport{stage, -1.0, message});
}

}  // namespace flowvid
