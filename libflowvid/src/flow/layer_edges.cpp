#include "layer_edges.hpp"

#include "synthesis_kernels.hpp"
#include "warp_table.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <deque>

namespace flowvid::flow::detail {

namespace {

// One pass of a sliding maximum over `radius` either side, along rows
// (along_x) or columns.
void max_pass(const std::vector<float>& in, std::vector<float>& out, int width, int height, int radius, bool along_x) {
    const int n = along_x ? width : height, lines = along_x ? height : width;
    const auto at = [&](int line, int i) {
        return along_x ? static_cast<std::size_t>(line) * width + i : static_cast<std::size_t>(i) * width + line;
    };
    std::deque<int> window;  // indices of decreasing values
    for (int l = 0; l < lines; ++l) {
        window.clear();
        int next = 0;
        for (int i = 0; i < n; ++i) {
            for (; next < n && next <= i + radius; ++next) {
                while (!window.empty() && in[at(l, window.back())] <= in[at(l, next)]) window.pop_back();
                window.push_back(next);
            }
            while (window.front() < i - radius) window.pop_front();
            out[at(l, i)] = in[at(l, window.front())];
        }
    }
}

}  // namespace

void fade_layer_edges(std::vector<float>& coverage, int width, int height, double fade_px) {
    const int radius = static_cast<int>(std::lround(0.5 * fade_px));
    if (radius < 1 || width <= 0 || height <= 0) return;
    if (std::none_of(coverage.begin(), coverage.end(), [](float c) { return c > 0.0f; })) return;
    std::vector<float> tent = coverage, scratch(coverage.size());
    smooth_in_place(tent, width, height, 1, radius);
    // The tent's largest value within its reach: 1 beside a layer wider than
    // the fade, less beside a thin one (a lone line, a single patch), whose
    // middle then stays and whose sides fade instead of all of it.
    std::vector<float> largest(coverage.size());
    max_pass(tent, scratch, width, height, 2 * radius, true);
    max_pass(scratch, largest, width, height, 2 * radius, false);
    for (std::size_t i = 0; i < coverage.size(); ++i)
        if (coverage[i] > 0.0f && largest[i] > 0.0f)
            coverage[i] *= std::clamp(2.0f * tent[i] / largest[i] - 1.0f, 0.0f, 1.0f);
}

void composite_faded_layer(const std::vector<float>& layer, std::vector<float>& layer_coverage, double fade_px, bool screen,
                           RgbImage& out, std::vector<float>* coverage) {
    fade_layer_edges(layer_coverage, out.width, out.height, fade_px);
    for (std::size_t i = 0; i < layer_coverage.size(); ++i) {
        const float c = layer_coverage[i];
        if (!(c > 0.0f)) continue;
        composite(out.rgb.data() + 3 * i, layer.data() + 3 * i, c, screen);
        if (coverage) (*coverage)[i] = c;
    }
}

}  // namespace flowvid::flow::detail
