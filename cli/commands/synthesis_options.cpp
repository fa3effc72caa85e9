#include "synthesis_options.hpp"

#include "flowvid/error.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "output.hpp"

#include <cmath>
#include <cstdio>

namespace flowvid::cli {

void add_synthesis_options(CLI::App& app, SynthesisOptions& o) {
    app.add_option("--particles", o.particles, "K particles per line in the diagonal order (0 = as many as fit)");
    app.add_option("--first-start", o.first_start, "input start frame of the first of the K particles (default: seeded)");
    app.add_option("--seed", o.seed, "chooses the K-particle window when several fit (0 = the one whose wrap joins best)");
    app.add_option("--borrow-within", o.borrow_within_frames,
                   "a window slot with no particle of its own start frame shows the nearest start's if it starts at "
                   "most N frames away, else it is left empty (0 = always empty)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--coverage", o.coverage,
                   "accumulated feather weight at which texture fully hides the background (default: 0.5 for "
                   "synth; 2 for edits, whose texture then fades with the feather where the clip had none)");
    app.add_option("--fade-frames", o.fade_frames, "particles fade in and out over N frames (-1 = automatic)");
    app.add_option("--wrap-fade-frames", o.wrap_fade_frames,
                   "the first particle of each period (where the diagonal order wraps) fades in over N frames "
                   "(-1 = automatic)");
    app.add_option("--blend", o.blend,
                   "where patches of different input frames overlap: detail (keep fine detail's contrast) or plain "
                   "(weighted mean)")
        ->check(CLI::IsMember({"detail", "plain"}))
        ->capture_default_str();
    app.add_option("--overlap-sharpness", o.overlap_sharpness,
                   "where patches of different input frames overlap, each group's weight is raised to this power "
                   "before mixing: 1 = in proportion (a double exposure), larger = the heavier shows, soft seam")
        ->check(CLI::Range(1.0, 64.0))
        ->capture_default_str();
    app.add_option("--edge-fade", o.edge_fade_px,
                   "the texture fades out over PX pixels at its edge, as a filmed fall's edge fades into the rock "
                   "(default: a patch for edits of whole textures, where new water meets the scene; 0 for synthesis "
                   "and the moving layer; 0 = off)")
        ->check(CLI::NonNegativeNumber);
}

flow::SynthesisSettings synthesis_settings(const SynthesisOptions& o) {
    flow::SynthesisSettings settings;
    settings.particles = o.particles;
    settings.first_start_frame = o.first_start;
    settings.seed = o.seed;
    settings.coverage_weight = o.coverage < 0.0 ? 0.5 : o.coverage;
    settings.fade_frames = o.fade_frames;
    settings.wrap_fade_frames = o.wrap_fade_frames;
    settings.preserve_detail = o.blend == "detail";
    settings.overlap_sharpness = o.overlap_sharpness;
    settings.borrow_within_frames = o.borrow_within_frames;
    return settings;
}

void add_edit_options(CLI::App& app, EditOptions& o) {
    app.add_option("--mapping", o.mapping, "equal or scaled arc length from input to output lines")
        ->check(CLI::IsMember({"equal", "scaled"}))
        ->capture_default_str();
    app.add_option("--spacing", o.spacing_px, "interpolated lines at most PX apart (0 = half a patch)");
    app.add_option("--max-gap", o.max_gap_px, "output lines further apart are not interpolated between (0 = 6 patches)");
    app.add_flag("--no-interpolate", o.no_interpolate, "render only the drawn output lines");
    app.add_option("--correspondence-frames", o.correspondence_frames, "frames the overlap error is averaged over")
        ->capture_default_str();
    app.add_option("--interpolated-inputs", o.interpolated_inputs,
                   "inputs an interpolated line may carry: between (those between its two drawn lines' inputs, "
                   "across the flow) or any (every input line, as the thesis; favours flat, static texture)")
        ->check(CLI::IsMember({"between", "any"}))
        ->capture_default_str();
    app.add_flag("--carry-background", o.carry_background,
                 "under the particles of a line moved off the flow, show the background around its input line "
                 "(smoothed): fills the gaps its particles leave, and the new flow fades into the scene (for water; "
                 "not for fire). Default: on for whole textures under --background auto");
    app.add_flag("--no-carry-background", o.no_carry_background,
                 "never carry the background, not even under --background auto")
        ->excludes("--carry-background");
}

void apply_edit_options(const EditOptions& o, int threads, flow::SynthesisJob& job) {
    job.edit = true;
    job.settings.mapping = flow::arc_mapping_from_string(o.mapping);
    job.settings.carry_background = o.carry_background;
    job.carry_background_auto = !o.no_carry_background;
    job.interpolate = !o.no_interpolate;
    job.edit_settings.spacing_px = o.spacing_px;
    job.edit_settings.max_gap_px = o.max_gap_px;
    job.edit_settings.correspondence_frames = o.correspondence_frames;
    job.edit_settings.interpolated_inputs = o.interpolated_inputs == "any" ? flow::EditSettings::InterpolatedInputs::any
                                                                          : flow::EditSettings::InterpolatedInputs::between;
    job.edit_settings.threads = threads;
}

flow::SynthesisJob synthesis_job(const std::string& bank, const std::string& capture, const std::string& flowlines,
                                 const std::string& background, const std::string& texture, const SynthesisOptions& options) {
    flow::SynthesisJob job;
    job.bank_path = bank;
    job.clip_path = capture;
    job.flowlines_path = flowlines;
    job.background = background;
    job.settings = synthesis_settings(options);
    job.texture_auto = texture == "auto";
    if (!job.texture_auto) job.settings.texture_layer = flow::texture_layer_from_string(texture);
    job.coverage_auto = options.coverage < 0.0;
    job.edge_fade_auto = options.edge_fade_px < 0.0;
    if (!job.edge_fade_auto) job.settings.edge_fade_px = options.edge_fade_px;
    return job;
}

}  // namespace flowvid::cli
