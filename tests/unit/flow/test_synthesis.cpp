// Synthesis from a particle bank: the diagonal order of thesis fig. 3.5 (every
// particle completes its path), periodicity and range independence, exact
// reproduction of the clip where all particles come from one input frame,
// and no seam above the clip's own frame-to-frame difference on a perfectly
// stationary flow.

#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/sampling.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/flow/tracking.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

// A bank with one straight vertical line and particles entering at frames
// 0..count-1, each living `life` frames; texel colour = (start, age) / 100.
std::shared_ptr<formats::ParticleBank> toy_bank(int count, int life, int patch = 4, int step = 1) {
    auto bank = std::make_shared<formats::ParticleBank>();
    bank->patch_size_px = patch;
    bank->clip_width_px = 64;
    bank->clip_height_px = 96;
    bank->clip_frame_count = (count - 1) * step + life;
    bank->lines.push_back({"in-1", 90.0f});
    for (int p = 0; p < count; ++p) {
        formats::TrackedParticle particle;
        particle.line_id = "in-1";
        particle.start_frame = p * step;
        for (int a = 0; a < life; ++a) {
            particle.arc_length_px.push_back(static_cast<float>(a * 80.0 / (life - 1)));
            for (int t = 0; t < patch * patch; ++t) {
                particle.texture_rgba.push_back(static_cast<float>(particle.start_frame) / 100.0f);
                particle.texture_rgba.push_back(static_cast<float>(a) / 100.0f);
                particle.texture_rgba.push_back(0.5f);
                particle.texture_rgba.push_back(1.0f);
            }
        }
        bank->particles.push_back(std::move(particle));
    }
    return bank;
}

std::vector<std::vector<Eigen::Vector2d>> toy_line() { return {{{32.0, 5.0}, {32.0, 95.0}}}; }

}  // namespace

TEST(FlowSynthesis, DiagonalOrderReplaysWholePathsOfTheFirstKParticles) {
    auto bank = toy_bank(10, 4);
    SynthesisSettings settings;
    settings.particles = 5;
    const Schedule schedule = make_schedule(*bank, settings);
    ASSERT_EQ(schedule.particles_per_line, 5);
    EXPECT_EQ(schedule.start_every, 1);
    EXPECT_EQ(schedule.first_start_frame, 0);
    EXPECT_EQ(schedule.period_frames, 5);
    // Fig. 3.5b: at output frame t the particle of age a is input particle
    // (t - 1 - a) mod K, showing input frame s_k + a.
    std::map<std::pair<int, int>, int> seen_age;  // (entry frame, particle) -> last age
    for (int t = 1; t <= 30; ++t) {
        const std::vector<ScheduledParticle> on_line = scheduled_particles(schedule, *bank, 0, t);
        ASSERT_EQ(on_line.size(), 4u) << "frame " << t;  // ages 0..3: one particle per age, a full diagonal
        for (const ScheduledParticle& sp : on_line) {
            const int k = ((t - 1 - sp.age) % 5 + 5) % 5;
            EXPECT_EQ(sp.particle, k);
            EXPECT_EQ(bank->particles[static_cast<std::size_t>(sp.particle)].start_frame, k);
            // Each entering particle shows every age 0..life-1 in consecutive frames.
            const int entry = t - sp.age;
            auto it = seen_age.find({entry, sp.particle});
            if (it != seen_age.end()) {
                EXPECT_EQ(it->second + 1, sp.age);
            } else if (entry >= 1) {
                EXPECT_EQ(sp.age, 0);
            }
            seen_age[{entry, sp.particle}] = sp.age;
        }
    }
    // Entries after frame 1 all reached age 3 (completed) if they entered early enough.
    for (const auto& [key, age] : seen_age)
        if (key.first >= 1 && key.first <= 27) {
            EXPECT_EQ(age, 3) << "entry " << key.first;
        }
}

TEST(FlowSynthesis, WindowAvoidsMissingParticlesAndReportsSubstitutes) {
    auto bank = toy_bank(12, 4);
    // Lose the particles of start frames 1 and 2 (as if tracking lost them).
    bank->particles.erase(bank->particles.begin() + 1, bank->particles.begin() + 3);
    const Schedule automatic = make_schedule(*bank, SynthesisSettings{});
    // Slots 3..11 are complete (9 particles); a window including 1 and 2
    // would borrow 2 of 11 slots (18 % < 25 %), so K = 12 is taken.
    EXPECT_EQ(automatic.particles_per_line, 12);
    EXPECT_EQ(automatic.lines[0].substituted, 2);
    ASSERT_FALSE(automatic.warnings.empty());
    SynthesisSettings six;
    six.particles = 6;
    const Schedule window = make_schedule(*bank, six);
    EXPECT_EQ(window.lines[0].substituted, 0);
    EXPECT_GE(window.first_start_frame, 3);
}

TEST(FlowSynthesis, FramesRepeatWithThePeriodAndDoNotDependOnTheRange) {
    auto bank = toy_bank(10, 4, 4);
    SynthesisSettings settings;
    settings.particles = 6;
    auto streams = std::make_shared<ParticleStreams>(bank, toy_line(), settings);
    const Synthesizer synth(streams, {}, Background(), settings);
    ASSERT_EQ(synth.period_frames(), 6);
    const RgbImage a = synth.render(7);
    EXPECT_EQ(a.rgb, synth.render(7 + 6).rgb);
    EXPECT_EQ(a.rgb, synth.render(7 + 600).rgb);
    EXPECT_NE(a.rgb, synth.render(8).rgb);
    std::map<int, std::vector<float>> first, second;
    synth.render_frames(1, 10, 2, [&](int f, const RgbImage& image) {
        first[f] = image.rgb;
        return true;
    });
    synth.render_frames(5, 12, 1, [&](int f, const RgbImage& image) {
        second[f] = image.rgb;
        return true;
    });
    for (int f = 5; f <= 10; ++f) EXPECT_EQ(first[f], second[f]) << "frame " << f;
}

TEST(FlowSynthesis, FeatherWeightsVanishAtPatchBorders) {
    for (int n : {4, 24, 25}) {
        EXPECT_FLOAT_EQ(feather_weight(-0.5f, n), 0.0f);
        EXPECT_FLOAT_EQ(feather_weight(n - 0.5f, n), 0.0f);
        EXPECT_LT(feather_weight(0.0f, n), 0.15f);
        EXPECT_NEAR(feather_weight((n - 1) / 2.0f, n), 1.0f, 1e-3f);
        for (int i = 0; i < n; ++i) EXPECT_NEAR(feather_weight(static_cast<float>(i), n), feather_weight(static_cast<float>(n - 1 - i), n), 1e-6f);
    }
    // Half a patch apart, raised cosines sum to one: overlapping particles
    // blend without brightening or darkening.
    for (float u = 0.0f; u < 12.0f; u += 0.5f) EXPECT_NEAR(feather_weight(u, 24) + feather_weight(u + 12.0f, 24), 1.0f, 1e-5f);
    EXPECT_EQ(patch_origin(10.0, 4), 9);    // pixels 9..12, centre 10.5 (a tie with 8..11 goes up)
    EXPECT_EQ(patch_origin(10.4, 24), -1);  // 10.4 - 11.5 = -1.1 -> -1
}

namespace {

struct StationaryFlowFixture {
    SyntheticFlow truth;
    formats::FlowLine line;
    std::shared_ptr<formats::ParticleBank> bank;
    std::shared_ptr<ClipFrames> clip;

    StationaryFlowFixture()
        : truth([] {
              SyntheticFlowSpec spec;
              spec.width = 96;
              spec.height = 112;
              spec.frames = 72;
              spec.curve = {{48.0, -8.0}, {48.0, 120.0}};
              spec.band_px = 48.0;
              spec.speed_px_per_frame = [](double) { return 4.0; };
              spec.feature_px = 10.0;  // consecutive frames alike, so that a jump shows
              spec.seed = 3;
              return spec;
          }()) {
        line.id = "in-1";
        line.points = truth.spec().curve;
        MemoryFrames frames = truth.clip();
        TrackingSettings settings;
        settings.start_every = 2;
        settings.max_path_frames = -1;
        bank = std::make_shared<formats::ParticleBank>(track_particles(frames, {line}, settings).bank);
        clip = std::make_shared<ClipFrames>(ClipFrames::read_all(frames));
    }
};

const StationaryFlowFixture& stationary() {
    static const StationaryFlowFixture fixture;
    return fixture;
}

}  // namespace

TEST(FlowSynthesis, ReproducesTheClipWhereEveryParticleShowsOneInputFrame) {
    const StationaryFlowFixture& f = stationary();
    SynthesisSettings settings;
    settings.fade_frames = 0;
    auto streams = std::make_shared<ParticleStreams>(f.bank, std::vector<std::vector<Eigen::Vector2d>>{f.line.points}, settings);
    const Synthesizer synth(streams, {}, Background::plate(median_plate(*f.clip)), settings);
    const Schedule& schedule = streams->schedule();
    ASSERT_GT(schedule.particles_per_line, 2);
    const int max_life = schedule.lines[0].max_life;
    ASSERT_GT(schedule.period_frames, max_life) << "the test needs a frame without a wrap on the line";
    // Frame t with (t - 1) mod period >= max_life: every particle on the line
    // entered after the last wrap and shows input frame s0 + (t - 1) mod period.
    const int t = max_life + 2;
    const int input = schedule.first_start_frame + (t - 1) % schedule.period_frames;
    const RgbImage out = to_display(synth.render(t));
    const RgbImage expected = f.clip->display(input);
    double worst = 0.0;
    for (int y = 16; y < 96; ++y)
        for (int x = 44; x <= 52; ++x)
            for (int c = 0; c < 3; ++c) worst = std::max(worst, static_cast<double>(std::fabs(out.pixel(x, y)[c] - expected.pixel(x, y)[c])));
    EXPECT_LT(worst, 2.0 / 255.0) << "output frame " << t << " vs input frame " << input;
}

TEST(FlowSynthesis, PerfectlyStationaryFlowHasNoSeamAboveTheClipsOwnDifferences) {
    const StationaryFlowFixture& f = stationary();
    SynthesisSettings settings;
    auto streams = std::make_shared<ParticleStreams>(f.bank, std::vector<std::vector<Eigen::Vector2d>>{f.line.points}, settings);
    const Synthesizer synth(streams, {}, Background::plate(median_plate(*f.clip)), settings);
    std::vector<std::vector<float>> clip_luma, ours, loop;
    for (int i = 0; i < f.clip->count(); ++i) clip_luma.push_back(f.clip->luma(i));
    const int frames = 3 * synth.period_frames() + 5;
    for (int t = 1; t <= frames; ++t) {
        ours.push_back(luma(to_display(synth.render(t))));
        loop.push_back(luma(to_display(naive_loop_frame(*f.clip, t))));
    }
    const auto mask = line_band_mask({f.line.points}, f.clip->width(), f.clip->height(), 6.0);
    const QualityReport q = measure_quality(clip_luma, ours, f.clip->width(), f.clip->height(), mask);
    const QualityReport naive = measure_quality(clip_luma, loop, f.clip->width(), f.clip->height(), mask);
    std::printf("stationary flow: ours max/p95 %.3f (clip max/p95 %.3f), share>p99 %.3f; loop max/p95 %.3f share>p99 %.3f\n",
                q.max_transition_ratio, q.clip_max / q.clip_p95, q.share_above_p99, naive.max_transition_ratio,
                naive.share_above_p99);
    EXPECT_LE(q.max_transition_ratio * q.clip_p95, q.clip_max * 1.0 + 1e-9);  // no transition beyond the clip's largest
    EXPECT_EQ(q.share_above_p99, 0.0);
    EXPECT_GT(naive.max_transition_ratio, 1.5 * q.max_transition_ratio);  // the naive loop jumps once a period
    EXPECT_GT(naive.share_above_p99, 0.0);
}

TEST(FlowSynthesis, BackgroundModes) {
    const StationaryFlowFixture& f = stationary();
    SynthesisSettings settings;
    auto streams = std::make_shared<ParticleStreams>(f.bank, std::vector<std::vector<Eigen::Vector2d>>{f.line.points}, settings);
    const RgbImage plate = median_plate(*f.clip);
    const Synthesizer none(streams, {}, Background(), settings);
    const Synthesizer median(streams, {}, Background::plate(plate), settings);
    const Synthesizer looped(streams, {}, Background::looped(f.clip), settings);
    std::vector<float> coverage;
    const RgbImage a = none.render(50, &coverage);
    const RgbImage b = median.render(50);
    const RgbImage c = looped.render(50);
    // Far from the line (x = 5): black, the plate, clip frame (50 - 1) mod 72 = 49.
    EXPECT_EQ(coverage[20 * 96 + 5], 0.0f);
    EXPECT_GT(coverage[20 * 96 + 48], 0.99f);
    const RgbImage clip_frame = f.clip->linear(49);
    for (int ch = 0; ch < 3; ++ch) {
        EXPECT_EQ(a.pixel(5, 20)[ch], 0.0f);
        EXPECT_EQ(b.pixel(5, 20)[ch], plate.pixel(5, 20)[ch]);
        EXPECT_EQ(c.pixel(5, 20)[ch], clip_frame.pixel(5, 20)[ch]);
        // On the line all three show the same particles.
        EXPECT_EQ(a.pixel(48, 60)[ch], b.pixel(48, 60)[ch]);
    }
    EXPECT_EQ(background_mode_from_string("loop"), BackgroundMode::loop);
    EXPECT_THROW(background_mode_from_string("blur"), std::invalid_argument);
}
