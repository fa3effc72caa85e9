// flowvid quality: the measured quality of flow-based synthesis from a
// particle bank against the two baselines of issue 6 (naive looping of the
// clip; the flow-map method games use), on the bank's clip (flow/quality.hpp).

#include "command.hpp"
#include "output.hpp"
#include "synthesis_options.hpp"

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace flowvid::cli {
namespace {

struct QualityOptions {
    std::string bank;
    std::string capture;
    std::string flowlines;
    int frames = 0;
    SynthesisOptions synthesis;
    std::string background = "median";
    std::string texture = "whole";
    double band_px = 0.0;
    int cycle = 32;
    int threads = 0;
    bool json = false;
    std::string series_csv;
};

nlohmann::json report_json(const flow::QualityReport& r) {
    return {{"seam_max_ratio", r.max_transition_ratio},
            {"share_above_clip_p99", r.share_above_p99},
            {"pulsing", r.pulsing},
            {"clip_pulsing", r.clip_pulsing},
            {"patch_distance", r.patch_distance},
            {"clip_self_distance", r.clip_self_distance},
            {"hf_power_ratio", r.hf_power_ratio},
            {"motion_ratio", r.motion_ratio},
            {"seam_spike", r.seam_spike},
            {"clip_seam_spike", r.clip_seam_spike},
            {"clip_transition_p95", r.clip_p95},
            {"clip_transition_p99", r.clip_p99},
            {"transitions", r.transitions}};
}

// One row per output frame: each method's transition into that frame and its
// high-frequency energy; the clip's own columns are empty past its length.
void write_series_csv(const std::string& path, const flow::Comparison& result) {
    formats::write_file_atomically(path, [&](std::ostream& out) {
        out << "frame,clip_transition,clip_hf_energy";
        for (const flow::MethodQuality& m : result.methods) {
            std::string name = m.method;
            for (char& c : name)
                if (c == ' ') c = '_';
            out << ',' << name << "_transition," << name << "_hf_energy";
        }
        out << '\n';
        out.precision(10);
        const auto cell = [&out](const std::vector<double>& values, int i) {
            out << ',';
            if (i >= 0 && i < static_cast<int>(values.size())) out << values[static_cast<std::size_t>(i)];
        };
        // Row t (1-based frame): the transition from frame t-1 to t, and frame t's energy.
        for (int t = 1; t <= result.output_frames; ++t) {
            out << t;
            cell(result.clip_series.transitions, t - 2);
            cell(result.clip_series.hf_energy, t - 1);
            for (const flow::MethodQuality& m : result.methods) {
                cell(m.series.transitions, t - 2);
                cell(m.series.hf_energy, t - 1);
            }
            out << '\n';
        }
    });
}

int run_quality(const QualityOptions& options, const GlobalOptions& global) {
    if (!options.series_csv.empty()) prepare_output_folder(options.series_csv);
    std::vector<Problem> warnings;
    auto bank = std::make_shared<formats::ParticleBank>(formats::read_particle_bank(options.bank, &warnings));
    print_problems(warnings);
    std::string why_no_clip;
    const std::optional<formats::Capture> opened = open_bank_clip(options.capture, options.bank, *bank, why_no_clip);
    if (!opened) {
        log_message("error: " + options.bank + ": the measures need the source clip (" + why_no_clip + "); give --capture");
        return kExitUsage;
    }
    const formats::Capture& capture = *opened;
    std::string lines_path = options.flowlines;
    if (lines_path.empty() && !capture.flowlines.empty()) lines_path = capture.resolve(capture.flowlines);
    if (lines_path.empty()) {
        log_message("error: no flow lines: give --flowlines FILE (the drawing the bank was tracked with)");
        return kExitUsage;
    }
    const formats::FlowLineSet drawing = formats::read_flowline_drawing(lines_path, &warnings);
    print_problems(warnings);

    const flow::TextureLayer layer = flow::texture_layer_from_string(options.texture);
    const flow::BackgroundMode background_mode = flow::background_mode_from_string(options.background);
    const bool moving = layer == flow::TextureLayer::moving;
    if (moving_layer_refused(layer, background_mode, options.background, false)) return kExitUsage;
    flow::SynthesisSettings settings = synthesis_settings(options.synthesis);
    settings.texture_layer = layer;
    const std::vector<std::vector<Eigen::Vector2d>> input_points =
        flow::ParticleStreams::input_points_from_drawing(*bank, drawing, lines_path);
    auto streams = std::make_shared<flow::ParticleStreams>(bank, input_points, settings, &drawing);
    report_schedule(streams->schedule());

    Progress reading(global, "read clip");
    flow::CaptureFrames frames(capture);
    if (frames.width() != bank->clip_width_px || frames.height() != bank->clip_height_px) {
        log_message("error: " + capture.clip_path() + ": frames are " + std::to_string(frames.width()) + " x " +
                    std::to_string(frames.height()) + " but the bank was tracked at " +
                    std::to_string(bank->clip_width_px) + " x " + std::to_string(bank->clip_height_px));
        return kExitInvalidInput;
    }
    flow::CameraMotion camera;
    const auto clip_frames = std::make_shared<const flow::ClipFrames>(flow::read_clip_stabilised(frames, drawing, camera, [&](double f) {
        reading.update(f);
        return true;
    }));
    reading.done();
    log_message(flow::describe(camera));
    const flow::ClipFrames& clip = *clip_frames;
    const flow::RgbImage plate = flow::median_plate(clip);  // also the flow map's background
    // As synth renders it: the moving layer over the dark plate it was taken
    // from, with the window chosen on whole textures.
    std::optional<flow::Background> background;
    if (moving) {
        flow::RgbImage still_plate = flow::moving_layer_still_plate(clip);
        flow::keep_moving_part(*bank, input_points, still_plate);
        background = flow::Background::plate(std::move(still_plate));
    } else if (background_mode == flow::BackgroundMode::median) {
        background = flow::Background::plate(plate);
    } else {
        background = flow::make_background(background_mode, clip_frames, streams->schedule(), streams->patch_size());
    }
    const flow::Synthesizer synth(streams, {}, std::move(*background), settings);

    flow::ComparisonSettings compare;
    compare.output_frames = options.frames;
    compare.band_half_width_px = options.band_px;
    compare.flow_map_cycle_frames = options.cycle;
    compare.threads = options.threads;
    Progress progress(global, "measure");
    InterruptWatch interrupt;
    flow::Comparison result;
    try {
        result = flow::compare_with_baselines(clip, *streams, synth, plate, compare, [&](double f) {
            progress.update(f);
            return !interrupt.requested();
        });
    } catch (const std::runtime_error& e) {
        if (std::string(e.what()) != "cancelled") throw;
        log_message("interrupted");
        return kExitInterrupted;
    }
    progress.done();
    if (!options.series_csv.empty()) write_series_csv(options.series_csv, result);

    const flow::Schedule& schedule = streams->schedule();
    int missing = 0, borrowed = 0;  // slots without a particle of their start frame; those borrowing a near one
    for (const flow::LineSchedule& l : schedule.lines) {
        missing += l.substituted;
        borrowed += l.borrowed;
    }
    nlohmann::json summary = {{"bank", options.bank},
                              {"clip", capture.clip_path()},
                              {"clip_frames", clip.count()},
                              {"output_frames", result.output_frames},
                              {"mask_pixels", result.mask_pixels},
                              {"particles_per_line", schedule.particles_per_line},
                              {"start_every", schedule.start_every},
                              {"period_frames", schedule.period_frames},
                              {"lines", schedule.lines.size()},
                              {"missing_slots", missing},
                              {"borrowed_slots", borrowed},
                              // What the measured synthesis was rendered with, so figures can be traced.
                              {"synthesis",
                               {{"background", options.background},
                                {"texture", options.texture},
                                {"blend", options.synthesis.blend},
                                {"overlap_sharpness", options.synthesis.overlap_sharpness},
                                {"coverage", options.synthesis.coverage},
                                {"fade_frames", options.synthesis.fade_frames},
                                {"wrap_fade_frames", options.synthesis.wrap_fade_frames},
                                {"borrow_within_frames", options.synthesis.borrow_within_frames},
                                {"first_start_frame", schedule.first_start_frame}}}};
    summary.update(window_summary(schedule));
    nlohmann::json methods = nlohmann::json::object();
    for (const flow::MethodQuality& m : result.methods) methods[m.method] = report_json(m.report);
    summary["methods"] = methods;
    // The clip against itself: what an output that moves like it scores.
    const flow::QualityReport& reference = result.methods.front().report;
    summary["clip_reference"] = {{"seam_max_ratio", reference.clip_max_ratio},
                                 {"smallest_transition_ratio", reference.clip_min_ratio},
                                 {"seam_spike", reference.clip_seam_spike},
                                 {"pulsing", reference.clip_pulsing},
                                 {"self_distance", reference.clip_self_distance}};
    if (options.json) {
        std::cout << summary.dump(2) << '\n';
        return kExitOk;
    }
    std::printf("%s: %d clip frames, %d output frames, %zu lines, K = %d, step %d, period %d frames, %d of %zu slots "
                "without a particle (%d borrowing a near one)\n",
                capture.clip_path().c_str(), clip.count(), result.output_frames, schedule.lines.size(),
                schedule.particles_per_line, schedule.start_every, schedule.period_frames, missing,
                schedule.lines.size() * static_cast<std::size_t>(schedule.particles_per_line), borrowed);
    std::printf("%-9s %9s %9s %9s | %8s %8s | %9s %9s %8s | %7s\n", "method", "seam max", "share>p99", "spike", "pulsing",
                "(clip)", "patch d", "(self d)", "HF ratio", "motion");
    for (const flow::MethodQuality& m : result.methods) {
        const flow::QualityReport& r = m.report;
        std::printf("%-9s %9.2f %9.3f %9.2f | %8.3f %8.3f | %9.4f %9.4f %8.2f | %7.2f\n", m.method.c_str(),
                    r.max_transition_ratio, r.share_above_p99, r.seam_spike, r.pulsing, r.clip_pulsing, r.patch_distance,
                    r.clip_self_distance, r.hf_power_ratio, r.motion_ratio);
    }
    std::printf("%-9s %9.2f %9s %9.2f | %8.3f %8s | %9s %9.4f %8.2f | %7.2f\n", "clip", reference.clip_max_ratio, "-",
                reference.clip_seam_spike, reference.clip_pulsing, "", "-", reference.clip_self_distance, 1.0, 1.0);
    std::printf("clip: its transitions span %.2f..%.2f x its p95; an output whose seam max is below %.2f changes less "
                "than the clip at every frame\n",
                reference.clip_min_ratio, reference.clip_max_ratio, reference.clip_min_ratio);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "quality", "measure synthesis from a bank against naive looping and the flow-map method",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<QualityOptions>();
        app.footer(
            "Renders frames 1..N of the infinite sequence (as flowvid synth does, with its --background and\n"
            "--texture), the clip looped, and the flow-map method games use (the clip's first frame advected\n"
            "by the tracked speeds in two layers half a cycle apart, cross-faded), and measures each against\n"
            "the clip on luma in the band around the tracked lines (issue 6):\n"
            "  seam max   largest frame-to-frame difference / the clip's 95th percentile\n"
            "  share>p99  share of transitions above the clip's 99th percentile\n"
            "  spike      largest transition / the method's own median transition (a seam stands out\n"
            "             from the motion around it; the clip's own value is printed below the table)\n"
            "  pulsing    coefficient of variation of per-frame high-frequency energy (clip: its own)\n"
            "  patch d    RMS distance of 16x16 output patches to their nearest clip patch (self d: the\n"
            "             clip's patches to frames >= 5 apart)\n"
            "  HF ratio   output / clip high-frequency energy (blur lowers it)\n"
            "  motion     output / clip median frame-to-frame difference (a still frame slid along: low)\n"
            "The last row measures the clip against itself: what an output that moves like the clip scores.\n\n"
            "Examples:\n"
            "  flowvid track --capture ../shared/captures/video-waterfall-cascade --densify 12 --out w.bank.exr\n"
            "  flowvid quality --bank w.bank.exr\n"
            "  flowvid quality --bank w.bank.exr --series w.quality.csv   # per-frame curves to plot\n"
            "  flowvid quality --bank fire.bank.exr --capture ../shared/captures/video-fire-pot --json");
        app.add_option("--bank", options->bank, "particle bank written by flowvid track (.exr)")->required();
        app.add_option("--capture,--clip", options->capture, "the source clip (default: the one recorded in the bank)");
        app.add_option("--flowlines", options->flowlines, "the drawing the bank was tracked with (default: the capture's)");
        app.add_option("--frames", options->frames, "output frames measured (0 = twice the clip)")
            ->check(CLI::NonNegativeNumber);
        add_synthesis_options(app, options->synthesis);  // as synth renders
        app.add_option("--background", options->background,
                       "our synthesis's background where no line reaches: median, loop, replay or relit (as in synth)")
            ->check(CLI::IsMember({"median", "loop", "replay", "relit"}))
            ->capture_default_str();
        app.add_option("--texture", options->texture,
                       "what our synthesis's patches carry: whole, or moving (the light the flow adds, screened over "
                       "the clip's dark plate; as in synth)")
            ->check(CLI::IsMember({"whole", "moving"}))
            ->capture_default_str();
        app.add_option("--band", options->band_px, "measure within PX of the tracked lines (0 = a quarter patch)");
        app.add_option("--cycle", options->cycle, "flow-map layer life in frames")->capture_default_str();
        app.add_option("--threads", options->threads, "frames rendered at once (0 = all cores)");
        app.add_flag("--json", options->json, "print the measures as JSON");
        app.add_option("--series", options->series_csv,
                       "also write per-frame transitions and HF energy of the clip and each method (CSV): where a "
                       "seam or a pulse happens");
        return [options](const GlobalOptions& global) { return run_quality(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
