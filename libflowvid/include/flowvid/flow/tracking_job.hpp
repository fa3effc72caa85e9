#pragma once
// The tracking pipeline in one place, as `flowvid track` and the flow
// benchmark run it: from a clip and its drawing to tracked particles.
//
// Steps: the patch size from the gap between the drawn lines (unless given);
// the lines densified where neighbours are further apart than two patches
// (where synthesis would show the background); the camera's drift measured
// on the background and undone (stabilise.hpp), so particles are tracked in
// the clip's central view (the drawing carried into it); then
// track_particles (tracking.hpp).

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/tracking.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/progress.hpp"

#include <string>
#include <vector>

namespace flowvid::flow {

struct TrackingJob {
    formats::FlowLineSet drawing;   // the input lines (their outputs are ignored)
    std::string drawing_name;       // for messages: the file it came from
    TrackingSettings settings;      // patch_size_px <= 0: chosen from the drawing
    // Lines added between drawn neighbours so that none are further apart
    // than this (px); < 0: two patches; 0: the lines as drawn.
    double densify_px = -1.0;
    double max_gap_px = 0.0;  // neighbours further apart are not densified between (0: six patches)
};

struct TrackingOutcome {
    TrackingResult result;               // the bank (its source clip still to be set by the writer) and the report
    CameraMotion camera;                 // the drift that was undone
    int patch_px = 0;                    // as tracked
    double densify_px = 0.0;
    std::vector<formats::FlowLine> lines;  // the input lines tracked (drawn and densified), in the view's pixels
};

// Tracks `frames` along the job's lines. Progress: stages "camera drift" and
// "track"; the choices made and warnings (patch size, densifying, wide
// neighbours, the drawing's size, the camera) as messages. Cancelling stops
// it: the outcome's report then says cancelled. Throws std::invalid_argument
// when the clip, the lines and the settings do not fit together.
TrackingOutcome track_clip(FrameSequence& frames, const TrackingJob& job, const Progress& progress = {});

}  // namespace flowvid::flow
