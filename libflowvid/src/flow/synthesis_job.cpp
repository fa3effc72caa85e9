#include "flowvid/flow/synthesis_job.hpp"

#include "flowvid/error.hpp"
#include "flowvid/flow/quality.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/atomic_file.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <cstdio>

namespace flowvid::flow {

namespace {

// The clip a bank was tracked from: the one named, else the one the bank records.
std::optional<formats::Capture> open_bank_clip(const SynthesisJob& job, const formats::ParticleBank& bank,
                                               std::string& why_not) {
    if (!job.clip_path.empty()) return open_clip(job.clip_path, bank.fps);
    const std::string recorded = formats::resolve_source_clip(job.bank_path, bank);
    if (recorded.empty()) {
        why_not = "not recorded in the bank";
        return std::nullopt;
    }
    try {
        return open_clip(recorded, bank.fps);
    } catch (const Error& error) {
        why_not = recorded + " recorded in the bank: " + error.what();
        return std::nullopt;
    }
}

// Lines for the log go out under the stage "prepare".
void say(const Progress& progress, const std::string& line) { report_message(progress, "prepare", line); }

// The schedule's warnings and, when the window was shortened for a
// better-joining wrap, which window was taken over the longest and why.
void report_window(const Schedule& schedule, const Progress& log) {
    for (const std::string& w : schedule.warnings) say(log, "warning: " + w);
    const Schedule::Window& longest = schedule.longest_window;
    if (longest.particles_per_line == 0) return;
    char text[400];
    std::snprintf(text, sizeof text,
                  "window: K = %d particles from input frame %d (period %d frames), whose wrap joins better than the longest "
                  "window's (K = %d from frame %d): join error %.3f against %.3f (--particles and --first-start choose another)",
                  schedule.particles_per_line, schedule.first_start_frame, schedule.period_frames, longest.particles_per_line,
                  longest.first_start_frame, schedule.wrap_join_error, longest.wrap_join_error);
    say(log, text);
}

}  // namespace

std::vector<std::vector<Eigen::Vector2d>> PreparedSynthesis::drawn_lines_at(int frame) const {
    if (outputs.empty()) return drawn_input_polylines(drawing);
    std::vector<std::vector<Eigen::Vector2d>> lines;
    for (const formats::FlowLine& line : drawing.outputs) lines.push_back(formats::points_at_frame(line, frame));
    return lines;
}

namespace {

// What the job decides before any frame is read: the settings that render,
// the background asked for, and whether the clip's frames are needed.
struct Decisions {
    SynthesisSettings settings;
    BackgroundMode background = BackgroundMode::median;
    bool auto_background = false;
    bool moving = false;               // the moving layer (TextureLayer::moving)
    bool background_to_choose = false;  // auto, decided once the particles and the clip are there
    bool clip_needed = false;
};

Decisions decide(const SynthesisJob& job, const formats::ParticleBank& bank) {
    Decisions d;
    d.auto_background = job.background == "auto";
    d.background = d.auto_background ? BackgroundMode::median : background_mode_from_string(job.background);
    d.settings = job.settings;
    const bool flames = bank.dynamics == formats::ParticleDynamics::non_stationary;
    if (job.texture_auto) d.settings.texture_layer = job.edit && flames ? TextureLayer::moving : TextureLayer::whole;
    d.moving = d.settings.texture_layer == TextureLayer::moving;
    if (job.coverage_auto) d.settings.coverage_weight = job.edit ? 2.0 : 0.5;
    if (job.edge_fade_auto) d.settings.edge_fade_px = job.edit && !d.moving ? static_cast<double>(bank.patch_size_px) : 0.0;
    // Whole textures choose (on plain synthesis, for edits too); the moving
    // layer keeps the plate it was taken from.
    d.background_to_choose = d.auto_background && !d.moving;
    if (d.moving && d.background != BackgroundMode::median && d.background != BackgroundMode::none)
        throw UsageError("", "", "--texture moving screens the flames over a still background, and the " + job.background +
                                     " background already " +
                                     (d.background == BackgroundMode::relit ? "carries their light" : "shows them"),
                         "use --background median (the clip's dark plate) or none");
    d.clip_needed = d.background != BackgroundMode::none || d.moving || job.keep_clip;
    return d;
}

// Checks a drawing against the bank and the job (said before the clip is
// read, which takes long).
void check_drawing(const formats::FlowLineSet& drawing, const std::string& drawing_name, const formats::ParticleBank& bank,
                   const SynthesisJob& job, const Progress& log) {
    if (drawing.width != bank.clip_width_px || drawing.height != bank.clip_height_px)
        say(log, "warning: " + drawing_name + ": drawn for " + std::to_string(drawing.width) + " x " +
                     std::to_string(drawing.height) + " but the bank's clip is " + std::to_string(bank.clip_width_px) +
                     " x " + std::to_string(bank.clip_height_px) + ": lines are read in the clip's pixels");
    if (job.edit && drawing.outputs.empty())
        throw ValidationError({{Problem::Severity::error, drawing_name, "output", "no output lines to edit with",
                                "draw them in the group id=\"output\""}});
}

// Everything after the inputs are in memory: the schedule, the background,
// an edit's plan, the Synthesizer.
PreparedSynthesis assemble(SynthesisSources sources, const SynthesisJob& job, const Decisions& decided,
                           const Progress& progress) {
    const Progress& log = progress;
    PreparedSynthesis out;
    out.bank = std::move(sources.bank);
    out.capture = std::move(sources.capture);
    out.flowlines_path = std::move(sources.drawing_name);
    out.drawing = std::move(sources.drawing);
    out.clip = std::move(sources.clip);
    out.camera = sources.camera;
    out.background = decided.background;
    SynthesisSettings settings = decided.settings;
    const bool moving = decided.moving;
    if (job.texture_auto && moving)
        say(log, "texture: moving (an edit of a non-stationary bank moves only the light the flow adds, at coverage " +
                     std::string(settings.coverage_weight == 2.0 ? "2" : "as given") + "; --texture whole to move whole patches)");
    if (decided.clip_needed && !out.clip)
        throw UsageError("", "", "the job needs the clip's frames (for the background, the moving layer or the measures)",
                         "give the clip, or background none with whole textures");
    if (out.clip && (out.clip->width() != out.bank->clip_width_px || out.clip->height() != out.bank->clip_height_px))
        throw ValidationError({{Problem::Severity::error, out.clip->source(), "frames",
                                "frames are " + std::to_string(out.clip->width()) + " x " +
                                    std::to_string(out.clip->height()) + " but the bank was tracked at " +
                                    std::to_string(out.bank->clip_width_px) + " x " +
                                    std::to_string(out.bank->clip_height_px),
                                "give the clip the bank was tracked from"}});

    out.input_points = ParticleStreams::input_points_from_drawing(*out.bank, out.drawing, out.flowlines_path);
    // The moving layer is screened over the plate it was taken from (the
    // clip's dark plate), which the median background then shows.
    std::optional<RgbImage> still_plate;
    if (moving) still_plate = moving_layer_still_plate(*out.clip);

    out.streams = std::make_shared<ParticleStreams>(out.bank, out.input_points, settings, &out.drawing);
    report_window(out.streams->schedule(), log);
    if (decided.background_to_choose && out.clip) {
        const ClipFrames& footage = sources.footage.count() > 0 ? sources.footage : *out.clip;
        const BackgroundChoice choice =
            choose_background(out.streams, out.clip, footage, settings, drawn_input_polylines(out.drawing));
        if (!job.keep_clip) sources.footage = ClipFrames();  // not needed while rendering
        out.background = choice.mode;
        out.median_detail = choice.median_detail;
        const bool carry = job.edit && job.carry_background_auto && !settings.carry_background &&
                           (out.background == BackgroundMode::replay ||
                            (out.background == BackgroundMode::median && settings.texture_layer == TextureLayer::whole));
        if (carry) settings.carry_background = true;
        char text[400];
        std::snprintf(text, sizeof text,
                      "background: %s (over the median plate synthesis keeps %.0f %% of the clip's detail within 20 px "
                      "of the lines%s; --background to choose)%s",
                      to_string(out.background), 100.0 * choice.median_detail,
                      out.background == BackgroundMode::replay ? ", below 80 %: the clip is replayed in step with the particles"
                                                               : "",
                      !carry ? ""
                      : out.background == BackgroundMode::replay
                          ? "; lines moved off the flow carry it from around their input lines (--no-carry-background: not)"
                          : "; lines moved off the flow carry the plate from around their input lines "
                            "(--no-carry-background: not)");
        say(log, text);
    }
    if (job.edit && job.edge_fade_auto && settings.edge_fade_px > 0.0)
        say(log, "edge: the texture fades out over " + std::to_string(static_cast<int>(std::lround(settings.edge_fade_px))) +
                     " px (a patch) where it ends, as the filmed flow's own edge fades into the scene (--edge-fade 0: not)");
    Background background = moving && out.background == BackgroundMode::median
                                ? Background::plate(*still_plate)
                                : make_background(out.background, out.clip, out.streams->schedule(), out.streams->patch_size());

    if (job.edit) {
        if (!job.interpolate) {
            for (const formats::FlowLine& line : out.drawing.outputs) out.outputs.push_back({line, line.from});
        } else {
            EditSettings edit_settings = job.edit_settings;
            edit_settings.mapping = settings.mapping;
            out.plan = plan_edit(out.drawing, *out.streams, edit_settings, progress);
            report_progress(progress, "correspondence", 1.0);
            for (const std::string& w : out.plan->warnings) say(log, "warning: " + w);
            out.outputs = output_lines(*out.plan);
        }
    }
    // The window and the edit's correspondence were chosen on whole textures,
    // so that both layers of one bank keep one timing and one assignment.
    if (moving) keep_moving_part(*out.bank, out.input_points, *still_plate);
    out.synthesizer = std::make_unique<Synthesizer>(out.streams, out.outputs, std::move(background), settings);
    out.settings = settings;
    const std::vector<std::string>& scheduled = out.streams->schedule().warnings;
    for (const std::string& w : out.synthesizer->warnings())
        if (std::find(scheduled.begin(), scheduled.end(), w) == scheduled.end()) say(log, "warning: " + w);
    if (job.keep_clip && sources.footage.count() > 0)
        out.footage = std::make_shared<const ClipFrames>(std::move(sources.footage));
    if (!job.keep_clip) out.clip.reset();  // a background that replays the clip holds it itself
    return out;
}

}  // namespace

PreparedSynthesis prepare_synthesis(SynthesisSources sources, const SynthesisJob& job, const Progress& progress) {
    if (!sources.bank) throw UsageError("", "", "no particle bank", "give the bank (SynthesisSources::bank)");
    const Decisions decided = decide(job, *sources.bank);
    check_drawing(sources.drawing, sources.drawing_name, *sources.bank, job, progress);
    return assemble(std::move(sources), job, decided, progress);
}

PreparedSynthesis prepare_synthesis(const SynthesisJob& job, const Progress& progress) {
    const Progress& log = progress;
    SynthesisSources sources;
    std::vector<Problem> warnings;
    sources.bank = std::make_shared<formats::ParticleBank>(formats::read_particle_bank(job.bank_path, &warnings));
    for (const Problem& w : warnings) say(log, w.to_string());
    warnings.clear();
    const Decisions decided = decide(job, *sources.bank);

    std::string why_no_clip;
    sources.capture = open_bank_clip(job, *sources.bank, why_no_clip);
    if (decided.clip_needed && !sources.capture) {
        const std::string need = job.keep_clip       ? "the measures need the source clip"
                                 : decided.moving    ? "--texture moving needs the source clip's still plate"
                                                     : "the background needs the source clip";
        throw UsageError(job.bank_path, "", need + " (" + why_no_clip + ")",
                         decided.moving || job.keep_clip ? "give --capture" : "give --capture, or --background none");
    }

    sources.drawing_name = job.flowlines_path;
    if (sources.drawing_name.empty() && sources.capture && !sources.capture->flowlines.empty())
        sources.drawing_name = sources.capture->resolve(sources.capture->flowlines);
    if (sources.drawing_name.empty())
        throw UsageError("", "", "no flow lines", "give --flowlines FILE (the drawing the bank was tracked with)");
    sources.drawing = formats::read_flowline_drawing(sources.drawing_name, &warnings);
    for (const Problem& w : warnings) say(log, w.to_string());
    check_drawing(sources.drawing, sources.drawing_name, *sources.bank, job, log);

    if (decided.clip_needed) {
        CaptureFrames frames(*sources.capture);
        if (frames.width() != sources.bank->clip_width_px || frames.height() != sources.bank->clip_height_px)
            throw ValidationError({{Problem::Severity::error, sources.capture->clip_path(), "frames",
                                    "frames are " + std::to_string(frames.width()) + " x " + std::to_string(frames.height()) +
                                        " but the bank was tracked at " + std::to_string(sources.bank->clip_width_px) +
                                        " x " + std::to_string(sources.bank->clip_height_px),
                                    "give the clip the bank was tracked from (--capture)"}});
        CameraMotion camera;
        bool cancelled = false;  // the reader stops early; what it read is not the clip
        const Progress reading = [&](const ProgressReport& r) { return !(cancelled = progress && !progress(r)); };
        ClipFrames* footage = decided.background_to_choose || job.keep_clip ? &sources.footage : nullptr;
        // The view the bank was tracked in, when it says (1.1); a 1.0 bank's
        // drift is estimated again, as its tracking did.
        const formats::ParticleBank& bank = *sources.bank;
        const bool stored = bank.camera && (bank.camera->model == formats::BankCameraModel::still ||
                                            static_cast<int>(bank.camera->first_to_frame.size()) == frames.count());
        if (stored) {
            camera = from_bank_camera(*bank.camera);
            sources.clip = std::make_shared<const ClipFrames>(read_clip_in_view(frames, camera, reading, footage));
        } else
            sources.clip = std::make_shared<const ClipFrames>(read_clip_stabilised(frames, sources.drawing, camera, reading, footage));
        if (cancelled) throw Cancelled();
        sources.camera = camera;
        // The lines were drawn on the first frame; the clip is now seen from its central view.
        sources.drawing = drawing_in_view(sources.drawing, camera);
        say(log, describe(camera));
    }
    // check_drawing has spoken; assemble says the rest.
    return assemble(std::move(sources), job, decided, progress);
}

SynthesisOutcome render_synthesis(const SynthesisJob& job, const SynthesisOutput& output, const Progress& progress) {
    if (!output.loop && (output.first_frame < 1 || output.last_frame < output.first_frame))
        throw UsageError("", "frames", "the range " + std::to_string(output.first_frame) + ":" +
                                           std::to_string(output.last_frame) + " is empty or starts before frame 1",
                         "give A:B with 1 <= A <= B");
    // Said before any work: an output the name alone rules out.
    FrameWriter::check_target(output.path, output.loop ? 0 : output.last_frame - output.first_frame + 1);
    formats::create_parent_folder(output.path);  // out/%06d.png or a video: its folder, made when missing
    if (!output.dense_lines_path.empty()) formats::create_parent_folder(output.dense_lines_path);
    const PreparedSynthesis prepared = prepare_synthesis(job, progress);
    SynthesisOutcome outcome;
    outcome.plan = prepared.plan;
    if (prepared.plan && !output.dense_lines_path.empty())
        formats::write_flowline_set(output.dense_lines_path,
                                    drawing_as_drawn(plan_to_flowlines(prepared.drawing, *prepared.plan),
                                                     prepared.camera.value_or(CameraMotion())));
    outcome.first_frame = output.loop ? 1 : output.first_frame;
    outcome.last_frame = output.loop ? prepared.synthesizer->period_frames() : output.last_frame;
    outcome.schedule = prepared.streams->schedule();
    outcome.background = prepared.background;
    outcome.median_detail = prepared.median_detail;
    outcome.settings = prepared.settings;
    outcome.camera = prepared.camera;

    const int total = outcome.last_frame - outcome.first_frame + 1;
    FrameWriter writer(output.path, prepared.synthesizer->width(), prepared.synthesizer->height(), prepared.bank->fps, total);
    // Counted here: a frame is written before the progress that may stop the render hears of it.
    prepared.synthesizer->render_frames(outcome.first_frame, outcome.last_frame, output.threads,
                                        [&](int frame, const RgbImage& image) {
                                            writer.write(frame, image);
                                            ++outcome.frames_written;
                                            return !progress || progress({"render",
                                                                          static_cast<double>(outcome.frames_written) / total,
                                                                          "frame " + std::to_string(frame)});
                                        });
    if (outcome.complete()) writer.close();
    else writer.discard();  // an interrupted video is not published as if it were whole
    return outcome;
}

EditQuality measure_edit(const PreparedSynthesis& prepared, int frames, double region_px, int threads,
                         const Progress& progress) {
    if (!prepared.clip) throw std::invalid_argument("measure_edit: prepare the synthesis with keep_clip");
    const ClipFrames& clip = *prepared.clip;
    const int width = clip.width(), height = clip.height();
    EditQuality out;
    out.output_frames = frames > 0 ? frames : 2 * clip.count();
    const std::vector<std::vector<float>> clip_luma = clip.luma_frames();
    std::vector<std::vector<float>> output_luma;
    for (const formats::FlowLine& line : prepared.drawing.outputs) out.moving_lines = out.moving_lines || line.is_time_varying();
    // Regions in the output's view, and where the lines were drawn (the
    // footage's pixels: the shared tool reads the drawing as it is).
    const CameraMotion camera = prepared.camera.value_or(CameraMotion());
    std::vector<std::vector<std::uint8_t>> regions, regions_as_drawn;
    const int rendered = prepared.synthesizer->render_frames(1, out.output_frames, threads, [&](int frame, const RgbImage& image) {
        output_luma.push_back(luma(to_display(image)));
        if (out.moving_lines || regions.empty()) {
            const std::vector<std::vector<Eigen::Vector2d>> lines = prepared.drawn_lines_at(frame);
            regions.push_back(line_band_mask(lines, width, height, region_px));
            if (prepared.footage)
                regions_as_drawn.push_back(line_band_mask(polylines_as_drawn(lines, camera), width, height, region_px));
        }
        return !progress || progress({"measure", 0.8 * frame / out.output_frames, "frame " + std::to_string(frame)});
    });
    if (rendered < out.output_frames) throw Cancelled();
    RegionSettings settings;
    settings.region_px = region_px;
    const double half_patch_px = 0.5 * prepared.bank->patch_size_px;  // what a particle's patch carries
    const std::vector<std::uint8_t> clip_region =
        line_band_mask(drawn_input_polylines(prepared.drawing), width, height, region_px);
    // The scene as filmed (in the output's view), over the first frames' regions.
    const std::size_t scene_frames = std::min(output_luma.size(), clip_luma.size());
    const std::vector<std::vector<float>> scene(clip_luma.begin(), clip_luma.begin() + static_cast<std::ptrdiff_t>(scene_frames));
    const auto first_regions = [scene_frames](const std::vector<std::vector<std::uint8_t>>& all) {
        return all.size() == 1 ? all : std::vector<std::vector<std::uint8_t>>(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(scene_frames));
    };
    if (prepared.footage) {
        // The shared scoring tool compares with the footage as filmed; the
        // still view says how much of the difference is the camera's drift.
        const std::vector<std::vector<float>> footage_luma = prepared.footage->luma_frames();
        const std::vector<std::uint8_t> footage_region =
            line_band_mask(polylines_as_drawn(drawn_input_polylines(prepared.drawing), camera), width, height, region_px);
        const RegionMeter footage_meter(footage_luma, width, height, footage_region, settings);
        out.region = footage_meter.measure(output_luma, regions_as_drawn);
        out.footage_over_region = footage_meter.measure(scene, first_regions(regions_as_drawn), true);
        out.region_still_view = RegionMeter(clip_luma, width, height, clip_region, settings).measure(output_luma, regions);
        out.tracked_texture_detail =
            clip_detail_share(footage_luma, width, height,
                              line_band_mask(polylines_as_drawn(prepared.input_points, camera), width, height, half_patch_px),
                              footage_region);
    } else {
        const RegionMeter clip_meter(clip_luma, width, height, clip_region, settings);
        out.region = clip_meter.measure(output_luma, regions);
        out.footage_over_region = clip_meter.measure(scene, first_regions(regions), true);
        out.tracked_texture_detail = clip_detail_share(
            clip_luma, width, height, line_band_mask(prepared.input_points, width, height, half_patch_px), clip_region);
    }
    report_progress(progress, "measure", 1.0);
    return out;
}

namespace {
nlohmann::json number_or_null(double value) { return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value); }
}  // namespace

nlohmann::json window_summary(const Schedule& schedule) {
    nlohmann::json out = {{"wrap_join_error", number_or_null(schedule.wrap_join_error)}};
    const Schedule::Window& longest = schedule.longest_window;
    if (longest.particles_per_line > 0)
        out["longest_window"] = {{"particles_per_line", longest.particles_per_line},
                                 {"first_start_frame", longest.first_start_frame},
                                 {"wrap_join_error", number_or_null(longest.wrap_join_error)}};
    return out;
}

nlohmann::json outcome_summary(const SynthesisOutcome& outcome, const SynthesisJob& job, const SynthesisOutput& output) {
    nlohmann::json summary;
    if (outcome.plan) {
        int interpolated = 0;
        for (const DenseLine& d : outcome.plan->lines) interpolated += d.drawn ? 0 : 1;
        summary["dense_lines"] = outcome.plan->lines.size();
        summary["interpolated_lines"] = interpolated;
        summary["correspondence_cost"] = outcome.plan->total_cost;
    }
    const Schedule& schedule = outcome.schedule;
    summary["output"] = output.path;
    summary["frames"] = {outcome.first_frame, outcome.first_frame + outcome.frames_written - 1};
    summary["frames_written"] = outcome.frames_written;
    summary["period_frames"] = schedule.period_frames;
    summary["particles_per_line"] = schedule.particles_per_line;
    summary["start_every"] = schedule.start_every;
    summary["first_start_frame"] = schedule.first_start_frame;
    summary.update(window_summary(schedule));
    summary["lines"] = schedule.lines.size();
    summary["background"] = to_string(outcome.background);
    summary["texture"] = to_string(outcome.settings.texture_layer);
    summary["coverage"] = outcome.settings.coverage_weight;
    summary["edge_fade_px"] = outcome.settings.edge_fade_px;
    if (job.edit) {
        summary["mapping"] = to_string(outcome.settings.mapping);
        summary["carry_background"] = outcome.settings.carry_background;
    }
    return summary;
}

}  // namespace flowvid::flow
