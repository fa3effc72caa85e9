#include "synthesis_options.hpp"

#include "flowvid/error.hpp"
#include "flowvid/flow/frames.hpp"
#include "output.hpp"

#include <cmath>
#include <cstdio>

namespace flowvid::cli {

namespace {
nlohmann::json number_or_null(double value) { return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value); }
}  // namespace

bool moving_layer_refused(flow::TextureLayer layer, flow::BackgroundMode mode, const std::string& background_option,
                          bool none_allowed) {
    const bool still = mode == flow::BackgroundMode::median || mode == flow::BackgroundMode::none;
    if (layer != flow::TextureLayer::moving || still) return false;
    log_message("error: --texture moving screens the flames over a still background, and the " + background_option +
                " background already " +
                (mode == flow::BackgroundMode::relit ? "carries their light" : "shows them") +
                ": use --background median (the clip's dark plate)" + (none_allowed ? " or none" : ""));
    return true;
}

void report_schedule(const flow::Schedule& schedule) {
    for (const std::string& w : schedule.warnings) log_message("warning: " + w);
    const flow::Schedule::Window& longest = schedule.longest_window;
    if (longest.particles_per_line == 0) return;
    char text[400];
    std::snprintf(text, sizeof text,
                  "window: K = %d particles from input frame %d (period %d frames), whose wrap joins better than the longest "
                  "window's (K = %d from frame %d): join error %.3f against %.3f (--particles and --first-start choose another)",
                  schedule.particles_per_line, schedule.first_start_frame, schedule.period_frames, longest.particles_per_line,
                  longest.first_start_frame, schedule.wrap_join_error, longest.wrap_join_error);
    log_message(text);
}

nlohmann::json window_summary(const flow::Schedule& schedule) {
    nlohmann::json out = {{"wrap_join_error", number_or_null(schedule.wrap_join_error)}};
    const flow::Schedule::Window& longest = schedule.longest_window;
    if (longest.particles_per_line > 0)
        out["longest_window"] = {{"particles_per_line", longest.particles_per_line},
                                 {"first_start_frame", longest.first_start_frame},
                                 {"wrap_join_error", number_or_null(longest.wrap_join_error)}};
    return out;
}

std::optional<formats::Capture> open_bank_clip(const std::string& capture_option, const std::string& bank_path,
                                               const formats::ParticleBank& bank, std::string& why_not) {
    if (!capture_option.empty()) return flow::open_clip(capture_option, bank.fps);
    const std::string recorded = formats::resolve_source_clip(bank_path, bank);
    if (recorded.empty()) {
        why_not = "not recorded in the bank";
        return std::nullopt;
    }
    try {
        return flow::open_clip(recorded, bank.fps);
    } catch (const Error& error) {
        why_not = recorded + " recorded in the bank: " + error.what();
        return std::nullopt;
    }
}

void add_synthesis_options(CLI::App& app, SynthesisOptions& o) {
    app.add_option("--particles", o.particles, "K particles per line in the diagonal order (0 = as many as fit)");
    app.add_option("--first-start", o.first_start, "input start frame of the first of the K particles (default: seeded)");
    app.add_option("--seed", o.seed, "chooses the K-particle window when several fit (0 = the one whose wrap joins best)");
    app.add_option("--borrow-within", o.borrow_within_frames,
                   "a window slot with no particle of its own start frame shows the nearest start's if it starts at "
                   "most N frames away, else it is left empty (0 = always empty)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--coverage", o.coverage, "accumulated feather weight at which texture fully hides the background")
        ->capture_default_str();
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
}

flow::SynthesisSettings synthesis_settings(const SynthesisOptions& o) {
    flow::SynthesisSettings settings;
    settings.particles = o.particles;
    settings.first_start_frame = o.first_start;
    settings.seed = o.seed;
    settings.coverage_weight = o.coverage;
    settings.fade_frames = o.fade_frames;
    settings.wrap_fade_frames = o.wrap_fade_frames;
    settings.preserve_detail = o.blend == "detail";
    settings.overlap_sharpness = o.overlap_sharpness;
    settings.borrow_within_frames = o.borrow_within_frames;
    return settings;
}

}  // namespace flowvid::cli
