#pragma once
// The texture layer's outer edge (SynthesisSettings::edge_fade_px): shared by
// the banded renderer and the whole-frame reference pass, so that both fade
// the same coverage the same way.

#include "flowvid/flow/frames.hpp"

#include <vector>

namespace flowvid::flow::detail {

// Scales `coverage` (width x height, 0..1) so that it falls to 0 at the
// layer's edge over `fade_px` pixels: each value is multiplied by
// clamp(2 T / M - 1, 0, 1), where T is the coverage smoothed by a tent
// reaching fade_px (a box of radius fade_px / 2, twice, shrinking at the
// frame's borders, so that the frame's border is no edge) and M the largest
// T within fade_px. Inside a wide layer, more than fade_px from any
// uncovered pixel, T = M = 1 and nothing changes; at a straight edge T = 1/2
// and the coverage is 0. A layer thinner than the fade (M < 1: a lone line)
// keeps its middle and fades at its sides. fade_px < 2: unchanged.
void fade_layer_edges(std::vector<float>& coverage, int width, int height, double fade_px);

// The finished texture layer (`layer`: 3 floats per pixel; `layer_coverage`)
// faded at its edge, then composited over `out` as the renderers composite
// (screened for the moving layer); `coverage`, when given, receives the
// faded coverage where the layer shows.
void composite_faded_layer(const std::vector<float>& layer, std::vector<float>& layer_coverage, double fade_px, bool screen,
                           RgbImage& out, std::vector<float>* coverage);

}  // namespace flowvid::flow::detail
