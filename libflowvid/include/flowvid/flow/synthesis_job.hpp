#pragma once
// The synthesis pipeline in one place: from a particle bank, its clip and a
// flow-line drawing to a ready Synthesizer, for plain infinite synthesis and
// for edits alike. `flowvid synth`, `flowvid edit` and `flowvid quality` all
// go through prepare_synthesis, so what quality measures is what synth and
// edit render.
//
// Steps: read the bank and the drawing; read the clip, stabilised into its
// central view when the camera drifts, the drawing carried into that view
// (stabilise.hpp); schedule the
// particles; for an edit, plan the dense output lines (editing.hpp); choose
// the background (`auto`: quality.hpp choose_background); for the moving
// layer, keep the light the flow adds (synthesis.hpp keep_moving_part).

#include "flowvid/flow/editing.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"
#include "flowvid/progress.hpp"

#include <nlohmann/json_fwd.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::flow {

struct SynthesisJob {
    std::string bank_path;       // particle bank (.exr) written by flowvid track
    std::string clip_path;       // capture folder, video or image pattern; empty: the clip the bank records
    std::string flowlines_path;  // the drawing; empty: the capture's
    // auto (whole textures: the median plate unless, under plain synthesis,
    // it blurs the flow region; then replay. The moving layer: the median
    // plate), median, loop, replay, relit or none.
    std::string background = "auto";
    SynthesisSettings settings;  // texture layer, arc mapping, carried background, blending
    // An edit of whole textures carries the background `auto` chose (the
    // replayed clip, or the median plate) under lines moved off the flow
    // (settings.carry_background): a new channel then shows the water around
    // its input line where its particles leave gaps, and fades into the
    // scene over the carried band, instead of showing the scene it was drawn
    // over through scalloped patch borders. Not for the moving layer
    // (flames: the scene stays where it is). false: settings.carry_background
    // alone decides.
    bool carry_background_auto = true;
    // An edit of whole textures fades the texture layer's edge over a patch
    // (settings.edge_fade_px = the bank's patch size): where a line moved
    // off the flow ends over the scene, the new water fades into it as the
    // filmed edge does. Plain synthesis puts patches over the flow they were
    // cut from and the moving layer is screened, so neither fades. false:
    // settings.edge_fade_px alone decides.
    bool edge_fade_auto = true;
    // Chosen from the bank when true (settings.texture_layer and
    // coverage_weight are then ignored): an edit of a non-stationary bank
    // (flames, smoke) moves only the light the flow adds (TextureLayer::moving;
    // whole patches would carry the scene behind the flames along the new
    // lines); everything else renders whole textures. An edit's texture fades
    // out with the patches' feather (coverage weight 2): it lies where the clip
    // had none, and a border that reaches full cover within a few pixels
    // stands as a hard edge (the waterfall's new channel) or opaque discs (a
    // lone flame). Plain synthesis puts patches back where they were cut, at
    // coverage 0.5.
    bool texture_auto = false;
    bool coverage_auto = false;
    bool edit = false;           // render the drawing's output lines instead of its input lines
    bool interpolate = true;     // edit: dense lines between the drawn ones (eq. 3.1); false: drawn lines only
    EditSettings edit_settings;  // its mapping is taken from `settings`
    bool keep_clip = false;      // keep the clip's frames in the result (for measuring against them)
};

struct PreparedSynthesis {
    std::shared_ptr<formats::ParticleBank> bank;
    std::optional<formats::Capture> capture;  // none when the background is `none` and the clip was not needed
    std::string flowlines_path;
    formats::FlowLineSet drawing;  // in the clip's (stabilised) view: drawing_in_view of the file's
    std::vector<std::vector<Eigen::Vector2d>> input_points;  // the bank's lines, in order
    std::shared_ptr<ParticleStreams> streams;
    std::shared_ptr<const ClipFrames> clip;  // the frames synthesis used (stabilised); kept with keep_clip
    // The clip as filmed, kept with keep_clip when the camera drifted (the
    // measures compare with the footage, as the shared scoring tool does);
    // null when `clip` is the footage itself.
    std::shared_ptr<const ClipFrames> footage;
    std::optional<CameraMotion> camera;      // when the clip was read
    BackgroundMode background = BackgroundMode::median;
    double median_detail = -1.0;             // auto: detail kept over the median plate (choose_background); -1 otherwise
    SynthesisSettings settings;              // what renders: the job's, with texture, coverage and carrying decided
    std::optional<EditPlan> plan;            // edit with interpolation
    std::vector<OutputLine> outputs;         // edit: what renders (dense or drawn lines)
    std::unique_ptr<Synthesizer> synthesizer;

    // What renders at output frame `frame`: the drawn input lines for plain
    // synthesis, the drawn output lines of an edit (keyed lines at that frame).
    std::vector<std::vector<Eigen::Vector2d>> drawn_lines_at(int frame) const;
};

// Reports the stages "read clip" and "correspondence" (an edit's plan) and
// logs the camera, the background chosen and warnings through `progress`.
// Throws flowvid::UsageError when something the user must name is missing
// (the clip, the drawing), ValidationError for inputs that do not fit
// together (the clip's size is not the bank's, no output lines to edit),
// the readers' errors for bad files, and flowvid::Cancelled.
PreparedSynthesis prepare_synthesis(const SynthesisJob& job, const Progress& progress = {});

// What prepare_synthesis reads from the job's files, for callers that hold
// it in memory already (the benchmarks' synthetic scenes, a host that made
// its own bank): the job then gives only the settings, background and edit
// fields; its paths are not read.
struct SynthesisSources {
    std::shared_ptr<formats::ParticleBank> bank;  // the moving layer keeps only the light the flow adds, in place
    formats::FlowLineSet drawing;                 // input lines named as the bank's; output lines for an edit, in the clip's view
    std::string drawing_name;                     // names the drawing in messages (its file, when it has one)
    // The clip's frames in the bank's pixels (stabilised when the camera
    // drifts). Needed unless the background is none with whole textures.
    std::shared_ptr<const ClipFrames> clip;
    ClipFrames footage;                        // as filmed, when `clip` was resampled (auto background, keep_clip); empty: clip
    std::optional<formats::Capture> capture;   // informative
    std::optional<CameraMotion> camera;        // informative
};

// The same pipeline from inputs in memory. Throws as the file version does,
// with a UsageError when the job needs a clip the sources lack.
PreparedSynthesis prepare_synthesis(SynthesisSources sources, const SynthesisJob& job, const Progress& progress = {});

// Where and which frames `render_synthesis` writes.
struct SynthesisOutput {
    std::string path;  // FrameWriter target: out/%06d.png (.exr, .tif), a folder, a video (.mp4, .avi), one image
    int first_frame = 1;  // 1-based, inclusive, of the infinite sequence (any range: frame A is
    int last_frame = 1;   // the same whichever range renders it)
    bool loop = false;    // instead of the range: exactly one period, frames 1..period (a file that loops)
    int threads = 0;      // frames rendered at once (flowvid/threads.hpp)
    std::string dense_lines_path;  // edit with interpolation: also write its dense lines (*.flowlines.json, as drawn)
};

struct SynthesisOutcome {
    int first_frame = 1;  // the range rendered (for `loop`, 1..period)
    int last_frame = 0;
    int frames_written = 0;  // fewer than the range when cancelled
    bool complete() const { return frames_written == last_frame - first_frame + 1; }
    Schedule schedule;  // the particles' timing (period, K, window, wrap join)
    BackgroundMode background = BackgroundMode::median;
    double median_detail = -1.0;  // background auto: detail kept over the median plate
    SynthesisSettings settings;   // as rendered: texture, coverage, carried background decided
    std::optional<CameraMotion> camera;
    std::optional<EditPlan> plan;  // edit with interpolation: the dense lines and their inputs
};

// The whole synthesis pipeline: prepare_synthesis, then frames into a
// FrameWriter, each reported as stage "render" (with the frame number as its
// message). Cancelling while frames render stops there: image sequences keep
// the frames written (each written atomically), a video is discarded so no
// partial file stands under its name, and the outcome says how many were
// written. Cancelling before throws flowvid::Cancelled. Throws what
// prepare_synthesis throws and IoError for an output that cannot be written,
// before any long work where the name alone decides.
SynthesisOutcome render_synthesis(const SynthesisJob& job, const SynthesisOutput& output, const Progress& progress = {});

// How an edit looks against its clip (`flowvid quality --edit`): frames
// 1..frames (0: twice the clip) rendered from a PreparedSynthesis prepared
// with keep_clip, measured over the output lines' region (within region_px
// of them, at every frame for keyed lines) against the clip's own over its
// drawn input lines (quality.hpp RegionMeter), the clip as filmed. When the
// camera drifted, also against the clip seen from the output's still view.
// Progress: stage "measure"; cancelling throws flowvid::Cancelled.
struct EditQuality {
    RegionQuality region;                          // against the footage as filmed
    std::optional<RegionQuality> region_still_view;  // against the stabilised clip (drifting camera only)
    int output_frames = 0;
    bool moving_lines = false;  // keyed output lines: the region follows them
    // The clip's detail within half a patch of the stretches the tracker
    // followed, over its flow region's (clip_detail_share, as filmed): what
    // an edit covered by moved texture keeps on average.
    double tracked_texture_detail = 0.0;
    // The footage itself (stabilised into the output's view when the camera
    // drifts) measured like `region`, over the edit's region, each frame's
    // patches searched without its own frame: what an edit that left the
    // scene as filmed scores there. A still output of a drifting clip
    // cannot score far below its patch fidelity (docs/flow.md).
    RegionQuality footage_over_region;
};
EditQuality measure_edit(const PreparedSynthesis& prepared, int frames, double region_px, int threads,
                         const Progress& progress = {});

// What a render did, as `flowvid synth --json` and `flowvid edit --json`
// print it (and the Python module returns it): output, frames, the window,
// the background, texture and coverage chosen, and for an edit its mapping,
// carried background and dense lines.
nlohmann::json outcome_summary(const SynthesisOutcome& outcome, const SynthesisJob& job, const SynthesisOutput& output);
// The window's wrap join: {"wrap_join_error": x or null, "longest_window":
// {...} when a shorter window than the longest was taken}.
nlohmann::json window_summary(const Schedule& schedule);

}  // namespace flowvid::flow
