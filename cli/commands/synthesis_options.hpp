#pragma once
// Options the flow commands that render synthesis share (synth, edit,
// quality): the K-particle window and how overlapping patches are blended.

#include "flowvid/flow/synthesis.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "command.hpp"
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
    double coverage = -1.0;  // < 0: automatic (SynthesisJob::coverage_auto)
    int fade_frames = -1;
    int wrap_fade_frames = -1;
    std::string blend = "detail";
    double overlap_sharpness = 4.0;
    int borrow_within_frames = flow::SynthesisSettings{}.borrow_within_frames;
    double edge_fade_px = -1.0;  // < 0: automatic (SynthesisJob::edge_fade_auto)
};

// What `flowvid edit` (and `flowvid quality --edit`) take for the edit itself.
struct EditOptions {
    std::string mapping = "equal";
    double spacing_px = 0.0;
    double max_gap_px = 0.0;
    bool no_interpolate = false;
    int correspondence_frames = 30;
    std::string interpolated_inputs = "between";
    bool carry_background = false;
    bool no_carry_background = false;
};

// Adds --mapping, --spacing, --max-gap, --no-interpolate, --correspondence-frames,
// --interpolated-inputs, --carry-background and --no-carry-background.
void add_edit_options(CLI::App& app, EditOptions& options);

// Sets the job's edit, its mapping and its carried background from the options.
void apply_edit_options(const EditOptions& options, int threads, flow::SynthesisJob& job);

// Adds --particles, --first-start, --seed, --borrow-within, --coverage,
// --fade-frames, --wrap-fade-frames, --blend, --overlap-sharpness and
// --edge-fade to a command.
void add_synthesis_options(CLI::App& app, SynthesisOptions& options);

// The library settings those options give (the rest at their defaults).
flow::SynthesisSettings synthesis_settings(const SynthesisOptions& options);

// The job the synthesis options describe (the rest at the library's defaults).
flow::SynthesisJob synthesis_job(const std::string& bank, const std::string& capture, const std::string& flowlines,
                                 const std::string& background, const std::string& texture, const SynthesisOptions& options);

}  // namespace flowvid::cli
