#pragma once
// Options the flow commands that render synthesis share (synth, edit,
// quality): the K-particle window and how overlapping patches are blended.

#include "flowvid/flow/synthesis.hpp"

#include <CLI/CLI.hpp>

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

}  // namespace flowvid::cli
