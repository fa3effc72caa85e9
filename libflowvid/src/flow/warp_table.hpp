#pragma once
// Warp tables: every output pixel near a warped output line, mapped into the
// input frame through the lines' tangent frames (thesis fig. 3.17), with the
// weight of the background carried from around the input line
// (SynthesisSettings::carry_background). Shared by the synthesizer's two
// renderers; not part of the public interface.

#include "synthesis_kernels.hpp"

#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/synthesis.hpp"

#include <algorithm>
#include <utility>
#include <vector>

namespace flowvid::flow::detail {

// Output pixels near an output line, mapped into the input frame.
struct WarpEntry {
    int pixel = 0;
    int row = 0;                 // pixel / width, kept: rendering reads it per sample
    float qx = 0.0f, qy = 0.0f;  // input-frame position
    float fade = 1.0f;
    // Weight of the background carried from around the input line: cos^2
    // across the line (zero three quarters of a patch to the side), falling
    // to zero over half a patch beyond either end.
    float carry = 0.0f;
};
struct WarpTable {
    double s_min = 0.0;                  // arc of bucket 0 (input line)
    std::vector<int> bucket_start;       // entries of bucket b: [bucket_start[b], bucket_start[b+1])
    std::vector<WarpEntry> entries;      // by bucket, then by pixel
    std::vector<int> bucket_row_lo;      // image rows a bucket's entries span (lo > hi: none)
    std::vector<int> bucket_row_hi;
    double reach_in = 0.0;               // input-space reach of a patch around its centre
};

// How far carried background reaches across its line (cos^2 to zero there),
// px: a patch and a half. A new channel's outer edge then fades over about
// 0.6 of that (10 to 90 %), as the waterfall's own edge fades into the rock
// (25 px, against 22 px with its 24 px patches); three quarters of a patch
// left a straight wall of water.
inline double carry_band_px(int patch) { return 1.5 * patch; }

// The table of `out_line` carrying `in_line`'s texture (a frame of `width` x
// `height`). Entries reach as far across the line as a particle's patch
// does, or `reach_across_px` when larger (tables that carry background:
// carry_band_px).
WarpTable build_warp(const LineGeometry& out_line, const LineGeometry& in_line, ArcMapping mapping, int patch, int width,
                     int height, double reach_across_px = 0.0);

// Carried background comes only from where the flow is: entries whose input
// arc lies outside every range of `arcs_px` (stretches of the input line no
// particle crossed, such as a rock ledge it runs over) lose their carry,
// fading over `fade_px` beyond each range. Empty `arcs_px`: unchanged.
void keep_carry_on_flowing_arcs(WarpTable& table, const std::vector<std::pair<double, double>>& arcs_px, double fade_px);

// Carried background is the background smoothed by a box of this radius,
// twice (a tent reaching twice as far): half a patch.
inline int carry_smoothing_radius_px(int patch) { return std::max(1, patch / 2); }

// The stretches of an input line (`points`) to carry background from: where
// the flow is, and where the carried background's smoothing sees only the
// flow. `tracked_px` (the arcs its particles crossed) are joined, and each
// grown into the untracked stretches between the first and the last of them
// while the background there looks like them (its mean display luma over a
// patch around the line within the tracked arcs' 10-90 % range, widened by
// 0.1 of full scale). Water too bright and even to have texture to follow
// (the top of a fall) is flow the tracker could not see, and a new line
// should show it rather than the rock it was drawn over; a rock ledge the
// line crosses is far darker and stays out, and so do the stretches beyond
// the first and last tracked arcs (where a drawn line runs past the flow).
// Then every end whose smoothing window (2 carry_smoothing_radius_px along
// the line) reaches background far unlike the flow (outside the tracked
// range widened by 0.2) is pulled in by that reach, so that a ledge's rock
// does not come along as a grey smear where the flow ends.
// `background_luma`: the background's display luma (luma(to_display(...))),
// `width` x `height`; empty: `tracked_px` unchanged.
std::vector<std::pair<double, double>> arcs_to_carry(const std::vector<Eigen::Vector2d>& points,
                                                     const std::vector<std::pair<double, double>>& tracked_px,
                                                     const std::vector<float>& background_luma, int width, int height,
                                                     int patch);

// One particle's patch added through a warp table (the whole-frame pass).
void splat_warped(Accumulator& acc, const WarpTable& table, const ParticleStreams::Visible& particle, int patch);

// `values` (width x height pixels of `channels` interleaved floats)
// smoothed by a box of (2 radius + 1)^2 pixels, twice (a tent), averaging
// over the part of the box inside the frame.
void smooth_in_place(std::vector<float>& values, int width, int height, int channels, int radius);

// `image` smoothed so (smooth_in_place).
RgbImage smoothed(const RgbImage& image, int radius);

// Composites over `out` the background found around each warped line's
// input line: `source` (the frame's background) sampled at the warp's input
// positions, weighted by WarpEntry::carry and shown fully where the weights
// reach `full` (smoothstep, as particles), times `allowed` per pixel. `sums`
// is scratch (4 per pixel).
void carry_background(const std::vector<const WarpTable*>& tables, const RgbImage& source, float full,
                      const std::vector<float>& allowed, std::vector<float>& sums, RgbImage& out);

// SynthesisSettings::carry_background: per pixel, how much carried background
// may show: 0 within half a patch of the flow's own region (its input lines
// and lines interpolated between neighbouring ones, as edits interpolate
// output lines), rising to 1 a patch away.
std::vector<float> carry_allowed_map(const ParticleStreams& streams, int w, int h, int patch);

}  // namespace flowvid::flow::detail
