#pragma once
// Measured quality of flow-based video, and the two baselines it is compared
// with (issue 6, "Measured quality"):
//
// - Seam: the largest frame-to-frame difference of an output, relative to the
//   clip's 95th-percentile frame-to-frame difference, and the share of output
//   transitions above the clip's 99th percentile (a naive loop spikes once per
//   period).
// - Pulsing: temporal variation (coefficient of variation) of per-frame
//   high-frequency energy; cross-fading makes detail pulse.
// - Fidelity: RMS distance from output patches to their nearest clip patch
//   (same neighbourhood, any frame), against the clip's own self-distance
//   (its patches to their nearest patch at least exclude_frames away), and
//   the ratio of output to clip high-frequency power (blur lowers it).
//
// All on luma of display values in [0, 1], inside a mask (the band around
// the flow lines, where every method shows moving texture).
//
// Baselines: (a) looping the clip; (b) the flow-map method games use: one
// texture advected by a velocity field in two layers half a cycle apart,
// cross-faded with triangle weights so each layer is reset while invisible.

#include "flowvid/progress.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/synthesis.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::flow {

// 1 where a pixel lies within half_width_px of one of the polylines.
std::vector<std::uint8_t> line_band_mask(const std::vector<std::vector<Eigen::Vector2d>>& lines, int width, int height,
                                         double half_width_px);

// Per-frame statistics in the mask.
struct SequenceStats {
    std::vector<double> transitions;  // mean |luma(t+1) - luma(t)|, one per consecutive pair
    std::vector<double> hf_energy;    // mean squared difference from the 3x3 box mean, per frame
};
SequenceStats sequence_stats(const std::vector<std::vector<float>>& luma_frames, int width, int height,
                             const std::vector<std::uint8_t>& mask);

// How much of the clip's fine detail a synthesis keeps where the flow is:
// the mean HF energy (as SequenceStats) of `sample_frames` output frames
// spread over one period, over the mean HF energy of all the frames of
// `footage` (the clip as filmed), in the pixels within `region_px` of `lines`
// (the drawn input lines; 20 px, as the flow region of the shared scoring
// tool). 1 = as detailed as the footage; a still median plate of mist or
// spray that the particles do not cover gives much less.
double detail_kept(const Synthesizer& synth, const ClipFrames& footage, const std::vector<std::vector<Eigen::Vector2d>>& lines,
                   int sample_frames = 8, double region_px = 20.0);

// The default background of plain synthesis (`--background auto`): the
// median plate, unless the synthesis over it keeps less than `min_detail` of
// the clip's detail in the flow region (detail_kept; mist, spray or drifting
// light that the particles do not cover turn to a smooth blur in a median);
// then the clip replayed in step with the particles, which shows real frames
// there. min_detail 0.8: the lower end of what the footage's own frames span.
struct BackgroundChoice {
    BackgroundMode mode = BackgroundMode::median;
    double median_detail = 1.0;  // detail_kept over the median plate
};
// `clip`: the frames synthesis uses (stabilised); `footage`: as filmed.
BackgroundChoice choose_background(const std::shared_ptr<const ParticleStreams>& streams,
                                   const std::shared_ptr<const ClipFrames>& clip, const ClipFrames& footage,
                                   const SynthesisSettings& settings, const std::vector<std::vector<Eigen::Vector2d>>& lines,
                                   double min_detail = 0.8);

struct QualitySettings {
    int patch_px = 16;           // fidelity patches
    int queries = 120;           // patches sampled per sequence
    int search_radius_px = 6;    // nearest-patch search around the same place
    int search_stride_px = 2;
    int exclude_frames = 5;      // self-distance ignores frames closer than this
    std::uint64_t seed = 7;
};

struct QualityReport {
    double clip_p95 = 0.0;               // clip transitions, 95th and 99th percentiles
    double clip_p99 = 0.0;
    double clip_max = 0.0;
    // The clip's own transitions against its p95: its largest (the clip's
    // own "seam max") and its smallest. An output whose largest transition
    // is below clip_min_ratio changes less, at every frame, than the
    // footage ever does.
    double clip_max_ratio = 0.0;
    double clip_min_ratio = 0.0;
    double max_transition_ratio = 0.0;   // largest output transition / clip_p95
    double share_above_p99 = 0.0;        // of output transitions above clip_p99
    double pulsing = 0.0;                // coefficient of variation of output HF energy
    double clip_pulsing = 0.0;
    double patch_distance = 0.0;         // output patches to their nearest clip patch (RMS luma)
    double clip_self_distance = 0.0;
    double hf_power_ratio = 0.0;         // mean output HF energy / mean clip HF energy
    // Complementary measures (not the issue's; they say what the do not):
    // seam_spike: largest output transition / the output's own median
    // transition, i.e. how much a seam stands out from the motion around it
    // (clip_seam_spike: the clip's own). A sequence that barely moves (a still
    // frame slid along, as the flow map does) scores well on the seam ratio
    // above without looking like the clip; motion_ratio shows that: the
    // output's median transition / the clip's (1 = moves like the clip).
    double seam_spike = 0.0;
    double clip_seam_spike = 0.0;
    double motion_ratio = 0.0;
    int transitions = 0;
};

// Compares an output sequence with its clip (both luma, same size).
QualityReport measure_quality(const std::vector<std::vector<float>>& clip_luma,
                              const std::vector<std::vector<float>>& output_luma, int width, int height,
                              const std::vector<std::uint8_t>& mask, const QualitySettings& settings = {});

// ---- the whole flow region (issue #30) -------------------------------------------------
//
// What a viewer sees of the flow: every pixel within 20 px of the drawn lines
// (the input lines for synthesis; an edit's output lines, at each output
// frame for lines that move), measured as ../shared/tools/baselines_flow.py
// measures it, on luma:
//   seam     whole-frame mean |g(t+1) - g(t)|; the largest output transition
//            and the share above the clip's 99th percentile
//   pulse    per-frame variance of the 3x3 Laplacian in the region: its
//            coefficient of variation, and the largest share of its variation
//            in one period of 4..50 frames (a periodic pulse: near 1)
//   detail   mean Laplacian variance, output / clip
//   patch    24 x 24 output patches (centre in the region) to their nearest clip
//            patch anywhere in the clip's region (stride 6, any frame); RMS grey
//            levels, over the clip's own leave-one-frame-out distance
//   motion   median region transition, output / clip (1 = changes as the clip)
// The clip's region is the drawn input lines'; an edited region is compared
// with it, since that is where the clip's flow is.

struct RegionSettings {
    double region_px = 20.0;
    int patch_px = 24;
    int query_stride_px = 12;   // output patches on this grid ...
    int query_frames = 20;      // ... in this many output frames, evenly spread
    int max_queries = 240;      // at most (drawn evenly from the grid)
    int search_stride_px = 6;   // clip patches on this grid
    int max_search_frames = 0;  // clip frames searched (evenly spread); 0: every frame, as the tool searches
    std::uint64_t seed = 7;
};

struct RegionQuality {
    double seam_max_ratio = 0.0;       // largest output transition / clip p99 (whole frame)
    double share_above_p99 = 0.0;
    double clip_seam_max_ratio = 0.0;  // the clip's own largest / its p99
    double clip_share_above_p99 = 0.0;
    double pulse_cv = 0.0;
    double clip_pulse_cv = 0.0;
    double pulse_peak = 0.0;
    double clip_pulse_peak = 0.0;
    double detail = 0.0;
    double patch_rms = 0.0;            // grey levels (0..255)
    double clip_patch_rms = 0.0;       // leave-one-frame-out
    double patch_fidelity = 0.0;       // patch_rms / clip_patch_rms
    double motion = 0.0;
    std::size_t clip_region_pixels = 0;
    double output_region_pixels = 0.0; // mean over frames
};

// The clip's side of the measures, computed once (its transitions, its
// Laplacian energy, the patch database and its leave-one-frame-out distance),
// then any number of outputs measured against it.
class RegionMeter {
public:
    // Luma in [0, 1]; `clip_region`: within region_px of the drawn input lines.
    RegionMeter(const std::vector<std::vector<float>>& clip_luma, int width, int height,
                std::vector<std::uint8_t> clip_region, const RegionSettings& settings = {});
    ~RegionMeter();
    RegionMeter(const RegionMeter&) = delete;
    RegionMeter& operator=(const RegionMeter&) = delete;
    // `output_regions`: one mask per output frame, or one for all.
    // `leave_own_frame_out`: the output is the clip's own frames (output
    // frame t is clip frame t, e.g. the footage stabilised into another
    // view), and each query leaves its frame's patches out of the search,
    // as the clip's own reference does: what leaving the scene as filmed
    // scores over the output's region. At most as many frames as the clip.
    RegionQuality measure(const std::vector<std::vector<float>>& output_luma,
                          const std::vector<std::vector<std::uint8_t>>& output_regions,
                          bool leave_own_frame_out = false) const;

private:
    struct Clip;
    std::unique_ptr<Clip> m_clip;
};

// One output measured against its clip (a RegionMeter used once).
RegionQuality measure_region_quality(const std::vector<std::vector<float>>& clip_luma,
                                     const std::vector<std::vector<float>>& output_luma, int width, int height,
                                     const std::vector<std::uint8_t>& clip_region,
                                     const std::vector<std::vector<std::uint8_t>>& output_regions,
                                     const RegionSettings& settings = {});

// The clip's detail over `region` as a share of its detail over
// `clip_region` (mean over the clip's frames of the Laplacian variance, as
// `detail` above). With `region` the pixels particles carry (within half a
// patch of the stretches the tracker followed), it is the detail an output
// covered by moved texture keeps on average: more shows the scene between
// and under the texture (rock edges and splash do not move with the flow).
double clip_detail_share(const std::vector<std::vector<float>>& clip_luma, int width, int height,
                         const std::vector<std::uint8_t>& region, const std::vector<std::uint8_t>& clip_region);

// The share of a series' variation (around its mean) in its strongest DFT bin
// with a period of min_period..max_period samples (0 for fewer than 8 samples).
double periodic_peak_share(const std::vector<double>& series, double min_period = 4.0, double max_period = 50.0);

// ---- baselines ----------------------------------------------------------------------

// (a) Output frame t (1-based) = clip frame (t - 1) mod count, linear RGB.
RgbImage naive_loop_frame(const ClipFrames& clip, int frame);

// A velocity field (px per frame) and how much each pixel is covered by it,
// from the particles' mean speeds along the input lines, spread by a
// Gaussian of sigma_px around the lines.
struct VelocityField {
    int width = 0;
    int height = 0;
    std::vector<Eigen::Vector2f> velocity;
    std::vector<float> coverage;  // 0..1
};
VelocityField velocity_field(const ParticleStreams& streams, int width, int height, double sigma_px);

// (b) The flow-map method.
class FlowMapBaseline {
public:
    // `texture` (linear) is advected; `background` (linear) shows where the
    // field does not reach. cycle_frames: a layer's life before it is reset.
    FlowMapBaseline(VelocityField field, RgbImage texture, RgbImage background, int cycle_frames = 32);
    RgbImage render(int frame) const;  // 1-based output frame, linear RGB; thread-safe

private:
    VelocityField m_field;
    RgbImage m_texture;
    RgbImage m_background;
    int m_cycle = 32;
};

// ---- our synthesis against both baselines on one clip ---------------------------------

struct ComparisonSettings {
    int output_frames = 0;            // frames of output measured; 0 = twice the clip
    double band_half_width_px = 0.0;  // mask: within this of the tracked lines; 0 = a quarter patch
    int flow_map_cycle_frames = 32;
    int threads = 0;                  // rendering threads (0 = hardware)
    QualitySettings quality;
    // When given (the drawn input lines), every method is also measured over
    // the whole flow region (measure_region_quality).
    std::vector<std::vector<Eigen::Vector2d>> region_lines;
    RegionSettings region;
    // The clip as filmed, when `clip` was stabilised: the region measures
    // compare with it, as the shared scoring tool compares with the footage,
    // and again with `clip` (MethodQuality::region_still_view). Null: `clip`
    // is the footage.
    const ClipFrames* footage = nullptr;
    // region_lines where they were drawn, in the footage's pixels (the view
    // moved them; stabilise.hpp polylines_as_drawn). Empty: region_lines.
    std::vector<std::vector<Eigen::Vector2d>> footage_region_lines;
};

struct MethodQuality {
    std::string method;  // "ours", "loop", "flow map"
    QualityReport report;
    SequenceStats series;  // per frame, in the mask: where a seam or a pulse happens
    std::optional<RegionQuality> region;             // against the footage as filmed
    std::optional<RegionQuality> region_still_view;  // against the stabilised clip (a drifting camera only)
};

struct Comparison {
    int output_frames = 0;
    std::size_t mask_pixels = 0;
    std::vector<MethodQuality> methods;  // ours, loop, flow map
    SequenceStats clip_series;
};

// Renders `output_frames` of `synth` (frames 1..N), of the naive loop of
// `clip` and of the flow-map baseline (the clip's first frame advected by the
// tracked speeds, over `plate`), and measures each against the clip in the
// band around the tracked lines of `streams`. `progress` gets the fraction
// done and may return false to stop (the comparison then throws
// flowvid::Cancelled).
Comparison compare_with_baselines(const ClipFrames& clip, const ParticleStreams& streams, const Synthesizer& synth,
                                  const RgbImage& plate, const ComparisonSettings& settings = {},
                                  const Progress& progress = {});

}  // namespace flowvid::flow
