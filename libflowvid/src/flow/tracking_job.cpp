#include "flowvid/flow/tracking_job.hpp"

#include "flowvid/flow/geometry.hpp"

#include <cstdio>

namespace flowvid::flow {

namespace {

void say(const Progress& progress, const std::string& line) { report_message(progress, "prepare", line); }

}  // namespace

TrackingOutcome track_clip(FrameSequence& frames, const TrackingJob& job, const Progress& progress) {
    TrackingOutcome out;
    if (job.drawing.width != frames.width() || job.drawing.height != frames.height())
        say(progress, "warning: " + job.drawing_name + ": drawn for " + std::to_string(job.drawing.width) + " x " +
                          std::to_string(job.drawing.height) + " but the clip is " + std::to_string(frames.width()) + " x " +
                          std::to_string(frames.height()));
    // A drifting camera is tracked in the clip's central view (stabilise.hpp),
    // the lines drawn on the first frame carried into it.
    bool cancelled = false;
    out.camera = estimate_camera_motion(frames, drawn_input_polylines(job.drawing), {}, [&](const ProgressReport& r) {
        return !(cancelled = progress && !progress(r));
    });
    if (cancelled) {
        out.result.report.status = TrackingReport::Status::cancelled;
        return out;
    }
    const formats::FlowLineSet drawing = drawing_in_view(job.drawing, out.camera);
    TrackingSettings settings = job.settings;
    char text[400];
    if (settings.patch_size_px <= 0) {
        const PatchSizeChoice choice = patch_size_from_lines(drawn_input_polylines(drawing));
        settings.patch_size_px = choice.patch_px;
        if (choice.neighbour_pairs > 0)
            std::snprintf(text, sizeof text,
                          "patch: %d px (half the median gap of %.0f px between neighbouring drawn lines; --patch to choose)",
                          choice.patch_px, choice.median_gap_px);
        else
            std::snprintf(text, sizeof text, "patch: %d px (no drawn line has a neighbour; --patch to choose)", choice.patch_px);
        say(progress, text);
    }
    out.patch_px = settings.patch_size_px;
    out.densify_px = job.densify_px;
    if (out.densify_px < 0.0) {
        out.densify_px = 2.0 * out.patch_px;
        say(progress, "densify: " + std::to_string(static_cast<int>(out.densify_px)) +
                          " px (lines added only between neighbours more than 2 patches apart, where synthesis would show "
                          "the background; --densify 0 for the lines as drawn)");
    }
    const double max_gap = job.max_gap_px > 0.0 ? job.max_gap_px : 6.0 * out.patch_px;
    out.lines = densify_input_lines(drawing, out.densify_px, max_gap);
    // Synthesis covers about a patch around each line: neighbours much
    // further apart leave the background showing between them (the fire's
    // six drawn lines, ~100 px apart with 24 px patches, show mostly plate).
    {
        std::vector<std::vector<Eigen::Vector2d>> polylines;
        for (const formats::FlowLine& l : out.lines) polylines.push_back(l.points);
        const auto wide = wide_neighbours(polylines, max_gap, 2.0 * out.patch_px);
        if (!wide.empty()) {
            std::snprintf(text, sizeof text, "%.0f px", wide.front().mean_gap_px);
            say(progress, "warning: " + std::to_string(wide.size()) + " pair(s) of neighbouring lines are more than 2 patches (" +
                              std::to_string(2 * out.patch_px) + " px) apart (widest: " +
                              out.lines[static_cast<std::size_t>(wide.front().a)].id + " and " +
                              out.lines[static_cast<std::size_t>(wide.front().b)].id + ", " + text +
                              "): synthesis shows the background between them; draw lines closer, leave --densify "
                              "automatic, or use a larger --patch");
        }
    }
    say(progress, describe(out.camera));
    StabilisedFrames stabilised(frames, out.camera);
    out.result = track_particles(stabilised, out.lines, settings, progress);
    // The view it was tracked in goes with the bank: replaying it needs that
    // view, and the estimate costs a whole read of the clip.
    out.result.bank.camera = to_bank_camera(out.camera);
    return out;
}

}  // namespace flowvid::flow
