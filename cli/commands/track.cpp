// flowvid track: follow textured particles along the input flow lines of a
// clip and store them as a particle texture bank (thesis 3.2, flow/tracking.hpp).

#include "command.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/flow/auto_lines.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/tracking.hpp"
#include "flowvid/flow/tracking_job.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>

namespace flowvid::cli {
namespace {

struct TrackOptions {
    std::string capture;
    std::string flowlines;
    std::string out;
    std::string dense_out;
    std::string auto_lines;  // propose input lines from the clip's optical flow, write them here (SVG), track along them
    double fps = 0.0;
    FrameOptions frame_selection;  // resolved into frames
    int frames = 0;                // the first N frames; 0: all
    int patch = 0;  // 0: from the drawn lines' spacing
    std::string dynamics = "stationary";
    int start_every = 0;
    int max_path_frames = 0;
    double densify_px = -1.0;  // -1: twice the patch (only gaps synthesis would leave open get lines)
    double max_gap_px = 0.0;
    double max_speed_px = 40.0;
    double search_radius_px = 6.0;
    double min_correlation = 0.3;
    int particles_per_line = 0;
    bool keep_static = false;
    int threads = 0;
    bool json = false;
};

// --auto-lines: input lines proposed from the clip's mean optical flow
// (flow::propose_input_lines_steadied), in the first frame's view when the
// camera drifts, written as an SVG over the first frame for the artist to
// correct. With a drawing as well, says how far the two are apart (px, both ways).
int propose_lines(const TrackOptions& options, const GlobalOptions& global, const formats::Capture& capture,
                  const formats::FlowLineSet* drawn, formats::FlowLineSet& proposed, nlohmann::json& summary) {
    flow::CameraMotion camera;
    flow::AutoLines lines;
    {
        TerminalProgress progress(global, "auto lines");
        try {
            lines = flow::propose_input_lines_steadied(capture, options.frames, camera, {}, progress.callback());
        } catch (const flowvid::Cancelled&) {
            log_message("interrupted: no lines written");
            return kExitInterrupted;
        } catch (const std::invalid_argument& e) {
            log_message("error: " + options.capture + ": " + e.what());
            return kExitInvalidInput;
        }
        progress.finish();
    }
    if (lines.drawing.inputs.empty()) {
        log_message("error: " + options.capture +
                    ": no flow found to propose lines along (nothing moves consistently faster than " +
                    std::to_string(lines.min_speed_px_per_frame) +
                    " px/frame; fix: draw the lines and give --flowlines, or use more frames)");
        return kExitFailure;
    }
    // The first frame beside the SVG, which shows it under the lines.
    const std::filesystem::path svg(options.auto_lines);
    const std::filesystem::path frame_png = svg.parent_path() / (svg.stem().string() + ".frame1.png");
    flow::CaptureFrames first(capture, 1);
    flow::write_image(frame_png.string(), flow::to_linear(first.frame(0)));
    formats::write_flowlines_svg(options.auto_lines, lines.drawing, frame_png.filename().string());
    char text[400];
    std::snprintf(text, sizeof text,
                  "auto lines: %zu proposed from the clip's optical flow (%d frame pairs; %.0f %% of the frame flows, "
                  "median %.2f px/frame; lines %.0f px apart) -> %s, over its first frame %s: correct them there; "
                  "track, synth and edit take the file with --flowlines",
                  lines.drawing.inputs.size(), lines.frame_pairs, 100.0 * lines.flow_area_share,
                  lines.median_speed_px_per_frame, lines.spacing_px, options.auto_lines.c_str(), frame_png.filename().c_str());
    log_message(text);
    summary = {{"file", options.auto_lines},
               {"lines", lines.drawing.inputs.size()},
               {"spacing_px", lines.spacing_px},
               {"min_speed_px_per_frame", lines.min_speed_px_per_frame},
               {"median_speed_px_per_frame", lines.median_speed_px_per_frame},
               {"flow_area_share", lines.flow_area_share}};
    if (drawn && !drawn->inputs.empty()) {
        const auto drawn_lines = flow::drawn_input_polylines(*drawn);
        const auto auto_polylines = flow::drawn_input_polylines(lines.drawing);
        const double to_drawn = flow::mean_distance_to_lines(auto_polylines, drawn_lines);
        const double from_drawn = flow::mean_distance_to_lines(drawn_lines, auto_polylines);
        std::snprintf(text, sizeof text,
                      "auto lines against the drawn ones: %.1f px from auto to drawn, %.1f px from drawn to auto (mean)",
                      to_drawn, from_drawn);
        log_message(text);
        summary["mean_distance_to_drawn_px"] = to_drawn;
        summary["mean_distance_from_drawn_px"] = from_drawn;
    }
    proposed = lines.drawing;
    return kExitOk;
}

int run_track(TrackOptions& options, const GlobalOptions& global) {
    formats::create_parent_folder(options.out);
    if (!options.dense_out.empty()) formats::create_parent_folder(options.dense_out);
    if (!options.auto_lines.empty()) formats::create_parent_folder(options.auto_lines);
    const formats::Capture capture = flow::open_clip(options.capture, options.fps);
    options.frames = resolve_frame_count(options.frame_selection, capture.frames.first,
                                         "particles are tracked from the clip's first frame", 0)
                         .value_or(0);
    std::string lines_path = options.flowlines;
    if (lines_path.empty() && !capture.flowlines.empty()) lines_path = capture.resolve(capture.flowlines);
    if (lines_path.empty() && options.auto_lines.empty()) {
        log_message("error: " + options.capture +
                    ": no flow lines; give --flowlines FILE (SVG or *.flowlines.json), or --auto-lines FILE.svg to "
                    "propose them from the clip's motion");
        return kExitUsage;
    }
    // The capture's own drawing is not an option's value, so the shared
    // check (outputs_spare_inputs) cannot see it.
    if (!options.auto_lines.empty() && !lines_path.empty() && same_file(options.auto_lines, lines_path)) {
        log_message("error: --auto-lines " + options.auto_lines + " is the drawing " + lines_path +
                    "; writing the proposal there would destroy it (fix: write it to another file)");
        return kExitUsage;
    }
    std::optional<formats::FlowLineSet> drawn;
    if (!lines_path.empty()) {
        std::vector<Problem> warnings;
        drawn = formats::read_flowline_drawing(lines_path, &warnings);
        print_problems(warnings);
    }
    formats::FlowLineSet drawing;
    nlohmann::json auto_summary;
    if (!options.auto_lines.empty()) {
        const int status = propose_lines(options, global, capture, drawn ? &*drawn : nullptr, drawing, auto_summary);
        if (status != kExitOk) return status;
        lines_path = options.auto_lines;
    } else {
        drawing = *drawn;
    }

    flow::CaptureFrames frames(capture, options.frames);
    flow::TrackingJob job;
    job.drawing = drawing;
    job.drawing_name = lines_path;
    job.settings.patch_size_px = options.patch;
    job.settings.dynamics = options.dynamics == "stationary" ? formats::ParticleDynamics::stationary
                                                              : formats::ParticleDynamics::non_stationary;
    job.settings.start_every = options.start_every;
    job.settings.max_path_frames = options.max_path_frames;
    job.settings.max_speed_px = options.max_speed_px;
    job.settings.search_radius_px = options.search_radius_px;
    job.settings.min_correlation = options.min_correlation;
    job.settings.max_particles_per_line = options.particles_per_line;
    job.settings.threads = options.threads;
    job.densify_px = options.densify_px;
    job.max_gap_px = options.max_gap_px;
    std::optional<TerminalProgress> progress;  // Ctrl-C stops the work cleanly while it runs
    progress.emplace(global, "track");
    flow::TrackingOutcome outcome;
    try {
        outcome = flow::track_clip(frames, job, progress->callback());
    } catch (const std::invalid_argument& e) {  // the clip, the lines and the options do not fit together
        log_message("error: " + frames.source() + " with " + lines_path + ": " + e.what());
        return kExitInvalidInput;
    }
    progress.reset();
    if (outcome.result.report.status == flow::TrackingReport::Status::cancelled) {
        log_message("interrupted: no bank written");
        return kExitInterrupted;
    }
    flow::TrackingResult& result = outcome.result;
    const flow::CameraMotion& camera = outcome.camera;

    nlohmann::json summary = {{"bank", options.out},
                              {"clip", frames.source()},
                              {"frames", frames.count()},
                              {"patch_size_px", outcome.patch_px},
                              {"dynamics", options.dynamics},
                              {"start_every", result.report.start_every},
                              {"max_path_frames", result.report.max_path_frames},
                              {"particles", result.bank.particles.size()}};
    nlohmann::json probes = nlohmann::json::array();
    for (const flow::LineProbe& p : result.report.probes)
        probes.push_back({{"id", p.id},
                          {"mean_speed_px_per_frame", p.mean_speed_px_per_frame},
                          {"travel_frames", p.travel_frames},
                          {"segments", p.segments},
                          {"untracked_segments", p.untracked}});
    summary["camera"] = {{"model", flow::to_string(camera.model)},
                         {"largest_drift_px", camera.largest_offset_px},
                         {"view_frame", camera.view_frame + 1}};
    summary["densify_px"] = outcome.densify_px;
    if (!auto_summary.is_null()) summary["auto_lines"] = auto_summary;
    summary["drawn_lines"] = probes;
    nlohmann::json tracked = nlohmann::json::array();
    for (const flow::LineTrackingStats& s : result.report.lines)
        tracked.push_back({{"id", s.id},
                           {"length_px", s.length_px},
                           {"started", s.started},
                           {"completed", s.completed},
                           {"uncertain_steps", s.uncertain_steps},
                           {"extrapolated_steps", s.extrapolated_steps},
                           {"steps", s.steps},
                           {"mean_correlation", s.mean_correlation},
                           {"mean_speed_px_per_frame", s.mean_speed_px_per_frame},
                           {"mean_life_frames", s.mean_life_frames}});
    summary["tracked_lines"] = tracked;
    // How sure the block matching was: of the completed particles' matched
    // steps (not those whose patch was mostly outside the frame), the share
    // whose match was weak or on the window's edge (moved by the prediction
    // instead), and the mean correlation of the others.
    long long matched = 0, uncertain = 0;
    double correlation_sum = 0.0;
    for (const flow::LineTrackingStats& s : result.report.lines) {
        matched += s.steps - s.extrapolated_steps;
        uncertain += s.uncertain_steps;
        correlation_sum += s.mean_correlation * static_cast<double>(s.steps - s.extrapolated_steps - s.uncertain_steps);
    }
    const double uncertain_share = matched > 0 ? static_cast<double>(uncertain) / static_cast<double>(matched) : 0.0;
    summary["uncertain_step_share"] = uncertain_share;
    summary["mean_correlation"] = matched > uncertain ? correlation_sum / static_cast<double>(matched - uncertain) : 0.0;
    if (uncertain_share > 0.5)
        log_message("warning: " + std::to_string(static_cast<int>(std::lround(100.0 * uncertain_share))) +
                    " % of the tracking steps were uncertain (weak match or on the search window's edge) and moved "
                    "by the prediction: the texture along the lines does not match from frame to frame; try a larger "
                    "--patch, --dynamics non-stationary for flames and smoke, or a wider --search-radius");

    // For people: totals and the drawn lines; every tracked segment only in --json.
    nlohmann::json brief = summary;
    brief.erase("tracked_lines");
    int with_particles = 0;
    for (const flow::LineTrackingStats& s : result.report.lines) with_particles += s.completed > 0 ? 1 : 0;
    brief["tracked_lines"] = std::to_string(result.report.lines.size()) + " (" + std::to_string(with_particles) +
                             " with complete particles; --json lists them)";
    const auto print_summary = [&] {
        if (options.json) std::cout << summary.dump(2) << '\n';
        else std::cout << human_readable(brief);
    };
    if (result.bank.particles.empty()) {
        print_summary();
        log_message("error: no particle completed its path along any line within the clip's " +
                    std::to_string(frames.count()) +
                    " frames (fix: check that the lines follow the flow, lower --max-path-frames, or raise --max-speed)");
        return kExitFailure;
    }
    result.bank.source_clip = formats::source_clip_for_bank(options.out, result.bank.source_clip);
    formats::write_particle_bank(options.out, result.bank);
    if (!options.dense_out.empty()) {
        formats::FlowLineSet dense = drawing;
        dense.inputs = result.tracked_lines;
        dense.outputs.clear();
        formats::write_flowline_set(options.dense_out, dense);
    }
    print_summary();
    return kExitOk;
}

const RegisterCommand registration{Command{
    "track", "track textured particles along flow lines into a particle texture bank (EXR)",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<TrackOptions>();
        app.footer(
            "Follows a particle entering every input flow line by block matching constrained to the\n"
            "line (a 1-D search along the arc, normalised cross-correlation, sub-pixel refinement) and\n"
            "stores its texture patch and arc-length position per frame in a bank (flowvid.particle_bank).\n"
            "A probe pass first measures each line's speed: lines a particle cannot cross within\n"
            "--max-path-frames are cut into segments it can (ids like in-3[0.0:41.5]); stretches nothing\n"
            "crosses within the clip (rocks a line runs over) are left out and listed. Only particles\n"
            "that complete their path are kept. --densify adds lines between neighbouring drawn lines\n"
            "(ids like in-1~in-2@0.500); synth and edit rebuild all of these from the same drawing.\n"
            "By default it adds them only where neighbours are more than 2 patches apart (synthesis covers\n"
            "about a patch around each line, so wider gaps would show the background).\n"
            "The patch side defaults to half the median gap between neighbouring drawn lines (to the\n"
            "nearest 8 px, 16..96): water drawn ~45 px apart gets 24 px, flames drawn ~100 px apart 48 px;\n"
            "the log says what was chosen.\n"
            "No lines drawn yet? --auto-lines FILE.svg proposes them from the clip's dense optical flow\n"
            "(evenly spaced streamlines of its mean motion, fastest flow first), writes them as an SVG over\n"
            "the clip's first frame for you to correct (Inkscape: edit the paths in group \"input\"), and\n"
            "tracks along them; give the corrected file back with --flowlines. With a drawing too, the log\n"
            "says how far the proposal lies from it.\n"
            "A camera that drifts is measured first (on the background, away from the lines) and the clip\n"
            "is tracked in its central view (the frame whose camera is nearest the others'; the lines, drawn\n"
            "on the first frame, are carried into it); synth, edit and quality do the same, so the output is\n"
            "a still camera in that view. A still camera, or one whose background changes too much to tell\n"
            "(firelight), leaves the frames as they are; the log says which.\n\n"
            "CLIP is a video.flow capture folder (its flowlines.svg is used unless --flowlines is given),\n"
            "a video file, or an image pattern such as frames/%06d.png.\n\n"
            "Exit codes: 0 bank written, 1 no particle completed its path, 2 usage, 3 invalid input,\n"
            "4 I/O error, 130 interrupted.\n\n"
            "Examples:\n"
            "  flowvid track --capture ../shared/captures/video-waterfall-cascade --out waterfall.bank.exr\n"
            "  flowvid track --capture clip.mp4 --flowlines lines.svg --patch 16 --densify 12 --out bank.exr\n"
            "  flowvid track --capture stream.mp4 --auto-lines stream.lines.svg --out stream.bank.exr\n"
            "  flowvid track --capture fire/ --dynamics non-stationary --out fire.bank.exr --json");
        app.add_option("--capture,--clip", options->capture, "capture folder, video file or image pattern")->required();
        app.add_option("--flowlines", options->flowlines, "input flow lines (SVG or *.flowlines.json); default: the capture's");
        app.add_option("--auto-lines", options->auto_lines,
                       "propose input lines from the clip's optical flow, write them to this SVG (over the first "
                       "frame, to correct) and track along them")
            ->check(file_name_ending({".svg"}, "flow lines as SVG", "proposed.lines.svg"));
        app.add_option("--out", options->out, "bank to write (.exr)")
            ->required()
            ->check(file_name_ending({".exr"}, "a particle bank (an OpenEXR file)", "waterfall.bank.exr"));
        app.add_option("--fps", options->fps, "frame rate of a clip that records none (image sequences: 25)");
        add_frame_options(app, options->frame_selection, "frames A to B of the clip; A is its first frame",
                          "use only the first N frames", "all");
        app.add_option("--patch", options->patch,
                       "patch side in pixels (default: half the median gap between neighbouring drawn lines; the "
                       "thesis: 24, 100 for flames)")
            ->check(CLI::Range(4, 1024));
        app.add_option("--dynamics", options->dynamics,
                       "stationary (waterfalls, streams: speed depends on position) or non-stationary (fire, smoke: "
                       "each particle keeps its own speed)")
            ->check(CLI::IsMember({"stationary", "non-stationary"}))
            ->capture_default_str();
        app.add_option("--start-every", options->start_every,
                       "a particle enters every line every N frames (0 = automatic, about a third of a patch apart)")
            ->check(CLI::NonNegativeNumber);
        app.add_option("--max-path-frames", options->max_path_frames,
                       "cut lines into segments a particle crosses in about N frames (0 = a fifth of the clip, "
                       "-1 = never cut)");
        app.add_option("--densify", options->densify_px,
                       "add interpolated input lines so that neighbours are at most PX apart (default: 2 patches, "
                       "filling only gaps synthesis would leave open; 0 = lines as drawn)")
            ->check(CLI::NonNegativeNumber);
        app.add_option("--max-gap", options->max_gap_px, "drawn lines further apart are not interpolated between (0 = 6 patches)");
        app.add_option("--max-speed", options->max_speed_px, "largest step searched, px per frame")->capture_default_str();
        app.add_option("--search-radius", options->search_radius_px,
                       "search window around the predicted step, px (a non-stationary particle whose match there "
                       "fails searches up to --max-speed)")
            ->capture_default_str();
        app.add_option("--min-correlation", options->min_correlation,
                       "weaker matches move the particle by the prediction instead")
            ->capture_default_str();
        app.add_option("--particles-per-line", options->particles_per_line,
                       "keep at most the first K complete particles per line (0 = all)");
        app.add_option("--dense-out", options->dense_out,
                       "also write the lines particles ran on (segments, interpolated lines) as *.flowlines.json")
            ->check(file_name_ending({".json"}, "flow lines as JSON", "tracked.flowlines.json"));
        app.add_option("--threads", options->threads, "worker threads (0 = all cores)");
        app.add_flag("--json", options->json, "print the report as JSON");
        return [options](const GlobalOptions& global) { return run_track(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
