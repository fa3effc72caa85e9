#pragma once
// The synthesis pipeline in one place: from a particle bank, its clip and a
// flow-line drawing to a ready Synthesizer, for plain infinite synthesis and
// for edits alike. `flowvid synth`, `flowvid edit` and `flowvid quality` all
// go through prepare_synthesis, so what quality measures is what synth and
// edit render.
//
// Steps: read the bank and the drawing; read the clip, stabilised into its
// first frame's view when the camera drifts (stabilise.hpp); schedule the
// particles; for an edit, plan the dense output lines (editing.hpp); choose
// the background (`auto`: quality.hpp choose_background); for the moving
// layer, keep the light the flow adds (synthesis.hpp keep_moving_part).

#include "flowvid/flow/editing.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <functional>
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
    // An edit whose background `auto` chose to replay the clip carries it
    // under lines moved off the flow (settings.carry_background): a new
    // channel then shows the moving water around its input line where its
    // particles leave gaps, not the still scene it was drawn over. false:
    // settings.carry_background alone decides.
    bool carry_replayed_background = true;
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

// Progress of the long steps: stage ("read clip", "correspondence") and the
// fraction of it done; returning false cancels (prepare_synthesis then throws
// SynthesisCancelled).
using SynthesisProgress = std::function<bool(const std::string& stage, double fraction)>;
// Lines for the user's log: the camera, the background chosen, warnings ("warning: ...").
using SynthesisLog = std::function<void(const std::string& line)>;

struct SynthesisCancelled : std::runtime_error {
    SynthesisCancelled() : std::runtime_error("cancelled") {}
};

struct PreparedSynthesis {
    std::shared_ptr<formats::ParticleBank> bank;
    std::optional<formats::Capture> capture;  // none when the background is `none` and the clip was not needed
    std::string flowlines_path;
    formats::FlowLineSet drawing;
    std::vector<std::vector<Eigen::Vector2d>> input_points;  // the bank's lines, in order
    std::shared_ptr<ParticleStreams> streams;
    std::shared_ptr<const ClipFrames> clip;  // the frames synthesis used (stabilised); kept with keep_clip
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

// Throws flowvid::UsageError when something the user must name is missing
// (the clip, the drawing), ValidationError for inputs that do not fit
// together (the clip's size is not the bank's, no output lines to edit),
// the readers' errors for bad files, and SynthesisCancelled.
PreparedSynthesis prepare_synthesis(const SynthesisJob& job, const SynthesisProgress& progress = {},
                                    const SynthesisLog& log = {});

}  // namespace flowvid::flow
