#pragma once
// Small statistics of per-frame series shared by the flow measures
// (quality.cpp, region_quality.cpp) and defaults (geometry.cpp).

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <vector>

namespace flowvid::flow::detail {

inline double mean_of(const std::vector<double>& values) {
    return values.empty() ? 0.0 : std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

// Linear interpolation between order statistics (numpy's default); 0 when empty.
inline double percentile(std::vector<double> values, double p) {
    if (values.empty()) return 0.0;
    std::sort(values.begin(), values.end());
    const double r = p * static_cast<double>(values.size() - 1);
    const std::size_t i = static_cast<std::size_t>(r);
    const std::size_t j = std::min(i + 1, values.size() - 1);
    return values[i] + (r - static_cast<double>(i)) * (values[j] - values[i]);
}

}  // namespace flowvid::flow::detail
