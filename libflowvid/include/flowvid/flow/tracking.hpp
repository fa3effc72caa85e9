#pragma once
// Tracking textured particles along artist-drawn flow lines (thesis 3.2.2,
// fig. 3.6): a particle enters each input line at its start on every frame
// (or every start_every frames) and is followed frame by frame by block
// matching *constrained to the line*: its patch is compared, by normalised
// cross-correlation over RGB, with patches centred at every whole pixel of a
// 1-D window of arc length in the next frame; the best match is refined to
// sub-pixel position by a parabola through the three best scores. Matching
// runs in a "ribbon" (the frame resampled along the line, tangent frames
// smoothed over a third of a patch), so a candidate is a row offset.
// The patch stored per frame is the axis-aligned RGBA texture around the
// particle (linear light, alpha 0 outside the frame): the block of whole
// pixels whose centre is nearest the particle (within half a pixel; the exact
// offset follows from the stored arc length), so that rendering it back at
// the same position copies the clip's pixels without resampling blur.
// Sub-pixel matching: after the integer search, a few Gauss-Newton steps fit
// a shift and a stretch along the line (falling water stretches), which
// removes the pixel-locking bias of a parabola through the scores.
//
// Stationary flows (waterfalls, streams: the speed depends on the position)
// predict a particle's next step from the speed profile of the particles
// tracked before it on the same line; non-stationary flows (flames, smoke)
// from the particle's own last step. A step whose correlation peak is below
// min_correlation (or on the window's edge) is "uncertain": the particle moves
// by the prediction instead and the report counts it.
//
// Only particles that complete their path (leave the line's end before the
// clip ends) go into the bank: synthesis replays whole paths (fig. 3.5).
// A first pass of "probe" particles entering all along each line measures its
// speed profile; a line a particle cannot cross within max_path_frames is cut
// into segments (ids "in-3[0.0:121.5]", see geometry.hpp), each with its own
// particles. Segments meet seamlessly in synthesis: at any output frame all
// particles show the same input frame (except across the ladder step).

#include "flowvid/progress.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <functional>
#include <string>
#include <vector>

namespace flowvid::flow {

struct TrackingSettings {
    int patch_size_px = 24;  // side of the square patch (the thesis: 24, 100 for flames)
    formats::ParticleDynamics dynamics = formats::ParticleDynamics::stationary;
    double max_speed_px = 40.0;      // largest step (px per frame) searched when nothing predicts it
    double search_radius_px = 6.0;   // half-width of the window around the predicted step, px
    double min_correlation = 0.3;    // NCC below this makes a step uncertain
    // A new particle enters every line every this many frames; 0 = automatic:
    // about a third of a patch apart at the typical probed speed.
    int start_every = 0;
    // Lines a particle needs longer than this to cross (measured by probes)
    // are cut into segments it crosses in about this time (segments at least
    // half a patch long), so that particles complete their paths within the
    // clip; 0 = a fifth of the clip, < 0 = never cut. Shorter paths leave
    // more particles per line (a longer period K * step) and spend less time
    // with a wrap of the diagonal order on the line.
    int max_path_frames = 0;
    double min_speed_px = 0.05;      // probed speeds are floored here (px per frame)
    int max_particles_per_line = 0;  // keep the earliest this many complete particles per line; 0 = all
    // Match on the frame minus the clip's per-pixel median (what moves),
    // rather than on the frame: otherwise the still outline of the flow and
    // the rocks around it hold matches near zero motion. Costs one extra pass
    // over 31 frames.
    bool remove_static_background = true;
    int threads = 0;                 // 0 = hardware concurrency
};

struct LineTrackingStats {
    std::string id;
    double length_px = 0.0;
    int started = 0;
    int completed = 0;         // kept in the bank
    int steps = 0;             // frame-to-frame matches of kept particles
    int uncertain_steps = 0;   // of those, moved by the prediction after a weak or edge match
    int extrapolated_steps = 0;  // moved by the prediction because the patch was mostly outside the frame
    double mean_correlation = 0.0;        // of the certain steps
    double mean_speed_px_per_frame = 0.0;
    double mean_life_frames = 0.0;
};

// What the probe pass measured on a drawn line.
struct LineProbe {
    std::string id;
    double mean_speed_px_per_frame = 0.0;
    double travel_frames = 0.0;  // time a particle takes from the start to the end
    int segments = 1;            // the line was cut into this many segments
    std::vector<std::string> untracked;  // segments no particle crosses within the clip (not tracked)
};

struct TrackingReport {
    enum class Status { ok, cancelled };
    Status status = Status::ok;
    int frames_read = 0;
    int start_every = 1;
    int max_path_frames = 0;
    std::vector<LineProbe> probes;        // per drawn line (empty when nothing was probed)
    std::vector<LineTrackingStats> lines;  // per tracked line (segments)
};

struct TrackingResult {
    formats::ParticleBank bank;  // may hold no particle (then nothing completed: see the report)
    TrackingReport report;
    std::vector<formats::FlowLine> tracked_lines;  // the lines particles ran on (segments of long lines)
};

// Tracks particles along `lines` (input lines, fixed points, in the frames'
// pixel coordinates) through every frame of `frames`. Deterministic: the same
// input gives the same bank whatever the thread count.
// Progress: stage "track", after every frame of both passes (a probe, then
// the tracking), with "frame i/n" as its message; false cancels (the report
// then says cancelled). Throws std::invalid_argument for settings out of
// range, a line with keys, a clip of fewer than 2 frames, a patch larger
// than the frame, or a line lying wholly off the frame.
TrackingResult track_particles(FrameSequence& frames, const std::vector<formats::FlowLine>& lines,
                               const TrackingSettings& settings, const Progress& progress = {});

// The stationary speed profile of a line from a bank: the mean step (px per
// frame) of its particles as a function of arc length, in bins of bin_px.
// Bins no particle crossed hold NaN.
std::vector<double> speed_profile(const formats::ParticleBank& bank, const std::string& line_id, double bin_px = 4.0);

}  // namespace flowvid::flow
