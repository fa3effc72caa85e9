// flowvid quality: the measured quality of flow-based synthesis from a
// particle bank against the two baselines of issue 6 (naive looping of the
// clip; the flow-map method games use), on the bank's clip (flow/quality.hpp).

#include "command.hpp"
#include "frame_options.hpp"
#include "output.hpp"
#include "synthesis_options.hpp"

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/flowlines.hpp"

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
    FrameOptions frame_selection;  // resolved into frames
    int frames = 0;                // output frames 1..N measured; 0: twice the clip
    SynthesisOptions synthesis;
    std::string background = "auto";
    std::string texture = "auto";
    bool edit = false;
    EditOptions edit_options;
    double band_px = 0.0;
    double region_px = 20.0;
    int cycle = 32;
    int threads = 0;
    bool json = false;
    std::string series_csv;
};

std::string clip_frames_name(const flow::PreparedSynthesis& prepared) {
    return prepared.capture ? prepared.capture->clip_path() : std::string("the clip");
}

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

nlohmann::json region_json(const flow::RegionQuality& r) {
    return {{"seam_max_ratio_p99", r.seam_max_ratio},
            {"share_above_clip_p99", r.share_above_p99},
            {"pulse_cv", r.pulse_cv},
            {"pulse_peak", r.pulse_peak},
            {"detail", r.detail},
            {"patch_fidelity", r.patch_fidelity},
            {"patch_rms", r.patch_rms},
            {"motion", r.motion},
            {"region_pixels", r.output_region_pixels}};
}

nlohmann::json clip_region_json(const flow::RegionQuality& r) {
    return {{"seam_max_ratio_p99", r.clip_seam_max_ratio},
            {"share_above_clip_p99", r.clip_share_above_p99},
            {"pulse_cv", r.clip_pulse_cv},
            {"pulse_peak", r.clip_pulse_peak},
            {"patch_rms", r.clip_patch_rms},
            {"region_pixels", r.clip_region_pixels}};
}

// `still_view`: the rows compare with the stabilised clip instead of the footage as filmed.
void print_region_table(const std::vector<std::pair<std::string, flow::RegionQuality>>& rows, double region_px,
                        bool still_view = false) {
    if (rows.empty()) return;
    if (still_view)
        std::printf("the same against the clip seen from the output's still view (the camera's drift taken out):\n");
    else
        std::printf("whole flow region (within %.0f px of the drawn lines; ../shared/tools/baselines_flow.py's measures, "
                    "against the clip as filmed):\n",
                    region_px);
    std::printf("%-9s %9s %9s %9s %9s | %7s %9s %9s | %7s\n", "method", "seam/p99", "share>p99", "pulse cv", "pulse pk",
                "detail", "patch fid", "patch rms", "motion");
    for (const auto& [name, r] : rows)
        std::printf("%-9s %9.2f %9.3f %9.3f %9.2f | %7.2f %9.2f %9.2f | %7.2f\n", name.c_str(), r.seam_max_ratio,
                    r.share_above_p99, r.pulse_cv, r.pulse_peak, r.detail, r.patch_fidelity, r.patch_rms, r.motion);
    const flow::RegionQuality& c = rows.front().second;
    std::printf("%-9s %9.2f %9.3f %9.3f %9.2f | %7.2f %9.2f %9.2f | %7.2f\n", "clip", c.clip_seam_max_ratio,
                c.clip_share_above_p99, c.clip_pulse_cv, c.clip_pulse_peak, 1.0, 1.0, c.clip_patch_rms, 1.0);
}

// An edit has no baselines (they follow the input lines): it is measured over
// its own flow region, the output lines' (at every frame for moving lines),
// against the clip's.
int run_edit_quality(const QualityOptions& options, const flow::PreparedSynthesis& prepared, TerminalProgress& terminal) {
    const flow::ClipFrames& clip = *prepared.clip;
    const flow::EditQuality measured =
        flow::measure_edit(prepared, options.frames, options.region_px, options.threads, terminal.callback());
    terminal.finish();
    const flow::RegionQuality& edit = measured.region;
    const int frames = measured.output_frames;
    const bool moving_lines = measured.moving_lines;
    nlohmann::json summary = {{"bank", options.bank},
                              {"clip", clip_frames_name(prepared)},
                              {"clip_frames", clip.count()},
                              {"output_frames", frames},
                              {"edit", true},
                              {"output_lines", prepared.drawing.outputs.size()},
                              {"moving_lines", moving_lines},
                              {"region_px", options.region_px},
                              {"background", flow::to_string(prepared.background)},
                              {"texture", flow::to_string(prepared.settings.texture_layer)},
                              {"coverage", prepared.settings.coverage_weight},
                              {"edge_fade_px", prepared.settings.edge_fade_px},
                              {"carry_background", prepared.settings.carry_background},
                              {"region", {{"ours", region_json(edit)}}},
                              {"clip_region_reference", clip_region_json(edit)},
                              {"tracked_texture_detail", measured.tracked_texture_detail},
                              {"footage_over_region", region_json(measured.footage_over_region)}};
    if (measured.region_still_view) {
        summary["region_still_view"] = {{"ours", region_json(*measured.region_still_view)}};
        summary["clip_region_reference_still_view"] = clip_region_json(*measured.region_still_view);
    }
    if (options.json) {
        std::cout << summary.dump(2) << '\n';
        return kExitOk;
    }
    std::printf("%s: %d clip frames, %d output frames of the edit along %zu output lines%s\n", clip_frames_name(prepared).c_str(),
                clip.count(), frames, prepared.drawing.outputs.size(), moving_lines ? " (moving: the region follows them)" : "");
    print_region_table({{"edit", edit}}, options.region_px);
    std::printf("the clip's moving texture alone (within half a patch of the stretches tracked) has detail %.2f: an edit\n"
                "covered by moved texture keeps about that much; more is the scene showing between and under it\n",
                measured.tracked_texture_detail);
    std::printf("the footage itself over the same region%s scores detail %.2f and patch fidelity %.2f\n"
                "(each frame searched without its own): what leaving the scene as filmed scores there\n",
                prepared.footage ? " (stabilised into the output's view)" : "", measured.footage_over_region.detail,
                measured.footage_over_region.patch_fidelity);
    if (measured.region_still_view) print_region_table({{"edit", *measured.region_still_view}}, options.region_px, true);
    return kExitOk;
}

int run_quality(const QualityOptions& options, const GlobalOptions& global) {
    if (!options.series_csv.empty()) formats::create_parent_folder(options.series_csv);
    flow::SynthesisJob job = synthesis_job(options.bank, options.capture, options.flowlines, options.background,
                                           options.texture, options.synthesis);
    job.keep_clip = true;  // the measures compare with it
    if (options.edit) apply_edit_options(options.edit_options, options.threads, job);
    TerminalProgress progress(global, "quality");
    const flow::PreparedSynthesis prepared = flow::prepare_synthesis(job, progress.callback());
    if (options.edit) return run_edit_quality(options, prepared, progress);
    const flow::ClipFrames& clip = *prepared.clip;
    const flow::RgbImage plate = flow::median_plate(clip);  // the flow map's background

    flow::ComparisonSettings compare;
    compare.output_frames = options.frames;
    compare.band_half_width_px = options.band_px;
    compare.flow_map_cycle_frames = options.cycle;
    compare.threads = options.threads;
    compare.region_lines = flow::drawn_input_polylines(prepared.drawing);
    compare.region.region_px = options.region_px;
    compare.footage = prepared.footage.get();
    if (prepared.footage && prepared.camera)
        compare.footage_region_lines = flow::polylines_as_drawn(compare.region_lines, *prepared.camera);
    const flow::Comparison result =
        flow::compare_with_baselines(clip, *prepared.streams, *prepared.synthesizer, plate, compare, progress.callback());
    progress.finish();
    if (!options.series_csv.empty()) write_series_csv(options.series_csv, result);

    const flow::Schedule& schedule = prepared.streams->schedule();
    int missing = 0, borrowed = 0;  // slots without a particle of their start frame; those borrowing a near one
    for (const flow::LineSchedule& l : schedule.lines) {
        missing += l.substituted;
        borrowed += l.borrowed;
    }
    nlohmann::json summary = {{"bank", options.bank},
                              {"clip", clip_frames_name(prepared)},
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
                               {{"background", flow::to_string(prepared.background)},
                                {"texture", flow::to_string(prepared.settings.texture_layer)},
                                {"blend", options.synthesis.blend},
                                {"overlap_sharpness", options.synthesis.overlap_sharpness},
                                {"coverage", prepared.settings.coverage_weight},
                                {"edge_fade_px", prepared.settings.edge_fade_px},
                                {"fade_frames", options.synthesis.fade_frames},
                                {"wrap_fade_frames", options.synthesis.wrap_fade_frames},
                                {"borrow_within_frames", options.synthesis.borrow_within_frames},
                                {"first_start_frame", schedule.first_start_frame}}}};
    summary.update(flow::window_summary(schedule));
    nlohmann::json methods = nlohmann::json::object(), region = nlohmann::json::object(),
                   region_still = nlohmann::json::object();
    std::vector<std::pair<std::string, flow::RegionQuality>> region_rows, still_rows;
    for (const flow::MethodQuality& m : result.methods) {
        methods[m.method] = report_json(m.report);
        if (m.region) {
            region[m.method] = region_json(*m.region);
            region_rows.emplace_back(m.method, *m.region);
        }
        if (m.region_still_view) {
            region_still[m.method] = region_json(*m.region_still_view);
            still_rows.emplace_back(m.method, *m.region_still_view);
        }
    }
    summary["methods"] = methods;
    summary["region_px"] = options.region_px;
    summary["region"] = region;
    if (!region_rows.empty()) summary["clip_region_reference"] = clip_region_json(region_rows.front().second);
    if (!still_rows.empty()) {
        summary["region_still_view"] = region_still;
        summary["clip_region_reference_still_view"] = clip_region_json(still_rows.front().second);
    }
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
                clip_frames_name(prepared).c_str(), clip.count(), result.output_frames, schedule.lines.size(),
                schedule.particles_per_line, schedule.start_every, schedule.period_frames, missing,
                schedule.lines.size() * static_cast<std::size_t>(schedule.particles_per_line), borrowed);
    std::printf("band around the tracked lines (%zu pixels):\n", result.mask_pixels);
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
    print_region_table(region_rows, options.region_px);
    print_region_table(still_rows, options.region_px, true);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "quality", "measure synthesis from a bank against naive looping and the flow-map method",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<QualityOptions>();
        app.footer(
            "Renders frames 1..N of the infinite sequence (as flowvid synth renders it, with its --background and\n"
            "--texture), the clip looped, and the flow-map method games use (the clip's first frame advected\n"
            "by the tracked speeds in two layers half a cycle apart, cross-faded), and measures each against\n"
            "the clip on luma, twice.\n"
            "In the band around the tracked lines (issue 6):\n"
            "  seam max   largest frame-to-frame difference / the clip's 95th percentile\n"
            "  share>p99  share of transitions above the clip's 99th percentile\n"
            "  spike      largest transition / the method's own median transition (a seam stands out\n"
            "             from the motion around it; the clip's own value is printed below the table)\n"
            "  pulsing    coefficient of variation of per-frame high-frequency energy (clip: its own)\n"
            "  patch d    RMS distance of 16x16 output patches to their nearest clip patch (self d: the\n"
            "             clip's patches to frames >= 5 apart)\n"
            "  HF ratio   output / clip high-frequency energy (blur lowers it)\n"
            "  motion     output / clip median frame-to-frame difference (a still frame slid along: low)\n"
            "Over the whole flow region (every pixel within --region px of the drawn lines: what a viewer\n"
            "sees), as ../shared/tools/baselines_flow.py scores it:\n"
            "  seam/p99   largest whole-frame transition / the clip's 99th percentile; share>p99 as above\n"
            "  pulse cv   variation of the Laplacian energy in the region; pulse pk: its largest share in\n"
            "             one period of 4..50 frames (a periodic pulse: near 1)\n"
            "  detail     Laplacian energy, output / clip (0.8..1.25: as detailed as the footage)\n"
            "  patch fid  24x24 output patches to the nearest clip patch anywhere in the clip's region,\n"
            "             over the clip's own leave-one-frame-out distance (1: as novel as a real frame)\n"
            "  motion     median change in the region, output / clip\n"
            "The clip rows measure the clip against itself: what an output that moves like the clip scores.\n"
            "Against the clip as filmed, as the tool does. When the camera drifts, a second table compares\n"
            "with the clip seen from the output's still view: the difference is what the drift costs.\n"
            "--edit measures the edit along the drawing's output lines instead (as flowvid edit renders it,\n"
            "with its options): over the output lines' region, at every frame for moving (keyed) lines.\n\n"
            "Examples:\n"
            "  flowvid track --capture ../shared/captures/video-waterfall-cascade --out w.bank.exr\n"
            "  flowvid quality --bank w.bank.exr\n"
            "  flowvid quality --bank w.bank.exr --series w.quality.csv   # per-frame curves to plot\n"
            "  flowvid quality --bank w.bank.exr --edit --frame-count 240     # the capture's drawn edit\n"
            "  flowvid quality --bank w.bank.exr --edit --flowlines particles.flowlines.json\n"
            "  flowvid quality --bank fire.bank.exr --capture ../shared/captures/video-fire-pot --json");
        app.add_option("--bank", options->bank, "particle bank written by flowvid track (.exr)")->required();
        app.add_option("--capture,--clip", options->capture, "the source clip (default: the one recorded in the bank)");
        app.add_option("--flowlines", options->flowlines, "the drawing the bank was tracked with, with the output lines for --edit (default: the capture's)");
        add_frame_options(app, options->frame_selection, "output frames 1 to B measured (the sequence starts at 1)",
                          "output frames 1 to N measured", "twice the clip");
        add_synthesis_options(app, options->synthesis);  // as synth renders
        app.add_option("--background", options->background,
                       "our synthesis's background where no line reaches: auto, median, loop, replay or relit (as in "
                       "synth and edit)")
            ->check(CLI::IsMember({"auto", "median", "loop", "replay", "relit"}))
            ->capture_default_str();
        app.add_option("--texture", options->texture,
                       "what our synthesis's patches carry: auto, whole, or moving (the light the flow adds, screened "
                       "over the clip's dark plate; as in synth and edit)")
            ->check(CLI::IsMember({"auto", "whole", "moving"}))
            ->capture_default_str();
        app.add_option("--band", options->band_px, "measure within PX of the tracked lines (0 = a quarter patch)");
        app.add_option("--region", options->region_px, "the whole flow region: within PX of the drawn lines")
            ->check(CLI::PositiveNumber)
            ->capture_default_str();
        app.add_flag("--edit", options->edit,
                     "measure the edit along the drawing's output lines (as flowvid edit renders it) over their region");
        add_edit_options(app, options->edit_options);  // as edit renders
        app.add_option("--cycle", options->cycle, "flow-map layer life in frames")->capture_default_str();
        app.add_option("--threads", options->threads, "frames rendered at once (0 = all cores)");
        app.add_flag("--json", options->json, "print the measures as JSON");
        app.add_option("--series", options->series_csv,
                       "also write per-frame transitions and HF energy of the clip and each method (CSV): where a "
                       "seam or a pulse happens");
        return [options](const GlobalOptions& global) {
            options->frames = resolve_frame_count(options->frame_selection, 1, "the measures run from the first output frame", 0)
                                  .value_or(0);
            return run_quality(*options, global);
        };
    }}};

}  // namespace
}  // namespace flowvid::cli
