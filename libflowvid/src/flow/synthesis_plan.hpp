#pragma once
// The synthesizer's plan (what each output line renders, what background it
// carries) and its carried-background buffers: shared by synthesis.cpp (the
// plan's construction, the whole-frame pass) and synthesis_banded.cpp. Not
// part of the public interface.

#include "warp_table.hpp"

#include "flowvid/flow/synthesis.hpp"

#include <memory>
#include <utility>
#include <vector>

namespace flowvid::flow {

struct Synthesizer::Plan {
    struct Line {
        int stream = -1;
        bool identity = false;
        bool keyed = false;
        int time_offset_frames = 0;  // shows the particles of frame + this
        formats::FlowLine line;  // keyed lines: geometry per frame
        detail::WarpTable warp;          // fixed, non-identity lines
        // Whether a replayed or relit background follows its particles (fill_background).
        bool followed_by(const Background& background) const {
            const BackgroundMode mode = background.mode();
            return (mode == BackgroundMode::replay || mode == BackgroundMode::relit) && identity && time_offset_frames == 0;
        }
    };
    std::vector<Line> lines;
    // SynthesisSettings::carry_background: each warped output line as a
    // whole, mapped onto its whole input line (segments and the gaps between
    // them alike).
    struct CarryLine {
        formats::FlowLine line;  // keyed lines: geometry per frame
        std::shared_ptr<const LineGeometry> input;
        // Arc ranges of the input line its particles were tracked on, px
        // (empty: all of it); the stretches between (rock nothing crossed)
        // are not carried.
        std::vector<std::pair<double, double>> flowing_arcs_px;
        detail::WarpTable warp;          // fixed lines
    };
    std::vector<CarryLine> carry_lines;
    // Per pixel, how much of the carried background may show
    // (carry_allowed_map): none on the flow's own region, whose background
    // already is the flow's.
    std::vector<float> carry_allowed;
    RgbImage carried_plate;  // fixed carry lines over a median plate: the composite, made once
    RgbImage carry_source;   // the median plate smoothed: what is carried (empty: per frame)
    int width = 0;
    int height = 0;
};

struct Synthesizer::CarryBuffers {
    std::vector<detail::WarpTable> keyed_warps;
    std::vector<const detail::WarpTable*> tables;
    RgbImage source;  // the frame's background, sampled while `out` changes
    std::vector<float> sums;
};

}  // namespace flowvid::flow
