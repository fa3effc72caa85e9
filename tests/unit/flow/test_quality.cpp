// The quality measures (seam, pulsing, fidelity) on sequences whose answer is
// known, and the two baselines they compare against.

#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/flow/tracking.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

constexpr int kW = 64, kH = 48;

std::vector<float> noise_frame(double shift, std::uint64_t seed, double feature = 4.0) {
    std::vector<float> g(static_cast<std::size_t>(kW) * kH);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) g[static_cast<std::size_t>(y) * kW + x] = value_noise(x / feature, (y - shift) / feature, seed);
    return g;
}

std::vector<float> box_blur(const std::vector<float>& g) {
    std::vector<float> out = g;
    for (int y = 1; y + 1 < kH; ++y)
        for (int x = 1; x + 1 < kW; ++x) {
            float sum = 0.0f;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) sum += g[static_cast<std::size_t>(y + dy) * kW + x + dx];
            out[static_cast<std::size_t>(y) * kW + x] = sum / 9.0f;
        }
    return out;
}

std::vector<std::uint8_t> everywhere() { return std::vector<std::uint8_t>(static_cast<std::size_t>(kW) * kH, 1); }

// A vertical band of fine texture falling 3 px per frame through a 96 x 96 frame, 48 frames.
SyntheticFlowSpec falling_band_spec() {
    SyntheticFlowSpec spec;
    spec.width = 96;
    spec.height = 96;
    spec.frames = 48;
    spec.curve = {{48.0, -8.0}, {48.0, 104.0}};
    spec.band_px = 6.0;
    spec.speed_px_per_frame = [](double) { return 3.0; };
    spec.feature_px = 3.0;
    return spec;
}

// The falling band tracked, over still rock (a fine still texture the
// median plate keeps) or over mist (texture that changes every frame, which
// the median blurs).
struct TrackedBand {
    formats::FlowLine line;
    std::shared_ptr<formats::ParticleBank> bank;
    std::shared_ptr<ClipFrames> clip;
};
TrackedBand tracked_band(bool mist) {
    const SyntheticFlowSpec spec = falling_band_spec();
    const SyntheticFlow flow(spec);
    TrackedBand band;
    band.line.id = "in-1";
    band.line.points = spec.curve;
    std::vector<RgbImage> display;
    for (int t = 0; t < spec.frames; ++t) {
        RgbImage frame = flow.frame(t);
        if (mist)
            for (int y = 0; y < spec.height; ++y)
                for (int x = 0; x < spec.width; ++x)
                    if (std::abs(x - 48) > 9)
                        for (int c = 0; c < 3; ++c)
                            frame.pixel(x, y)[c] = 0.3f + 0.4f * value_noise(x / 2.0, y / 2.0, 100 + static_cast<std::uint64_t>(t));
        display.push_back(frame);
    }
    MemoryFrames frames(display, spec.fps);
    TrackingSettings tracking;
    tracking.patch_size_px = 16;
    tracking.start_every = 2;
    tracking.max_path_frames = -1;
    band.bank = std::make_shared<formats::ParticleBank>(track_particles(frames, {band.line}, tracking).bank);
    band.clip = std::make_shared<ClipFrames>(ClipFrames::read_all(frames));
    return band;
}

}  // namespace

TEST(FlowQuality, NaiveLoopSpikesOncePerPeriod) {
    // A texture sliding 1 px per frame for 30 frames, looped 3 times.
    std::vector<std::vector<float>> clip, looped;
    for (int t = 0; t < 30; ++t) clip.push_back(noise_frame(t, 1));
    for (int t = 0; t < 90; ++t) looped.push_back(clip[static_cast<std::size_t>(t % 30)]);
    QualitySettings settings;
    settings.search_radius_px = 2;  // a pure translation would otherwise match itself a few frames later
    const QualityReport q = measure_quality(clip, looped, kW, kH, everywhere(), settings);
    EXPECT_GT(q.max_transition_ratio, 3.0);
    // Above the clip's 99th percentile: the two wraps, and the clip's own
    // largest transition once per repetition.
    EXPECT_NEAR(q.share_above_p99, 5.0 / 89.0, 1e-9);
    const SequenceStats stats = sequence_stats(looped, kW, kH, everywhere());
    int jumps = 0;
    for (double d : stats.transitions) jumps += d > 2.0 * q.clip_max ? 1 : 0;
    EXPECT_EQ(jumps, 2);
    EXPECT_NEAR(q.patch_distance, 0.0, 1e-9);            // every output patch is a clip patch
    EXPECT_NEAR(q.hf_power_ratio, 1.0, 1e-9);
    EXPECT_GT(q.clip_self_distance, 0.0);
}

TEST(FlowQuality, CrossFadingPulsesAndBlurLowersHighFrequencyPower) {
    std::vector<std::vector<float>> clip, faded, blurred;
    for (int t = 0; t < 40; ++t) clip.push_back(noise_frame(t, 2));
    // Two layers half a cycle apart, cross-faded: detail halves at mid-fade.
    for (int t = 0; t < 40; ++t) {
        const double phase = (t % 16) / 16.0;
        const float w = static_cast<float>(1.0 - std::fabs(2.0 * phase - 1.0));
        const std::vector<float> a = noise_frame(t % 16, 3), b = noise_frame((t + 8) % 16, 4);
        std::vector<float> mix(a.size());
        for (std::size_t i = 0; i < a.size(); ++i) mix[i] = w * a[i] + (1.0f - w) * b[i];
        faded.push_back(mix);
        blurred.push_back(box_blur(clip[static_cast<std::size_t>(t)]));
    }
    const QualityReport fade = measure_quality(clip, faded, kW, kH, everywhere());
    const QualityReport blur = measure_quality(clip, blurred, kW, kH, everywhere());
    std::printf("pulsing: clip %.3f, cross-fade %.3f; blur hf ratio %.3f\n", fade.clip_pulsing, fade.pulsing, blur.hf_power_ratio);
    EXPECT_GT(fade.pulsing, 3.0 * fade.clip_pulsing);
    EXPECT_LT(blur.hf_power_ratio, 0.5);
    EXPECT_GT(blur.patch_distance, 0.0);
}

TEST(FlowQuality, TheClipsOwnTransitionsBoundTheSeamOfAnOutputThatMovesLikeIt) {
    // Flat frames whose brightness steps by 0.01, 0.02, ..., 0.20: the clip's
    // transitions are known exactly (p95 by linear interpolation: 0.1905).
    std::vector<std::vector<float>> clip;
    float level = 0.0f;
    const std::size_t pixels = static_cast<std::size_t>(kW) * kH;
    clip.emplace_back(pixels, 0.5f);
    for (int step = 1; step <= 20; ++step) {
        level += (step % 2 ? 1.0f : -1.0f) * 0.01f * static_cast<float>(step);  // stays within 0.5 +- 0.1
        clip.emplace_back(pixels, 0.5f + level);
    }
    const QualityReport same = measure_quality(clip, clip, kW, kH, everywhere());
    EXPECT_NEAR(same.clip_p95, 0.1905, 1e-6);
    EXPECT_NEAR(same.clip_max_ratio, 0.20 / 0.1905, 1e-5);
    EXPECT_NEAR(same.clip_min_ratio, 0.01 / 0.1905, 1e-5);
    // Replaying the clip scores the clip's own seam max.
    EXPECT_NEAR(same.max_transition_ratio, same.clip_max_ratio, 1e-9);
}

TEST(FlowQuality, BandMaskAndStats) {
    const auto mask = line_band_mask({{{10.0, 0.0}, {10.0, 47.0}}}, kW, kH, 3.0);
    int inside = 0;
    for (auto m : mask) inside += m;
    EXPECT_EQ(inside, 7 * 48);
    const SequenceStats stats = sequence_stats({noise_frame(0, 5), noise_frame(0, 5)}, kW, kH, mask);
    ASSERT_EQ(stats.transitions.size(), 1u);
    EXPECT_EQ(stats.transitions[0], 0.0);
    EXPECT_EQ(stats.hf_energy.size(), 2u);
}

TEST(FlowQuality, FlowMapBaselineAdvectsAndCrossFades) {
    VelocityField field;
    field.width = kW;
    field.height = kH;
    field.velocity.assign(static_cast<std::size_t>(kW) * kH, Eigen::Vector2f(0.0f, 1.0f));
    field.coverage.assign(field.velocity.size(), 1.0f);
    RgbImage texture(kW, kH);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            for (int c = 0; c < 3; ++c) texture.pixel(x, y)[c] = static_cast<float>(y) / kH;  // a vertical ramp
    const FlowMapBaseline baseline(field, texture, RgbImage(kW, kH), 16);
    // Frame 1: layer 0 at phase 0 (weight 0), layer 1 at phase 1/2 (offset 8 px, weight 1).
    const RgbImage first = baseline.render(1);
    EXPECT_NEAR(first.pixel(20, 30)[0], (30.0f - 8.0f) / kH, 1e-5f);
    // Frame 5: layer 0 offset 4 (weight 1/2), layer 1 offset 12 (weight 1/2).
    EXPECT_NEAR(baseline.render(5).pixel(20, 30)[0], 0.5f * (26.0f + 18.0f) / kH, 1e-5f);
    EXPECT_EQ(baseline.render(3).rgb, baseline.render(3 + 16).rgb);  // periodic
}

// --background auto (issue #30): a narrow stream tracked with 16 px patches
// leaves the rest of the 20 px flow region to the background. Beside it a
// still, textured rock keeps its detail in the median plate (the plate stays
// the default); mist that is new in every frame turns to a smooth median,
// the output over it keeps little of the clip's detail, and the clip is
// replayed instead.
TEST(FlowQuality, TheDefaultBackgroundReplaysTheClipWhereTheMedianPlateBlursIt) {
    const auto choose = [](bool mist) {
        const TrackedBand band = tracked_band(mist);
        SynthesisSettings settings;
        auto streams = std::make_shared<ParticleStreams>(band.bank, std::vector<std::vector<Eigen::Vector2d>>{band.line.points},
                                                         settings);
        return choose_background(streams, band.clip, *band.clip, settings, {band.line.points});
    };
    const BackgroundChoice rock = choose(false), mist = choose(true);
    EXPECT_EQ(rock.mode, BackgroundMode::median) << rock.median_detail;
    EXPECT_GT(rock.median_detail, 0.9);
    EXPECT_EQ(mist.mode, BackgroundMode::replay) << mist.median_detail;
    EXPECT_LT(mist.median_detail, 0.6);
}

TEST(FlowQuality, AnEditOfWholeTexturesCarriesTheBackgroundAutoChose) {
    // A new line 24 px left of the band. Over the median plate (rock) as
    // over the replayed clip (mist), whole textures carry the background
    // from around the input line, so the new flow does not show the scene
    // through scalloped patch borders; the moving layer (flames) and
    // --no-carry-background do not.
    for (const bool mist : {false, true}) {
        const TrackedBand band = tracked_band(mist);
        const auto prepare = [&](bool carry_auto, TextureLayer texture) {
            SynthesisSources sources;
            sources.bank = std::make_shared<formats::ParticleBank>(*band.bank);
            sources.drawing.width = sources.drawing.height = 96;
            sources.drawing.inputs = {band.line};
            formats::FlowLine moved;
            moved.id = "out-1";
            moved.from = "in-1";
            moved.points = {{24.0, -8.0}, {24.0, 104.0}};
            sources.drawing.outputs = {moved};
            sources.drawing_name = "memory";
            sources.clip = band.clip;
            SynthesisJob job;
            job.edit = true;
            job.interpolate = false;
            job.carry_background_auto = carry_auto;
            job.texture_auto = false;
            job.settings.texture_layer = texture;
            return prepare_synthesis(std::move(sources), job);
        };
        const PreparedSynthesis whole = prepare(true, TextureLayer::whole);
        EXPECT_EQ(whole.background, mist ? BackgroundMode::replay : BackgroundMode::median);
        EXPECT_TRUE(whole.settings.carry_background) << (mist ? "mist" : "rock");
        EXPECT_FALSE(prepare(false, TextureLayer::whole).settings.carry_background) << (mist ? "mist" : "rock");
        if (!mist) EXPECT_FALSE(prepare(true, TextureLayer::moving).settings.carry_background);
    }
}

// ---- the whole flow region ---------------------------------------------------------

TEST(FlowRegionQuality, APeriodicSeriesPutsItsPowerInOneBin) {
    std::vector<double> sine, steps;
    for (int t = 0; t < 120; ++t) {
        sine.push_back(3.0 + std::sin(2.0 * M_PI * t / 10.0));  // period 10: in the 4..50 band
        steps.push_back(t < 60 ? 1.0 : 2.0);                    // one step: its power is spread, mostly at long periods
    }
    EXPECT_NEAR(periodic_peak_share(sine), 1.0, 1e-9);
    EXPECT_LT(periodic_peak_share(steps), 0.1);
    EXPECT_EQ(periodic_peak_share({1.0, 2.0, 3.0}), 0.0);  // too short to say
}

namespace {

// Columns 16-47 of every row: the region the noise clips below are measured over.
std::vector<std::uint8_t> middle_band() {
    std::vector<std::uint8_t> band(static_cast<std::size_t>(kW) * kH, 0);
    for (int y = 0; y < kH; ++y)
        for (int x = 16; x < 48; ++x) band[static_cast<std::size_t>(y) * kW + x] = 1;
    return band;
}

// 12 px patches on fine grids, for frames this small.
RegionSettings small_patch_settings() {
    RegionSettings settings;
    settings.patch_px = 12;
    settings.query_stride_px = 6;
    settings.search_stride_px = 2;
    return settings;
}

}  // namespace

TEST(FlowRegionQuality, TheClipAgainstItselfAndABlurOfIt) {
    // A texture sliding 1 px per frame: replayed, every measure is the clip's own;
    // blurred, it keeps less detail and its patches are no longer the clip's.
    std::vector<std::vector<float>> clip, replayed, blurred;
    for (int t = 0; t < 30; ++t) clip.push_back(noise_frame(t, 5, 3.0));
    for (int t = 0; t < 30; ++t) {
        replayed.push_back(clip[static_cast<std::size_t>(t)]);
        blurred.push_back(box_blur(clip[static_cast<std::size_t>(t)]));
    }
    const std::vector<std::uint8_t> band = middle_band();
    const RegionSettings settings = small_patch_settings();
    const RegionMeter meter(clip, kW, kH, band, settings);
    const RegionQuality same = meter.measure(replayed, {band});
    EXPECT_NEAR(same.detail, 1.0, 1e-12);
    EXPECT_NEAR(same.motion, 1.0, 1e-12);
    EXPECT_NEAR(same.seam_max_ratio, same.clip_seam_max_ratio, 1e-12);
    EXPECT_NEAR(same.share_above_p99, same.clip_share_above_p99, 1e-12);
    EXPECT_NEAR(same.pulse_cv, same.clip_pulse_cv, 1e-12);
    EXPECT_NEAR(same.patch_rms, 0.0, 1e-6);  // every patch is in the clip (no frame left out)
    EXPECT_GT(same.clip_patch_rms, 0.1);     // leaving a frame out, the odd shifts are off the clip's patch grid
    EXPECT_EQ(same.clip_region_pixels, static_cast<std::size_t>(32 * kH));

    const RegionQuality blur = meter.measure(blurred, {band});
    EXPECT_LT(blur.detail, 0.5);
    EXPECT_GT(blur.patch_rms, 1.0);

    // Nothing changes in a still clip: the motion ratio is not defined and reported as 0.
    const RegionMeter still_meter({clip[0], clip[0]}, kW, kH, band, settings);
    EXPECT_EQ(still_meter.measure(replayed, {band}).motion, 0.0);
}

TEST(FlowRegionQuality, TheClipMeasuredWithoutItsOwnFramesScoresItsOwnReference) {
    // The clip's own frames as the output, each searched without its own
    // frame: the same queries as the clip's leave-one-frame-out reference,
    // so patch fidelity is exactly 1 (and 0 when the own frame is searched).
    std::vector<std::vector<float>> clip;
    for (int t = 0; t < 30; ++t) clip.push_back(noise_frame(t, 5, 3.0));
    const std::vector<std::uint8_t> band = middle_band();
    const RegionSettings settings = small_patch_settings();
    const RegionMeter meter(clip, kW, kH, band, settings);
    const RegionQuality without_own = meter.measure(clip, {band}, true);
    EXPECT_GT(without_own.clip_patch_rms, 0.1);
    EXPECT_NEAR(without_own.patch_rms, without_own.clip_patch_rms, 1e-9);
    EXPECT_NEAR(without_own.patch_fidelity, 1.0, 1e-9);
    EXPECT_NEAR(without_own.detail, 1.0, 1e-12);
    EXPECT_NEAR(meter.measure(clip, {band}).patch_rms, 0.0, 1e-6);
    // A frame the clip does not have cannot leave its own out.
    std::vector<std::vector<float>> longer = clip;
    longer.push_back(clip.front());
    EXPECT_THROW(meter.measure(longer, {band}, true), std::invalid_argument);
}

TEST(FlowRegionQuality, AMovingRegionIsMeasuredWhereItIsAtEachFrame) {
    // Output frames that are flat grey except for the clip's texture inside a
    // band that moves 2 px per frame: measured in that moving band, they keep
    // all the detail; measured in a fixed band, part of it is flat.
    std::vector<std::vector<float>> clip, output;
    std::vector<std::vector<std::uint8_t>> moving;
    const std::size_t pixels = static_cast<std::size_t>(kW) * kH;
    std::vector<std::uint8_t> fixed(pixels, 0);
    for (int y = 0; y < kH; ++y)
        for (int x = 8; x < 24; ++x) fixed[static_cast<std::size_t>(y) * kW + x] = 1;
    for (int t = 0; t < 12; ++t) clip.push_back(noise_frame(t, 6, 3.0));
    for (int t = 0; t < 12; ++t) {
        std::vector<float> frame(pixels, 0.5f);
        std::vector<std::uint8_t> region(pixels, 0);
        for (int y = 0; y < kH; ++y)
            for (int x = 8 + 2 * t - 1; x < 24 + 2 * t + 1; ++x) {  // texture one pixel wider than the region
                const std::size_t i = static_cast<std::size_t>(y) * kW + x;
                frame[i] = clip[static_cast<std::size_t>(t)][i];
                if (x >= 8 + 2 * t && x < 24 + 2 * t) region[i] = 1;
            }
        output.push_back(frame);
        moving.push_back(region);
    }
    RegionSettings settings;
    settings.patch_px = 8;
    settings.query_stride_px = 4;
    settings.search_stride_px = 2;
    const RegionQuality followed = measure_region_quality(clip, output, kW, kH, fixed, moving, settings);
    const RegionQuality still = measure_region_quality(clip, output, kW, kH, fixed, {fixed}, settings);
    EXPECT_NEAR(followed.output_region_pixels, 16.0 * kH, 1e-9);
    EXPECT_GT(followed.detail, 0.8);
    EXPECT_LT(still.detail, 0.6 * followed.detail);
    EXPECT_THROW(measure_region_quality(clip, output, kW, kH, fixed, {fixed, fixed}, settings), std::invalid_argument);
}

// The whole-region measures compare with the footage as filmed (as the shared
// scoring tool does) when the clip synthesis used was stabilised, and with the
// stabilised clip beside it: replaying the stabilised clip is the clip itself
// in the still view, and 1-3 px off the shaking footage as filmed.
TEST(FlowRegionQuality, ComparesWithTheFootageAsFilmedAndTheStillViewBeside) {
    const SyntheticFlowSpec spec = falling_band_spec();
    const SyntheticFlow flow(spec);
    std::vector<RgbImage> steady, filmed;
    for (int t = 0; t < spec.frames; ++t) {
        const RgbImage frame = flow.frame(t);
        // The camera 1 px to the side, 3 px in the odd frames: odd shifts,
        // off the even search grid of the patches.
        RgbImage moved = frame;
        for (int y = 0; y < spec.height; ++y)
            for (int x = 0; x < spec.width; ++x)
                for (int c = 0; c < 3; ++c) moved.pixel(x, y)[c] = frame.pixel(std::max(0, x - 1 - 2 * (t % 2)), y)[c];
        steady.push_back(frame);
        filmed.push_back(moved);
    }
    MemoryFrames steady_frames(steady, spec.fps), filmed_frames(filmed, spec.fps);
    formats::FlowLine line;
    line.id = "in-1";
    line.points = spec.curve;
    TrackingSettings tracking;
    tracking.patch_size_px = 16;
    tracking.start_every = 2;
    tracking.max_path_frames = -1;
    auto bank = std::make_shared<formats::ParticleBank>(track_particles(steady_frames, {line}, tracking).bank);
    auto clip = std::make_shared<const ClipFrames>(ClipFrames::read_all(steady_frames));
    const ClipFrames footage = ClipFrames::read_all(filmed_frames);
    SynthesisSettings settings;
    formats::FlowLineSet drawing;
    drawing.width = spec.width;
    drawing.height = spec.height;
    drawing.inputs = {line};
    auto streams = std::make_shared<ParticleStreams>(bank, ParticleStreams::input_points_from_drawing(*bank, drawing, "drawing"),
                                                     settings);
    const Synthesizer synth(streams, {}, Background::looped(clip), settings);

    ComparisonSettings compare;
    compare.output_frames = 48;
    compare.threads = 1;
    compare.region_lines = {line.points};
    compare.region.patch_px = 12;
    compare.region.query_stride_px = 6;
    compare.region.search_stride_px = 2;
    const RgbImage plate = median_plate(*clip);
    const Comparison only_clip = compare_with_baselines(*clip, *streams, synth, plate, compare);
    compare.footage = &footage;
    const Comparison both = compare_with_baselines(*clip, *streams, synth, plate, compare);

    ASSERT_EQ(both.methods.size(), 3u);
    const MethodQuality& loop = both.methods[1];
    ASSERT_EQ(loop.method, "loop");
    ASSERT_TRUE(loop.region && loop.region_still_view);
    EXPECT_FALSE(only_clip.methods[1].region_still_view);
    // The still view is the comparison made without footage, to the bit.
    EXPECT_EQ(loop.region_still_view->patch_rms, only_clip.methods[1].region->patch_rms);
    EXPECT_EQ(both.methods[0].region_still_view->detail, only_clip.methods[0].region->detail);
    EXPECT_NEAR(loop.region_still_view->patch_rms, 0.0, 1e-6);  // every replayed patch is a clip patch
    EXPECT_GT(loop.region->patch_rms, 1.0);                      // the footage's frames are 1 or 3 px off
    // The footage's camera jumps 2 px every frame: its transitions (and p99) are larger.
    EXPECT_GT(loop.region->clip_seam_max_ratio, 0.0);
    EXPECT_LT(loop.region->seam_max_ratio, loop.region_still_view->seam_max_ratio);
    const ClipFrames wrong_size(10, 10, 25.0, "small");
    compare.footage = &wrong_size;
    EXPECT_THROW(compare_with_baselines(*clip, *streams, synth, plate, compare), std::invalid_argument);
}

TEST(FlowRegionQuality, TheClipsDetailOverPartOfItsRegionIsTheLaplacianVarianceRatio) {
    // White noise of standard deviation a left of x = 32 and b right of it:
    // the 4-neighbour Laplacian of independent pixels has variance 20 s^2,
    // so the left half holds 2 a^2 / (a^2 + b^2) of the whole frame's mean
    // (0.4 for a = 0.02, b = 0.04; the column where they meet mixes a little).
    std::mt19937 rng(11);
    std::normal_distribution<float> unit(0.0f, 1.0f);
    const double a = 0.02, b = 0.04;
    std::vector<std::vector<float>> clip(4, std::vector<float>(static_cast<std::size_t>(kW) * kH));
    for (auto& frame : clip)
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x)
                frame[static_cast<std::size_t>(y) * kW + x] = 0.5f + static_cast<float>(x < 32 ? a : b) * unit(rng);
    std::vector<std::uint8_t> left(static_cast<std::size_t>(kW) * kH, 0), all(left.size(), 1);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < 32; ++x) left[static_cast<std::size_t>(y) * kW + x] = 1;
    const double share = clip_detail_share(clip, kW, kH, left, all);
    EXPECT_NEAR(share, 2.0 * a * a / (a * a + b * b), 0.03);
    EXPECT_NEAR(clip_detail_share(clip, kW, kH, all, all), 1.0, 1e-12);
    EXPECT_THROW(clip_detail_share(clip, kW, kH, std::vector<std::uint8_t>(10, 1), all), std::invalid_argument);
}
