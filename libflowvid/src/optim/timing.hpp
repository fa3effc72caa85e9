#pragma once
// Wall-clock helpers the optimizers share for their time budgets. Private to optim.

#include <chrono>
#include <cstdio>
#include <string>

namespace flowvid::optim::detail {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// The message of an optimiser's progress report: "N evaluations, best V",
// then "<scale_name> s, ETA s" when given (scale_name empty: left out).
inline std::string progress_message(long long evaluations, double best_value, const char* scale_name = "",
                                    double scale = 0.0, double eta_s = -1.0) {
    char text[160];
    int used = std::snprintf(text, sizeof text, "%lld evaluations, best %.4g", evaluations, best_value);
    if (*scale_name && used > 0 && used < static_cast<int>(sizeof text))
        used += std::snprintf(text + used, sizeof text - static_cast<std::size_t>(used), ", %s %.3g", scale_name, scale);
    if (eta_s >= 0.0 && used > 0 && used < static_cast<int>(sizeof text))
        std::snprintf(text + used, sizeof text - static_cast<std::size_t>(used), ", ETA %.0f s", eta_s);
    return text;
}

}  // namespace flowvid::optim::detail
