#pragma once
// Options the flow commands that render synthesis share (synth, edit,
// quality): the K-particle window and how overlapping patches are blended.

#include "flowvid/flow/synthesis.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace flowvid::cli {

struct SynthesisOptions {
    int particles = 0;
    int first_start = -1;
    unsigned long long seed = 0;
    double coverage = 0.5;
    int fade_frames = -1;
    int wrap_fade_frames = -1;
    std::string blend = "detail";
    double overlap_sharpness = 4.0;
    int borrow_within_frames = flow::SynthesisSettings{}.borrow_within_frames;
};

// Adds --particles, --first-start, --seed, --borrow-within, --coverage,
// --fade-frames, --wrap-fade-frames, --blend and --overlap-sharpness to a command.
void add_synthesis_options(CLI::App& app, SynthesisOptions& options);

// The library settings those options give (the rest at their defaults).
flow::SynthesisSettings synthesis_settings(const SynthesisOptions& options);

// --texture moving screens the flow over a still background; the looped or
// replayed clip already shows it, and the relit plate its light. Logs why and
// returns true when `mode` is one of those (the caller exits with kExitUsage
// before reading the clip).
bool moving_layer_refused(flow::TextureLayer layer, flow::BackgroundMode mode, const std::string& background_option,
                          bool none_allowed);

// Logs the schedule's warnings and, when the window was shortened for a
// better-joining wrap, which window was taken over the longest and why.
void report_schedule(const flow::Schedule& schedule);

// The window's wrap join for a command's summary: {"wrap_join_error": x or
// null, "longest_window": {...} when a shorter window was taken}.
nlohmann::json window_summary(const flow::Schedule& schedule);

// The clip a bank was tracked from (a capture folder, a video or an image
// pattern): `capture_option` when given (its errors name the file and the
// fix), else the one the bank records. Nothing when the bank records none or
// it cannot be opened; `why_not` then says which and why.
std::optional<formats::Capture> open_bank_clip(const std::string& capture_option, const std::string& bank_path,
                                               const formats::ParticleBank& bank, std::string& why_not);

}  // namespace flowvid::cli
