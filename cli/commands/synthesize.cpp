// flowvid synth / flowvid edit: render any range of the seamless infinite
// sequence from a particle bank, along the input lines (synth) or along new,
// possibly moving, output lines (edit). thesis 3.2-3.4, flow/synthesis.hpp and
// flow/editing.hpp.

#include "command.hpp"
#include "frame_options.hpp"
#include "synthesis_options.hpp"
#include "output.hpp"

#include "flowvid/flow/editing.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/synthesis_job.hpp"

#include <iostream>
#include <memory>
#include <tuple>

namespace flowvid::cli {
namespace {

struct RenderOptions {
    std::string bank;
    std::string capture;
    std::string flowlines;
    FrameOptions frames;  // default 1:100
    std::string out;
    std::string background = "auto";
    std::string texture = "auto";
    SynthesisOptions synthesis;
    bool loop = false;
    int threads = 0;
    bool json = false;
    EditOptions edit;
    std::string dense_out;
};

int render(const RenderOptions& options, const GlobalOptions& global, bool edit) {
    flow::SynthesisOutput output;
    output.path = options.out;
    output.loop = options.loop;
    output.threads = options.threads;
    output.dense_lines_path = options.dense_out;
    // Frames of the infinite sequence, numbered from 1 as capture.json and
    // the flow-line keys count.
    if (!options.loop) std::tie(output.first_frame, output.last_frame) = resolve_frame_range(options.frames, 1, 100, 1, -1);
    flow::SynthesisJob job = synthesis_job(options.bank, options.capture, options.flowlines, options.background,
                                           options.texture, options.synthesis);
    if (edit) apply_edit_options(options.edit, options.threads, job);
    TerminalProgress progress(global, edit ? "edit" : "synth");
    const flow::SynthesisOutcome outcome = flow::render_synthesis(job, output, progress.callback());
    progress.finish();

    const nlohmann::json summary = flow::outcome_summary(outcome, job, output);
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    if (!outcome.complete()) {
        log_message("interrupted after " + std::to_string(outcome.frames_written) + " frames");
        return kExitInterrupted;
    }
    return kExitOk;
}

void add_common(CLI::App& app, RenderOptions& o) {
    app.add_option("--bank", o.bank, "particle bank written by flowvid track (.exr)")->required();
    add_frame_options(app, o.frames, "frames A to B of the infinite sequence (1-based, inclusive)",
                      "frames 1 to N", "1:100");
    app.add_option("--out", o.out,
                   "image pattern (out/%06d.png, .exr, .tif), folder, video (.mp4, .avi), or for one frame an image "
                   "(still.png)")
        ->required();
    app.add_option("--capture,--clip", o.capture, "the source clip (default: the one recorded in the bank)");
    app.add_option("--background", o.background,
                   "where no line reaches: auto (median, or replay when over the median synthesis keeps "
                   "under 80 % of the clip's detail around the lines; with --texture moving: median), median (static plate), loop "
                   "(the clip), replay (the clip in step with the particles: the input frame they show), relit (the plate darkened where that frame is: the light of "
                   "flames comes and goes on the scene, and patch ends meet it), none")
        ->check(CLI::IsMember({"auto", "median", "loop", "replay", "relit", "none"}))
        ->capture_default_str();
    app.add_option("--texture", o.texture,
                   "what a patch carries: whole (everything in it: water and the rock it passes), moving (only the "
                   "light the flow adds to the clip's dark plate, screened over that plate, or over black with "
                   "--background none: flames and smoke in front of a scene, whose edits should not move the "
                   "scene's edges), or auto (moving for edits of a bank tracked with --dynamics non-stationary, "
                   "else whole)")
        ->check(CLI::IsMember({"auto", "whole", "moving"}))
        ->capture_default_str();
    app.add_flag("--loop", o.loop, "render exactly one period (frames 1..K*step): a file that loops seamlessly")
        ->excludes("--frames")
        ->excludes("--frame-count");
    add_synthesis_options(app, o.synthesis);
    app.add_option("--threads", o.threads, "frames rendered at once (0 = all cores)");
    app.add_flag("--json", o.json, "print the summary as JSON");
}

const RegisterCommand synth_registration{Command{
    "synth", "render any range of the seamless infinite sequence from a particle bank",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<RenderOptions>();
        app.footer(
            "Particles enter every input line in the diagonal order of the thesis (fig. 3.5): the m-th\n"
            "particle on a line replays input particle m mod K, whole, from the line's start to its end.\n"
            "Patches are feathered and put back on the pixels they came from; the background shows where\n"
            "no line reaches. Frame A of the infinite sequence is the same whichever range it is rendered\n"
            "in (image files are named by frame number), and the sequence repeats every K*step frames.\n"
            "The flow lines default to the capture's flowlines.svg; give the drawing the bank was tracked\n"
            "with (synth rebuilds segments and interpolated lines from it).\n"
            "The background (--background auto) is the clip's median plate, or the clip replayed in step\n"
            "with the particles when over the plate the output would keep under 80 % of the clip's detail\n"
            "around the lines (mist and spray the particles do not cover); the log says which and why.\n"
            "A drifting camera is rendered still, in the clip's central view (flowvid help track).\n\n"
            "Examples:\n"
            "  flowvid synth --bank waterfall.bank.exr --frame-count 250 --out out/%06d.png\n"
            "  flowvid synth --bank waterfall.bank.exr --frames 251:500 --out out/%06d.png   # continues the above\n"
            "  flowvid synth --bank waterfall.bank.exr --loop --out loop.mp4 --background loop");
        add_common(app, *options);
        app.add_option("--flowlines", options->flowlines, "the drawing the bank was tracked with (default: the capture's)");
        return [options](const GlobalOptions& global) { return render(*options, global, false); };
    }}};

const RegisterCommand edit_registration{Command{
    "edit", "render the infinite sequence along new (also moving) output flow lines",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<RenderOptions>();
        app.footer(
            "Output lines are the group id=\"output\" of --flowlines, each naming the input line whose\n"
            "texture it carries (data-from / from). A dense set is interpolated between neighbouring\n"
            "output lines (--spacing apart) and every interpolated line gets the input line, among those\n"
            "between its two drawn lines' inputs, that minimises the patch-overlap error with its\n"
            "neighbours (dynamic programming, thesis eq. 3.1, averaged over 30 frames); each interpolated\n"
            "line shows its input at its own offset in time, so neighbours do not repeat one texture.\n"
            "Texture is warped along each output line through the tangent frames, with equal arc lengths\n"
            "or arc lengths scaled to the output line's length (--mapping, thesis fig. 3.17).\n"
            "Output lines with keys (*.flowlines.json) move over time, e.g. lines from a simulation.\n"
            "Lines moved off the flow show their particles over the output's own background, which\n"
            "shows through where the input line's particles leave gaps (parts nothing crossed within\n"
            "the clip); --carry-background fills those with the background around the input line. For\n"
            "whole textures under --background auto (water) that is on by default: a new channel shows\n"
            "the water around its input line (the replayed clip, or the median plate), not the rock it\n"
            "was drawn over through scalloped patch borders (--no-carry-background: off). The log says\n"
            "what was chosen.\n"
            "Texture carried over a background unlike its own (water over rock) ends in a hard edge at\n"
            "the default --coverage 0.5; --coverage 2 blends it in.\n\n"
            "Examples:\n"
            "  flowvid edit --bank waterfall.bank.exr --flowlines edit.svg --frame-count 250 --out edit/%06d.png\n"
            "  flowvid edit --bank waterfall.bank.exr --flowlines new-channel.svg --carry-background --coverage 2 \\\n"
            "      --frame-count 250 --out channel.mp4\n"
            "  flowvid edit --bank smoke.bank.exr --flowlines wind.flowlines.json --mapping scaled --frames 1:100 \\\n"
            "      --out smoke.mp4 --dense-out dense.flowlines.json");
        add_common(app, *options);
        app.add_option("--flowlines", options->flowlines, "input and output lines (SVG or *.flowlines.json)")->required();
        add_edit_options(app, options->edit);
        app.add_option("--dense-out", options->dense_out, "write the dense output lines with their inputs (*.flowlines.json)")
            ->check(file_name_ending({".json"}, "flow lines as JSON", "dense.flowlines.json"));
        return [options](const GlobalOptions& global) { return render(*options, global, true); };
    }}};

}  // namespace
}  // namespace flowvid::cli
