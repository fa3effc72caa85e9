#pragma once
// Input flow lines proposed from dense optical flow, for clips where the
// artist has drawn none yet (`flowvid track --auto-lines`): the artist starts
// from these and corrects them.
//
// Method: dense optical flow (OpenCV DIS) between frame pairs (i, i + step) of
// the clip's luma at a reduced analysis size; per pixel the temporal mean
// flow vector and mean speed; the flow region is where the mean vector is
// fast enough and its direction consistent over time; evenly spaced
// streamlines (Jobard & Lefer 1997) are traced through the smoothed mean
// field, fastest flow first, and simplified.
//
// Coordinates are image pixels in the OpenCV convention (pixel (x, y) is the
// centre of column x, row y, y down); speeds are pixels per frame of the
// clip at its full size. A line's first point is upstream.

#include "flowvid/progress.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <vector>

namespace flowvid::flow {

struct AutoLineSettings {
    // Target gap between neighbouring lines, px. 0 = automatic: a fifth of the
    // flow region's width across the flow (its area over its extent along the
    // mean flow direction), clamped to 24 .. 128 px.
    double spacing_px = 0.0;
    // Pixels whose mean flow is slower are not flow, px/frame. 0 = automatic:
    // 3 x the frame's median mean speed (camera drift and estimator noise,
    // assuming less than half the frame flows) and at least 0.15 x its 99th
    // percentile, but at most half its 95th percentile (a flow filling most of
    // the frame is still found), and never below 0.05 px/frame (a still clip
    // gets no lines).
    double min_speed_px_per_frame = 0.0;
    // Shorter lines are dropped, px. 0 = automatic: 2 x spacing.
    double min_length_px = 0.0;
    // The first max_frames frames of the clip are used (<= 0: all).
    int max_frames = 120;
    // Flow is measured between frames i and i + step_frames (>= 1); a larger
    // step helps slow flows, speeds are still reported per frame.
    int step_frames = 1;
    // The flow is measured on frames scaled down so that their shorter side
    // is at most this, px (0: full size): fast enough for 1080p clips, and
    // coarse scales suit flames and water whose detail changes every frame.
    int analysis_short_side_px = 180;
};

struct AutoLines {
    formats::FlowLineSet drawing;  // inputs only, ids "auto-1", "auto-2", ... (fastest flow first); the clip's size
    double spacing_px = 0.0;       // what was used (chosen or given)
    double min_speed_px_per_frame = 0.0;
    double median_speed_px_per_frame = 0.0;  // of the mean flow over the flow region (0 when there is none)
    double flow_area_share = 0.0;            // share of the frame in the flow region, 0..1
    int frame_pairs = 0;                     // frame pairs whose flow was measured
};

// Proposes input flow lines for `frames` (display RGB). `progress` gets the
// fraction done (0..1) and may return false to cancel (flowvid::Cancelled). Deterministic: the same
// clip and settings give the same lines. Throws std::invalid_argument for a
// clip with fewer than step_frames + 1 frames (of those used) or bad settings.
AutoLines propose_input_lines(FrameSequence& frames, const AutoLineSettings& settings = {},
                              const Progress& progress = {});

// The lines `flowvid track --auto-lines` proposes for a clip (its first
// max_frames frames; 0: all), in the view of its first frame, where an
// artist draws (tracking carries them into the clip's central view):
// proposed once on the frames as filmed; when the camera drifts
// (measured away from those lines: the flowing part of the frame would pull
// the estimate along with it), proposed again on the steadied frames.
// `camera` receives the drift. `progress` gets the stage ("optical flow",
// "camera drift", "optical flow, steadied") and its fraction done; returning
// false cancels (flowvid::Cancelled).
AutoLines propose_input_lines_steadied(const formats::Capture& capture, int max_frames, CameraMotion& camera,
                                       const AutoLineSettings& settings = {},
                                       const Progress& progress = {});

// Mean distance, px, from points sampled every `step_px` of arc along each
// polyline of `from` (first and last points included) to the nearest point of
// any polyline of `to` (point-to-segment distance). NaN when either has no
// points. Used to compare proposed lines with drawn ones, both ways.
double mean_distance_to_lines(const std::vector<std::vector<Eigen::Vector2d>>& from,
                              const std::vector<std::vector<Eigen::Vector2d>>& to, double step_px = 2.0);

namespace detail {

// A flow field on a width x height grid (row-major): velocity per cell,
// any unit, and where it flows (mask != 0).
struct FlowField {
    int width = 0;
    int height = 0;
    std::vector<float> vx;
    std::vector<float> vy;
    std::vector<std::uint8_t> mask;
};

struct StreamlineSettings {
    double separation = 16.0;   // d_sep: no seed closer than this to an accepted line, grid cells
    double test_ratio = 0.5;    // a line stops closer than test_ratio x separation to another
    double min_speed = 0.0;     // a line stops where the field is slower than this (field units)
    double min_length = 32.0;   // shorter lines are dropped, grid cells
    double step = 1.0;          // integration step (RK2), grid cells
    double max_turn_deg = 60.0;  // a line stops where it has turned this far from its seed's direction
};

// Evenly spaced streamlines of `field` (Jobard & Lefer): seeds on a grid of
// separation / 4 inside the mask, fastest first, each traced forward and
// backward. Points in grid coordinates (cell (x, y) at (x, y)), one per step,
// upstream first.
std::vector<std::vector<Eigen::Vector2d>> evenly_spaced_streamlines(const FlowField& field,
                                                                    const StreamlineSettings& settings);

// Douglas-Peucker simplification: the fewest points of `points` (first and
// last kept) within `tolerance` of the original polyline.
std::vector<Eigen::Vector2d> simplify_polyline(const std::vector<Eigen::Vector2d>& points, double tolerance);

}  // namespace detail

}  // namespace flowvid::flow
