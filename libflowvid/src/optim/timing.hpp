#pragma once
// Wall-clock helpers the optimizers share for their time budgets. Private to optim.

#include <chrono>

namespace flowvid::optim::detail {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace flowvid::optim::detail
