#pragma once
// Seamless infinite synthesis from a particle texture bank (thesis 3.2,
// fig. 3.5) and rendering along edited output lines (3.3, fig. 3.16/3.17).
//
// Diagonal order. On every line a particle enters at the line's start every
// `step` output frames (step = the bank's start spacing). The m-th particle to
// enter (at output frame 1 + m * step) replays input particle k = m mod K of a
// chosen window of K consecutive input particles (start frames s0, s0 + step,
// ..., the shaded diagonals of fig. 3.5a), from its first frame to its last:
// every particle completes its path. At output frame t a particle of age a
// shows its texture and position of input frame s_k + a; neighbours on a line,
// and particles of different lines, then come from the same input frame, so
// their textures agree where patches overlap, except along one "ladder" step
// per line where k wraps from K-1 to 0, which moves with the flow.
// The sequence is defined for every output frame number and repeats with
// period K * step: frame t is the same whichever range it is rendered in.
//
// Rendering. Each particle's patch is feathered (raised-cosine weights that
// vanish at the patch border) and put back on the whole pixels it was cut
// from (flow/sampling.hpp, patch_origin): plain synthesis copies clip pixels
// without resampling blur. Particles fade in and out over a few frames at the
// ends of their life.
// Colour = sum(w * rgb) / sum(w) with premultiplied alpha, where patches of
// different input frames meet sharpened towards the heavier
// (SynthesisSettings::overlap_sharpness); the background shows through where
// the accumulated weight sum(w) is below `coverage_weight` (smoothstep).
// On an output line other than the input line, every pixel near the line is
// mapped to the input frame through the tangent frames: pixel q projects to
// arc s_out and lateral offset n on the output line; s_in = s_out (equal arc
// length) or s_out * L_in / L_out (scaled, fig. 3.17); the texture is read at
// P_in(s_in) + n N_in(s_in) from the particles near s_in.
// With TextureLayer::moving, patches hold only the light the flow adds to the
// clip's still plate where they were cut (keep_moving_part) and are screened
// over the background: bg + coverage * r * (1 - bg), r = sum(w * residual) / sum(w).
// A frame is rendered in bands of rows through a small ring of rows (the
// band, plus the rows the detail-preserving local mean reaches): every patch
// is added to each band it crosses in the same order as a whole-frame pass,
// so the result is that of the whole-frame pass, with cache-sized buffers
// reused from frame to frame.

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/geometry.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace flowvid::flow {

enum class ArcMapping { equal, scaled };
const char* to_string(ArcMapping mapping);
ArcMapping arc_mapping_from_string(const std::string& text);  // "equal" | "scaled"; std::invalid_argument otherwise
// s_in = s_out * scale: 1 for equal arc length, L_in / L_out for scaled.
double arc_mapping_scale(ArcMapping mapping, double length_in, double length_out);

// What a particle's patch carries onto the output.
enum class TextureLayer {
    whole,   // everything in the patch: the water, and the rock it passes
    moving,  // the light the flow adds to the clip's still plate, screened over the background
};
// The moving layer's still plate is the clip's dark plate: per pixel, this
// quantile over the clip (the scene with the least light of flames on it;
// the median would keep their glow, and every moment with less flame than
// that would show as a dark hole wherever an edit moves it).
inline constexpr double kMovingLayerStillQuantile = 0.1;
// Screening (bg + r * (1 - bg), r = (pixel - still) / (1 - still)) gives back
// the clip's own pixel over its still plate and never passes white over a
// brighter background (adding would: an edited flame over the glowing base
// clipped to white and lilac). Still values are capped here: a white still
// pixel leaves nothing to screen.
inline constexpr float kMovingLayerMaxStill = 0.95f;
const char* to_string(TextureLayer layer);
TextureLayer texture_layer_from_string(const std::string& text);  // "whole" | "moving"; std::invalid_argument otherwise

struct SynthesisSettings {
    // K per line; 0 = as many as every line has in one common window, or up
    // to 15 % fewer where such a window's wrap joins clearly better
    // (Schedule::wrap_join_error).
    int particles = 0;
    int first_start_frame = -1;  // s0, the input start frame of particle 0; -1 = from the seed
    // 0 = the window whose wrap joins best (the earliest when none is clearly
    // better); else a seeded window among the longest that fit.
    std::uint64_t seed = 0;
    ArcMapping mapping = ArcMapping::equal;
    double coverage_weight = 0.5;  // accumulated feather weight at which texture fully hides the background
    // Particles fade in over this many frames after entering a line and out
    // before leaving it; -1 = automatic (the entry spacing, 1 to 3 frames).
    // Without it the particle entering where the diagonal order wraps pops.
    int fade_frames = -1;
    // The first particle of each repetition of the window (k = 0, where the
    // diagonal order wraps) shows other input frames than the particles it
    // meets, on every line at once: it fades in over this many frames, so
    // that the change is spread instead of stepping; -1 = automatic (the
    // entry spacing, at most half the particle's life).
    int wrap_fade_frames = -1;
    // A slot of the window whose start frame has no complete particle on a
    // line borrows the particle of the nearest start if that starts at most
    // this many frames away. The borrowed particle shows its own texture, from
    // input frames that far off its neighbours', all its life: where texture
    // persists as it flows (water), that is another piece of the flow over
    // theirs and their overlap ghosts, even 3 frames off. Otherwise the slot
    // is left empty: its neighbours on the line (which show the same input
    // frame) and the neighbouring lines cover it, unless they are too far
    // apart and the background shows through. 0 (default) = always empty; a
    // large value = always borrow.
    int borrow_within_frames = 0;
    // Where patches showing different input frames overlap (the wrap of the
    // diagonal order, borrowed slots), their weighted mean loses fine detail
    // in proportion to how evenly they mix, and the loss comes and goes with
    // the wraps: detail pulses. Detail-preserving blending keeps the local
    // mean (a 5 x 5 normalised box mean of the blend) and rescales the detail
    // around it by sum(W) / sqrt(sum(W_g^2)) over the groups g of patches
    // showing one input frame (Heitz and Neyret's variance-preserving blend
    // for uncorrelated detail, applied only across groups: copies of the same
    // input frame are identical and blend exactly as before).
    bool preserve_detail = true;
    // Where patches showing different input frames overlap, each group's
    // weight W_g is raised to this power before they are mixed (colour =
    // sum W_g^p C_g / sum W_g^p; coverage unchanged). 1 mixes them in
    // proportion to their weights, so two unlike frames show at once, each
    // faintly (a double exposure: on the fire's wrap, bright flame at a tenth
    // of its weight over the dark pot reads as grey-green smears). Larger
    // values let the heavier group show, with a soft seam where the weights
    // are close. The detail gain above then follows the powered weights.
    double overlap_sharpness = 4.0;
    // Along an output line other than its input line (edits), first show the
    // background found around the input line (the whole drawn line, smoothed
    // over half a patch), carried through the same tangent-frame mapping as
    // the particles and feathered across the line like a patch, then the
    // particles over it. Where the input line's particles leave gaps
    // (segments nothing crossed within the clip, empty slots), a new line then
    // shows the flow's look instead of the output's own background. Nothing
    // is carried onto the flow's own region (near an input line or between
    // neighbouring ones), whose background already is the flow's, nor over
    // BackgroundMode::none. Off by default: it also carries whatever the input
    // line crosses (a rock ledge), and a fire's plate is the scene without
    // flames.
    bool carry_background = false;
    // TextureLayer::moving: patches are screened over the background instead
    // of covering it. For flames and smoke in front of a still scene: an edit
    // that bends the lines moves the flames, not the pot's edge behind them
    // (a whole patch cut beside the pot carries its edge along, and the dark
    // pot of moments without flame). The bank's textures must hold the
    // moving part (keep_moving_part), and the background must be still: the
    // plate they were taken from (moving_layer_still_plate) or none (a layer
    // to screen over a render). Over the clip looped or replayed the flames
    // would show twice. Unedited lines over that plate render as with
    // `whole`, except where the clip is darker than it.
    TextureLayer texture_layer = TextureLayer::whole;
    // The texture layer's coverage falls to 0 at the layer's edge over this
    // many pixels (0: off; detail::fade_layer_edges): a new channel of water
    // ends the way the filmed fall's own edge does, fading into the rock
    // over about a patch (the cascade's right edge: 24 px), instead of where
    // its patches' summed weight runs out (about 8 px, flat water beside
    // crisp rock, an edge the clip never shows). Gaps inside the layer fade
    // the same way. SynthesisJob turns it on for edits of whole textures.
    double edge_fade_px = 0.0;
    // Testing: render with the straightforward whole-frame accumulation
    // (several full-size buffers per frame) instead of the banded renderer,
    // which reproduces it to float rounding. Slower; same frames.
    bool reference_rendering = false;
};

// The diagonal order (fig. 3.5b) of one line.
struct LineSchedule {
    std::string line_id;
    std::vector<int> particles;  // K indices into bank.particles, in order k = 0..K-1; -1 = empty slot
    // How many of the K had no complete particle of their start frame, and
    // how many of those borrow the nearest start's
    // (SynthesisSettings::borrow_within_frames; the rest are left empty).
    int substituted = 0;
    int borrowed = 0;
    int max_life = 0;            // frames
};

struct Schedule {
    int particles_per_line = 0;  // K
    int start_every = 1;         // step, output frames between two entries on a line
    int first_start_frame = 0;   // s0
    int period_frames = 0;       // K * step: frame t + period equals frame t
    // How well the wrap joins (the ladder step of fig. 3.5b): RMS difference
    // of linear luma between what the window's first particle shows and what
    // the input showed at the same place a period later, where the old
    // particles it meets come from. NaN where the clip has no such frames.
    double wrap_join_error = std::numeric_limits<double>::quiet_NaN();
    // When a shorter window was taken because its wrap joins clearly better:
    // the longest window's K, s0 and join error (particles_per_line 0: not).
    struct Window {
        int particles_per_line = 0;
        int first_start_frame = 0;
        double wrap_join_error = std::numeric_limits<double>::quiet_NaN();
    } longest_window;
    std::vector<LineSchedule> lines;  // bank lines with particles, bank order
    std::vector<std::string> warnings;
};

// The first three ids, and ", ..." when there are more: warnings summarise
// lines (a densified bank or a particle system has hundreds).
std::string some_line_ids(const std::vector<std::string>& ids);

// Chooses the K-particle window for every line of the bank. Throws
// std::invalid_argument when no line has a particle.
Schedule make_schedule(const formats::ParticleBank& bank, const SynthesisSettings& settings);

// The background `mode` asks for, from the clip: the median plate, the clip
// looped, or replayed in step with `schedule` (the frame the particles show;
// after the wrap, the particles still on the lines from before it show the
// frames after the window until they leave, and the Synthesizer shows those
// around them too; elsewhere the background dissolves to the window's first
// frames over the entry spacing, as the new particles fade in); relit: the
// median plate darkened as that frame is, light measured over half a patch
// (`patch_size_px`, the bank's); none: black.
Background make_background(BackgroundMode mode, std::shared_ptr<const ClipFrames> clip, const Schedule& schedule,
                           int patch_size_px);

// The still plate of the moving layer: quantile_plate at kMovingLayerStillQuantile.
RgbImage moving_layer_still_plate(const ClipFrames& clip);

// Keeps only the light the flow adds in every particle's texture: each
// texel's excess over the still plate (linear, the clip's size) at the pixel
// it was cut from, as a screen residual (kMovingLayerMaxStill); textures are
// premultiplied. `input_points` as for ParticleStreams (one polyline per
// bank line). For TextureLayer::moving.
// The window (make_schedule weighs textures) and an edit's correspondence
// are best chosen before, on whole textures: both layers then keep one
// timing. ParticleStreams keeps nothing computed from textures.
void keep_moving_part(formats::ParticleBank& bank, const std::vector<std::vector<Eigen::Vector2d>>& input_points,
                      const RgbImage& linear_still_plate);

// The particles on a scheduled line at output frame `frame` (1-based, any
// integer): bank particle index and age, in entry order (youngest first).
struct ScheduledParticle {
    int particle = 0;
    int age = 0;
    int slot = 0;  // k, its place in the window
};
std::vector<ScheduledParticle> scheduled_particles(const Schedule& schedule, const formats::ParticleBank& bank,
                                                   std::size_t line, int frame);

// The particles of every input line, ready to render: the bank, the input
// geometry, the schedule and the feather weights.
class ParticleStreams {
public:
    // `input_points[i]` is the polyline of bank.lines[i]. `drawing`, when
    // given, supplies the full lengths of lines tracked in segments (else the
    // end of their last tracked segment).
    ParticleStreams(std::shared_ptr<const formats::ParticleBank> bank,
                    std::vector<std::vector<Eigen::Vector2d>> input_points, const SynthesisSettings& settings,
                    const formats::FlowLineSet* drawing = nullptr);
    // The polylines from the drawing the bank was tracked with (input_line_points).
    static std::vector<std::vector<Eigen::Vector2d>> input_points_from_drawing(const formats::ParticleBank& bank,
                                                                              const formats::FlowLineSet& drawing,
                                                                              const std::string& drawing_file);

    const formats::ParticleBank& bank() const { return *m_bank; }
    const Schedule& schedule() const { return m_schedule; }
    int patch_size() const { return m_bank->patch_size_px; }
    // Index into schedule().lines of a bank line id, or -1 (no particle or unknown).
    int stream_index(const std::string& line_id) const;
    const LineGeometry& geometry(int stream) const { return m_geometry[static_cast<std::size_t>(stream)]; }

    // Input lines as the artist drew them (or as interpolated between drawn
    // ones): a line tracked in segments ("in-3[0.0:36.0]", ...) groups them.
    // Output lines name these in `from`.
    struct InputLine {
        struct Segment {
            int stream = 0;
            double from_px = 0.0;  // arc range of the segment on the line
            double to_px = 0.0;
        };
        std::string id;
        double length_px = 0.0;
        std::vector<Segment> segments;  // by arc
        std::vector<Eigen::Vector2d> points;  // the whole line as drawn; empty without the drawing
    };
    const std::vector<InputLine>& input_lines() const { return m_inputs; }
    int input_line_index(const std::string& id) const;

    struct Visible {
        float arc_px = 0.0f;       // along the input line
        Eigen::Vector2d centre;    // input-frame pixel position
        const float* texture = nullptr;  // patch x patch x 4, linear premultiplied RGBA
        float weight = 1.0f;             // fade in after entering, out before leaving
        int input_frame = 0;             // clip frame the texture was cut from (start + age)
    };
    // The particles of a stream at an output frame, sorted by arc length.
    void visible(int stream, int frame, std::vector<Visible>& out) const;
    // Colour (linear RGB) and feather weight of one stream rendered alone
    // along an output line of length `output_length_px`, at points given in
    // that line's frame: arc length s_out and lateral offset n (pixels).
    // The editing correspondence samples patch overlaps with this.
    struct Samples {
        std::vector<float> rgb;     // 3 per point
        std::vector<float> weight;  // 1 per point (0 = not covered)
    };
    void sample(int stream, int frame, ArcMapping mapping, double output_length_px, const std::vector<float>& s_out,
                const std::vector<float>& n, Samples& out) const;
    // The same for a whole input line (its segments each where they lie).
    void sample_input_line(int input_line, int frame, ArcMapping mapping, double output_length_px,
                           const std::vector<float>& s_out, const std::vector<float>& n, Samples& out) const;

    // For sampling the same points at many frames (the editing
    // correspondence): the input-frame positions, computed once...
    struct SamplePoints {
        std::vector<int> stream;    // per point: the stream holding it, -1 = off the line
        std::vector<float> s;       // arc length on that stream
        std::vector<float> qx, qy;  // input-frame pixel position
    };
    SamplePoints prepare_samples(int input_line, ArcMapping mapping, double output_length_px,
                                 const std::vector<float>& s_out, const std::vector<float>& n) const;
    // ...every stream's particles at a frame, computed once...
    struct FrameParticles {
        int frame = 0;
        std::vector<std::vector<Visible>> streams;  // per stream, sorted by arc
        std::vector<std::vector<float>> arcs;       // their arc lengths
    };
    FrameParticles frame_particles(int frame) const;
    // ...and the colours.
    void sample(const SamplePoints& points, const FrameParticles& particles, Samples& out) const;

private:
    std::shared_ptr<const formats::ParticleBank> m_bank;
    Schedule m_schedule;
    std::vector<LineGeometry> m_geometry;  // per schedule line
    std::vector<InputLine> m_inputs;
    // Ids to indices: banks and drawings may hold many lines, and every output
    // line looks its input up.
    std::unordered_map<std::string, int> m_stream_by_id;  // into m_schedule.lines
    std::unordered_map<std::string, int> m_input_by_id;   // into m_inputs
    int m_fade_frames = 2;
    int m_wrap_fade_frames = -1;
};

// One line of the output and the input line whose particles it carries.
struct OutputLine {
    formats::FlowLine line;  // fixed points or keys (output frames, 1-based)
    std::string from;        // an input line (ParticleStreams::input_lines) or a bank line id
};

class Synthesizer {
public:
    // `outputs` empty: every scheduled input line renders itself (plain
    // infinite synthesis). An output line carrying an input line tracked in
    // segments is cut into the matching parts (equal or scaled arc length),
    // each carrying one segment. Output lines whose `from` has no particles
    // are skipped with a warning.
    Synthesizer(std::shared_ptr<const ParticleStreams> streams, std::vector<OutputLine> outputs, Background background,
                const SynthesisSettings& settings);
    ~Synthesizer();

    int width() const;
    int height() const;
    const ParticleStreams& streams() const { return *m_streams; }
    int period_frames() const { return m_streams->schedule().period_frames; }
    const std::vector<std::string>& warnings() const { return m_warnings; }

    // Output frame `frame` (1-based; any integer), linear RGB. Thread-safe.
    RgbImage render(int frame) const;
    // The same, also returning how much each pixel is covered by texture (0..1).
    RgbImage render(int frame, std::vector<float>* coverage) const;

    // Renders frames first..last on `threads` threads (0 = hardware), each
    // frame on one thread, and hands them to `sink` in order (on the calling
    // thread); `sink` returns false to stop. Returns the number of frames
    // delivered. The frames do not depend on the thread count.
    int render_frames(int first, int last, int threads, const std::function<bool(int, const RgbImage&)>& sink) const;

    // Colour and weight at image `points` of the line `output_points`
    // rendered alone with the particles of bank line `from` at `frame`.
    ParticleStreams::Samples sample_line(const std::vector<Eigen::Vector2d>& output_points, const std::string& from,
                                         int frame, const std::vector<Eigen::Vector2d>& points) const;

private:
    struct Plan;
    struct Scratch;  // a rendering thread's working buffers, reused from frame to frame
    struct CarryBuffers;
    void render_into(int frame, RgbImage& out, std::vector<float>* coverage, Scratch& scratch) const;
    // The frame's background; a replayed one follows the ladder, from the
    // particles visible on the lines it follows (gathered while rendering).
    void fill_background(int frame, const std::vector<ParticleStreams::Visible>& on_followed_lines, RgbImage& out) const;
    // Composites the background carried along warped output lines over `out`
    // (the frame's background), before the particles.
    void carry_background_into(int frame, RgbImage& out, CarryBuffers& buffers) const;
    RgbImage render_reference(int frame, std::vector<float>* coverage) const;
    std::shared_ptr<const ParticleStreams> m_streams;
    std::unique_ptr<Plan> m_plan;
    Background m_background;
    bool m_carry_background = false;  // resolved SynthesisSettings::carry_background
    SynthesisSettings m_settings;
    std::vector<std::string> m_warnings;
};

}  // namespace flowvid::flow
