// Synthesis from a particle bank: the diagonal order of thesis fig. 3.5 (every
// particle completes its path), periodicity and range independence, exact
// reproduction of the clip where all particles come from one input frame,
// and no seam above the clip's own frame-to-frame difference on a perfectly
// stationary flow.

#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/sampling.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/error.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/flow/tracking.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

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
    // Two lines; tracking lost in-2's particles of start frames 1 and 2.
    const auto one_line = toy_bank(12, 4);
    auto bank = std::make_shared<formats::ParticleBank>(*one_line);
    bank->lines = {{"in-1", 90.0f}, {"in-2", 90.0f}, {"in-3", 90.0f}};
    bank->particles.clear();
    for (const char* id : {"in-1", "in-2", "in-3"})
        for (formats::TrackedParticle p : one_line->particles) {
            p.line_id = id;
            if (std::string(id) == "in-2" && (p.start_frame == 1 || p.start_frame == 2)) continue;
            bank->particles.push_back(std::move(p));
        }
    const Schedule automatic = make_schedule(*bank, SynthesisSettings{});
    // A window including starts 1 and 2 lacks 2 of 36 slots (6 % < 25 %), and
    // most lines have them, so K = 12 is taken; in-2 leaves them empty.
    EXPECT_EQ(automatic.particles_per_line, 12);
    EXPECT_EQ(automatic.lines[0].substituted, 0);
    EXPECT_EQ(automatic.lines[1].substituted, 2);
    ASSERT_FALSE(automatic.warnings.empty());
    SynthesisSettings six;
    six.particles = 6;
    const Schedule window = make_schedule(*bank, six);
    EXPECT_EQ(window.lines[1].substituted, 0);
    EXPECT_GE(window.first_start_frame, 3);

    // On a single line the lost starts are a gap across the whole flow: the
    // automatic window leaves them out.
    bank->lines.resize(1);
    bank->particles.assign(one_line->particles.begin(), one_line->particles.end());
    bank->particles.erase(bank->particles.begin() + 1, bank->particles.begin() + 3);
    const Schedule single = make_schedule(*bank, SynthesisSettings{});
    EXPECT_EQ(single.particles_per_line, 9);
    EXPECT_EQ(single.first_start_frame, 3);
    EXPECT_EQ(single.lines[0].substituted, 0);
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

// --background replay: the clip in step with the diagonal order, so that
// where the particles' coverage ends the background shows the same input
// frame as their texture (the median plate shows another: the clip's
// typical look, not this frame's), and a dissolve where the order wraps.
TEST(FlowSynthesis, AReplayedBackgroundShowsTheFrameTheParticlesShow) {
    const StationaryFlowFixture& f = stationary();
    SynthesisSettings settings;
    auto streams = std::make_shared<ParticleStreams>(f.bank, std::vector<std::vector<Eigen::Vector2d>>{f.line.points}, settings);
    const Schedule& schedule = streams->schedule();
    const int s0 = schedule.first_start_frame, period = schedule.period_frames;
    ASSERT_LT(s0 + period, f.clip->count());  // the clip goes on past the window: the wrap dissolves
    const Synthesizer replayed(streams, {}, make_background(BackgroundMode::replay, f.clip, schedule, f.bank->patch_size_px), settings);
    const Synthesizer median(streams, {}, make_background(BackgroundMode::median, f.clip, schedule, f.bank->patch_size_px), settings);
    const int dissolve = schedule.start_every;
    ASSERT_GE(dissolve, 2);
    // Away from the wrap: after the particles on the line when it wrapped have left.
    const int settled = schedule.lines[0].max_life;
    ASSERT_LT(settled + 2, period);

    double worst_replayed = 0.0, worst_median = 0.0;  // where coverage is partial, against the replayed clip frame
    for (int t : {settled + 1, settled + 2, period, 2 * period - 1}) {
        std::vector<float> coverage;
        const RgbImage out = replayed.render(t, &coverage);
        const RgbImage plate_out = median.render(t);
        const RgbImage frame = f.clip->linear(s0 + (t - 1) % period);
        for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(out.pixel(2, 20)[ch], frame.pixel(2, 20)[ch]) << t;  // no line here
        for (int y = 0; y < out.height; ++y)
            for (int x = 0; x < out.width; ++x) {
                const float c = coverage[static_cast<std::size_t>(y) * out.width + x];
                if (c <= 0.05f || c >= 0.95f) continue;
                for (int ch = 0; ch < 3; ++ch) {
                    worst_replayed = std::max(worst_replayed, static_cast<double>(std::fabs(out.pixel(x, y)[ch] - frame.pixel(x, y)[ch])));
                    worst_median = std::max(worst_median, static_cast<double>(std::fabs(plate_out.pixel(x, y)[ch] - frame.pixel(x, y)[ch])));
                }
            }
    }
    std::printf("partial coverage, largest difference from the replayed clip frame: replay %.4f, median %.4f\n", worst_replayed,
                worst_median);
    EXPECT_LT(worst_replayed, 0.02);
    EXPECT_GT(worst_median, 0.1);

    // After the wrap (output frame period + 1 + r) the background dissolves
    // from the frame after the window, s0 + period + r, to s0 + r.
    for (int r : {0, dissolve / 2, dissolve}) {
        const RgbImage out = replayed.render(period + 1 + r);
        const double w = r < dissolve ? (r + 1.0) / (dissolve + 1.0) : 1.0;
        const RgbImage now = f.clip->linear(s0 + r), after = f.clip->linear(s0 + period + r);
        for (int ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(out.pixel(2, 20)[ch], w * now.pixel(2, 20)[ch] + (1.0 - w) * after.pixel(2, 20)[ch], 1e-5) << r;
    }

    // Until the particles on the line at the wrap have left, those ahead of
    // the ladder step show the frames after the window, and so does the
    // background around them (the dissolve alone would show the window's
    // frame there: where their coverage ends, the texture's edge would show).
    ASSERT_GE(s0 + period, 40);  // the frames after the window are dim: a plate only darkens
    const int half = streams->patch_size() / 2;
    int checked = 0;
    double worst_ladder = 0.0, frames_differ = 0.0;
    for (int r = dissolve + 1; r < settled; r += 3) {
        const int t = period + 1 + r, continuing = s0 + period + r;
        std::vector<float> coverage;
        const RgbImage out = replayed.render(t, &coverage);
        std::vector<ParticleStreams::Visible> visible;
        streams->visible(0, t, visible);
        const RgbImage after = f.clip->linear(continuing), now = f.clip->linear(s0 + r);
        for (int y = 0; y < out.height; ++y)
            for (int x = 0; x < out.width; ++x) {
                const float c = coverage[static_cast<std::size_t>(y) * out.width + x];
                if (c <= 0.05f || c >= 0.95f) continue;
                bool under_continuing = false;
                double to_new = std::numeric_limits<double>::infinity();  // chessboard distance to the nearest new particle
                for (const auto& v : visible) {
                    const double d = std::max(std::fabs(x - v.centre.x()), std::fabs(y - v.centre.y()));
                    if (v.input_frame == continuing) under_continuing = under_continuing || d < half;
                    else to_new = std::min(to_new, d);
                }
                if (!under_continuing || to_new < 4 * half) continue;  // away from the ladder step
                ++checked;
                for (int ch = 0; ch < 3; ++ch) {
                    worst_ladder = std::max(worst_ladder, static_cast<double>(std::fabs(out.pixel(x, y)[ch] - after.pixel(x, y)[ch])));
                    frames_differ = std::max(frames_differ, static_cast<double>(std::fabs(now.pixel(x, y)[ch] - after.pixel(x, y)[ch])));
                }
            }
    }
    std::printf("after the wrap, %d partly covered pixels ahead of the ladder step: largest difference from the frame "
                "their particles show %.4f (from the window's frame: %.4f)\n",
                checked, worst_ladder, frames_differ);
    EXPECT_GT(checked, 50);
    EXPECT_LT(worst_ladder, 0.02);
    EXPECT_GT(frames_differ, 0.1);
    EXPECT_EQ(background_mode_from_string("replay"), BackgroundMode::replay);
}

// --background relit: the median plate darkened where the replayed frame is
// darker than it. A scene whose light comes and goes as a whole (a factor
// a(t) on every pixel, as flames light a pot) around a narrow flowing band:
// away from the band the relit plate is the frame itself on dim frames
// (a(t) / a_median times the plate) and the plate unchanged on bright ones
// (never brightened); where patches end, the output meets the frame the
// particles show instead of the plate's typical light.
TEST(FlowSynthesis, ARelitBackgroundDarkensThePlateAsTheReplayedFrameIs) {
    SyntheticFlowSpec spec;
    spec.width = 144;
    spec.height = 96;
    spec.frames = 60;
    spec.curve = {{72.0, -8.0}, {72.0, 104.0}};
    spec.band_px = 4.0;  // narrower than a patch: patches end over the still scene
    spec.speed_px_per_frame = [](double) { return 8.0; };  // lives shorter than the period
    spec.feature_px = 6.0;
    spec.seed = 5;
    const SyntheticFlow truth(spec);
    // 0.2 .. 1, and dim at the end of the clip (the frames after the window).
    const auto light = [](int t) { return t < 40 ? 0.6 + 0.4 * std::cos(2.0 * M_PI * t / 13.0) : 0.25; };
    std::vector<RgbImage> display;
    for (int t = 0; t < spec.frames; ++t) {
        RgbImage linear = to_linear(truth.frame(t));
        for (float& v : linear.rgb) v *= static_cast<float>(light(t));
        display.push_back(to_display(linear));
    }
    MemoryFrames frames(display, spec.fps);
    formats::FlowLine line;
    line.id = "in-1";
    line.points = spec.curve;
    TrackingSettings tracking;
    tracking.start_every = 2;
    tracking.max_path_frames = -1;
    auto bank = std::make_shared<formats::ParticleBank>(track_particles(frames, {line}, tracking).bank);
    auto clip = std::make_shared<ClipFrames>(ClipFrames::read_all(frames));

    SynthesisSettings settings;
    auto streams = std::make_shared<ParticleStreams>(bank, std::vector<std::vector<Eigen::Vector2d>>{line.points}, settings);
    const Schedule& schedule = streams->schedule();
    const int s0 = schedule.first_start_frame, period = schedule.period_frames;
    const Background relit = make_background(BackgroundMode::relit, clip, schedule, bank->patch_size_px);
    ASSERT_EQ(relit.mode(), BackgroundMode::relit);
    const RgbImage plate = median_plate(*clip);
    std::vector<double> factors;
    for (int i = 0; i < spec.frames; i += std::max(1, spec.frames / 64)) factors.push_back(light(i));
    std::nth_element(factors.begin(), factors.begin() + factors.size() / 2, factors.end());
    const double median_light = factors[factors.size() / 2];

    const Synthesizer with_relit(streams, {}, relit, settings);
    const Synthesizer with_median(streams, {}, Background::plate(plate), settings);
    int dim_frames = 0, bright_frames = 0;
    double relit_error = 0.0, median_error = 0.0, worst_scene = 0.0, worst_bright = 0.0;
    // After the particles on the line at the wrap have left (they show the
    // frames after the window; below), to the end of the period.
    const int settled = schedule.lines[0].max_life;
    for (int t = settled + 1; t <= period; ++t) {
        const int input = s0 + (t - 1) % period;
        const double gain = light(input) / median_light;
        RgbImage background;
        relit.fill(t, spec.width, spec.height, background);
        // The static scene, well clear of the band (light is measured over half a patch).
        for (int y = 0; y < spec.height; ++y)
            for (int x : {4, 20, 36, 108, 124, 139})
                for (int ch = 0; ch < 3; ++ch) {
                    const float p = plate.pixel(x, y)[ch], b = background.pixel(x, y)[ch];
                    if (gain < 1.0) worst_scene = std::max(worst_scene, std::fabs(b - gain * p) / std::max(p, 0.02f));
                    else if (gain > 1.1) worst_bright = std::max(worst_bright, static_cast<double>(std::fabs(b - p)));
                }
        if (gain > 0.9) {
            bright_frames += gain >= 1.0;
            continue;
        }
        ++dim_frames;
        // Where coverage is partial over the still scene (inside the band the
        // plate's texture is not the frame's, relit or not): the output
        // against the frame the particles show.
        std::vector<float> coverage;
        const RgbImage out = with_relit.render(t, &coverage), plate_out = with_median.render(t);
        const RgbImage frame = clip->linear(input);
        for (std::size_t i = 0; i < coverage.size(); ++i) {
            const double x = static_cast<double>(i % static_cast<std::size_t>(spec.width));
            if (coverage[i] <= 0.05f || coverage[i] >= 0.95f || std::fabs(x - 72.0) < spec.band_px + 2.0) continue;
            for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                relit_error += std::fabs(out.rgb[k] - frame.rgb[k]);
                median_error += std::fabs(plate_out.rgb[k] - frame.rgb[k]);
            }
        }
    }
    std::printf("relit plate on %d dim frames: largest relative error of the scene %.4f; on %d bright frames: largest "
                "change %.6f; partial coverage, summed difference from the frame shown: relit %.2f, median %.2f\n",
                dim_frames, worst_scene, bright_frames, worst_bright, relit_error, median_error);
    ASSERT_GT(dim_frames, 3);
    ASSERT_GT(bright_frames, 3);
    EXPECT_LT(worst_scene, 0.03);
    EXPECT_LT(worst_bright, 1e-6);
    EXPECT_LT(relit_error, 0.3 * median_error);

    // Until they have left, the relit plate around the particles still on the
    // line from before the wrap is lit as the frame they show (the frames
    // after the window), as a replayed background follows them.
    ASSERT_GE(s0 + period, 40);  // the frames after the window are dim: a plate only darkens
    const int half = streams->patch_size() / 2;
    int checked = 0;
    double ladder_error = 0.0, dissolve_error = 0.0;
    for (int r = schedule.start_every + 1; r < settled; ++r) {
        const int t = period + 1 + r, continuing = s0 + period + r;
        if (continuing >= clip->count()) break;
        std::vector<float> coverage;
        const RgbImage out = with_relit.render(t, &coverage);
        RgbImage dissolved;  // the plate lit as the window's frame, as without following
        relit.fill(t, spec.width, spec.height, dissolved);
        RgbImage wanted;  // the plate lit as the frame after the window: a one-frame window of it
        Background::relit(clip, plate, continuing, 1, 0, 0.5 * bank->patch_size_px).fill(1, spec.width, spec.height, wanted);
        std::vector<ParticleStreams::Visible> visible;
        streams->visible(0, t, visible);
        const RgbImage after = clip->linear(continuing);
        for (int y = 0; y < spec.height; ++y)
            for (int x = 0; x < spec.width; ++x) {
                const float c = coverage[static_cast<std::size_t>(y) * spec.width + x];
                if (c <= 0.05f || c >= 0.95f || std::fabs(x - 72.0) < spec.band_px + 2.0) continue;
                bool under_continuing = false;
                double to_new = std::numeric_limits<double>::infinity();
                for (const auto& v : visible) {
                    const double d = std::max(std::fabs(x - v.centre.x()), std::fabs(y - v.centre.y()));
                    if (v.input_frame == continuing) under_continuing = under_continuing || d < half;
                    else to_new = std::min(to_new, d);
                }
                if (!under_continuing || to_new < 4 * half) continue;
                ++checked;
                // The patch carries the frame it shows; the plate under it is lit as that frame.
                for (int ch = 0; ch < 3; ++ch) {
                    const float tex = after.pixel(x, y)[ch];
                    ladder_error += std::fabs(out.pixel(x, y)[ch] - ((1.0f - c) * wanted.pixel(x, y)[ch] + c * tex));
                    dissolve_error += std::fabs((1.0f - c) * (dissolved.pixel(x, y)[ch] - wanted.pixel(x, y)[ch]));
                }
            }
    }
    std::printf("after the wrap, %d partly covered pixels ahead of the ladder step: summed difference from the plate lit "
                "as the frame their particles show %.4f (lit as the window's frame: %.4f)\n",
                checked, ladder_error, dissolve_error);
    EXPECT_GT(checked, 60);
    EXPECT_LT(ladder_error, 0.1 * dissolve_error);

    // Frame t + period is frame t, relit too.
    RgbImage a, b;
    relit.fill(5, spec.width, spec.height, a);
    relit.fill(5 + period, spec.width, spec.height, b);
    EXPECT_EQ(a.rgb, b.rgb);
    EXPECT_EQ(background_mode_from_string("relit"), BackgroundMode::relit);
}

TEST(FlowSynthesis, MissingSlotsAreLeftEmptyUnlessANearStartMayBeBorrowed) {
    auto bank = toy_bank(12, 4);
    bank->particles.erase(bank->particles.begin() + 1, bank->particles.begin() + 3);  // starts 1 and 2 lost
    SynthesisSettings settings;
    settings.particles = 5;
    settings.first_start_frame = 0;
    const Schedule empty = make_schedule(*bank, settings);  // the default: never borrow
    ASSERT_EQ(empty.particles_per_line, 5);
    EXPECT_EQ(empty.lines[0].substituted, 2);
    EXPECT_EQ(empty.lines[0].particles, (std::vector<int>{0, -1, -1, 1, 2}));  // bank indices after the erase
    // Slot k = 1 enters at frame 2: nothing of it is scheduled, at any age.
    for (int frame = 1; frame <= 2 * empty.period_frames; ++frame)
        for (const ScheduledParticle& sp : scheduled_particles(empty, *bank, 0, frame)) {
            EXPECT_GE(sp.particle, 0);
            EXPECT_NE(sp.slot, 1);
            EXPECT_NE(sp.slot, 2);
        }
    EXPECT_EQ(empty.lines[0].borrowed, 0);
    settings.borrow_within_frames = 3;
    const Schedule borrowed = make_schedule(*bank, settings);
    EXPECT_EQ(borrowed.lines[0].substituted, 2);
    EXPECT_EQ(borrowed.lines[0].borrowed, 2);
    EXPECT_EQ(borrowed.lines[0].particles, (std::vector<int>{0, 0, 1, 1, 2}));  // the nearest start (ties go down)

    // Particles entering 4 frames apart, starts 4, 8 and 12 lost: within 4
    // frames, start 4 borrows 0 and 12 borrows 16; 8 has none nearer than 8.
    auto sparse = toy_bank(12, 4, 4, 4);
    sparse->particles.erase(sparse->particles.begin() + 1, sparse->particles.begin() + 4);
    settings.borrow_within_frames = 4;
    const Schedule some = make_schedule(*sparse, settings);
    ASSERT_EQ(some.start_every, 4);
    EXPECT_EQ(some.lines[0].substituted, 3);
    EXPECT_EQ(some.lines[0].borrowed, 2);
    EXPECT_EQ(some.lines[0].particles, (std::vector<int>{0, 0, -1, 1, 1}));
    settings.borrow_within_frames = 3;
    EXPECT_EQ(make_schedule(*sparse, settings).lines[0].particles, (std::vector<int>{0, -1, -1, -1, 1}));
}

// The automatic window ends before start frames most lines lack (the clip's
// last starts, whose particles cannot complete their paths), even where the
// missing slots are few overall: their entry would leave every line's start
// to the background at once, once a period.
TEST(FlowSynthesis, TheAutomaticWindowEndsBeforeStartsMostLinesLack) {
    const auto one_line = toy_bank(10, 4, 4, 4);
    auto bank = std::make_shared<formats::ParticleBank>(*one_line);
    bank->lines.clear();
    std::vector<formats::TrackedParticle> particles;
    for (const char* id : {"in-1", "in-2", "in-3", "in-4"}) {
        bank->lines.push_back({id, 90.0f});
        for (formats::TrackedParticle p : one_line->particles) {
            p.line_id = id;
            // Starts 32 and 36 completed on in-1 only: 6 of 40 slots missing (15 %).
            if (p.start_frame >= 32 && std::string(id) != "in-1") continue;
            particles.push_back(std::move(p));
        }
    }
    bank->particles = std::move(particles);
    // Textures alike whatever the start, so that every window's wrap joins
    // equally well and the window's length decides.
    for (formats::TrackedParticle& p : bank->particles)
        for (std::size_t i = 0; i < p.texture_rgba.size(); i += 4) p.texture_rgba[i] = 0.5f;
    const Schedule schedule = make_schedule(*bank, SynthesisSettings{});
    EXPECT_EQ(schedule.first_start_frame, 0);
    EXPECT_EQ(schedule.particles_per_line, 8);  // 10 before: the quarter allowed the two thin starts
    EXPECT_EQ(schedule.longest_window.particles_per_line, 0);
    for (const LineSchedule& line : schedule.lines) EXPECT_EQ(line.substituted, 0);
    // Asked for, the thin starts are still taken.
    SynthesisSettings ten;
    ten.particles = 10;
    EXPECT_EQ(make_schedule(*bank, ten).particles_per_line, 10);
}

// The default window is the one whose wrap joins best (the ladder step of
// fig. 3.5b shows the least), among those at least 85 % as long as the
// longest. Every particle shows a grey g(f) of the input frame f it comes
// from, random per frame except that frames 19..24 repeat frames 1..6: a
// window starting at frame 1 with a period of 18 frames wraps onto the very
// frames the input shows, so its join error is 0, while the longest window
// (K = 20 from frame 0) joins frames 0..4 to 20..24. Its error is the RMS of
// those grey differences, computed here by hand.
TEST(FlowSynthesis, TheDefaultWindowIsTheOneWhoseWrapJoinsBest) {
    const int count = 20, life = 6;
    auto bank = toy_bank(count, life);
    ASSERT_EQ(bank->clip_frame_count, 25);
    std::mt19937 random(7);
    std::uniform_real_distribution<float> grey(0.1f, 0.9f);
    std::vector<float> g(25);
    for (float& value : g) value = grey(random);
    for (int f = 19; f < 25; ++f) g[static_cast<std::size_t>(f)] = g[static_cast<std::size_t>(f - 18)];
    // Slow particles (1 px/frame): the input's particle nearest a place is
    // within the quarter patch the measure looks in.
    for (formats::TrackedParticle& p : bank->particles)
        for (int a = 0; a < life; ++a) {
            p.arc_length_px[static_cast<std::size_t>(a)] = static_cast<float>(a);
            for (int t = 0; t < 16; ++t)
                for (int c = 0; c < 3; ++c)
                    p.texture_rgba[(static_cast<std::size_t>(a) * 16 + t) * 4 + c] = g[static_cast<std::size_t>(p.start_frame + a)];
        }

    const Schedule schedule = make_schedule(*bank, SynthesisSettings{});
    EXPECT_EQ(schedule.first_start_frame, 1);
    EXPECT_EQ(schedule.particles_per_line, 18);
    EXPECT_NEAR(schedule.wrap_join_error, 0.0, 1e-6);
    double sum = 0.0;
    for (int a = 0; a + 20 < 25; ++a) sum += std::pow(g[static_cast<std::size_t>(a)] - g[static_cast<std::size_t>(a + 20)], 2);
    const double longest = std::sqrt(sum / 5.0);
    ASSERT_GT(longest, 0.05);
    EXPECT_EQ(schedule.longest_window.particles_per_line, 20);
    EXPECT_EQ(schedule.longest_window.first_start_frame, 0);
    EXPECT_NEAR(schedule.longest_window.wrap_join_error, longest, 1e-6);
    std::printf("wrap join error: chosen window %.4f, longest %.4f (by hand %.4f)\n", schedule.wrap_join_error,
                schedule.longest_window.wrap_join_error, longest);

    // A window asked for is kept; so is a seeded one (among the longest).
    SynthesisSettings asked;
    asked.first_start_frame = 0;
    const Schedule kept = make_schedule(*bank, asked);
    EXPECT_EQ(kept.particles_per_line, 20);
    EXPECT_NEAR(kept.wrap_join_error, longest, 1e-6);  // measured for any window
    EXPECT_EQ(kept.longest_window.particles_per_line, 0);
    SynthesisSettings seeded;
    seeded.seed = 3;
    EXPECT_EQ(make_schedule(*bank, seeded).particles_per_line, 20);
    // Of the windows of an asked length, the best-joining one.
    SynthesisSettings eighteen;
    eighteen.particles = 18;
    EXPECT_EQ(make_schedule(*bank, eighteen).first_start_frame, 1);
}

// Where the diagonal order wraps, patches of input frames a period apart
// overlap; their plain weighted mean loses detail while the wrap crosses the
// line, so detail pulses once a period. Detail-preserving blending keeps it
// steady: the synthesis pulses less than without it and less than the
// flow-map cross-fade, with more high-frequency power and still no seam.
namespace {

// A finely textured stationary flow (detail at the scale the pulsing measure
// sees), several lines 8 px apart whose patches overlap, as densified lines do.
struct FineFlowFixture {
    SyntheticFlow truth;
    std::vector<formats::FlowLine> lines;
    std::vector<std::vector<Eigen::Vector2d>> points;
    std::shared_ptr<formats::ParticleBank> bank;
    std::shared_ptr<ClipFrames> clip;

    FineFlowFixture()
        : truth([] {
              SyntheticFlowSpec spec;
              spec.width = 96;
              spec.height = 112;
              spec.frames = 72;
              spec.curve = {{48.0, -8.0}, {48.0, 120.0}};
              spec.band_px = 48.0;
              spec.speed_px_per_frame = [](double) { return 3.0; };
              spec.feature_px = 2.0;
              spec.seed = 5;
              return spec;
          }()) {
        for (int k = 0; k < 3; ++k) {
            formats::FlowLine line;
            line.id = "in-" + std::to_string(k + 1);
            line.points = {{40.0 + 8.0 * k, -8.0}, {40.0 + 8.0 * k, 120.0}};
            lines.push_back(line);
            points.push_back(line.points);
        }
        MemoryFrames frames = truth.clip();
        TrackingSettings settings;
        settings.start_every = 3;
        settings.max_path_frames = -1;
        bank = std::make_shared<formats::ParticleBank>(track_particles(frames, lines, settings).bank);
        clip = std::make_shared<ClipFrames>(ClipFrames::read_all(frames));
    }
};

}  // namespace

TEST(FlowSynthesis, DetailPreservingBlendingPulsesLessThanPlainBlendingAndTheCrossFade) {
    const FineFlowFixture f;
    const int w = f.clip->width(), h = f.clip->height();
    std::vector<std::vector<float>> clip_luma;
    for (int i = 0; i < f.clip->count(); ++i) clip_luma.push_back(f.clip->luma(i));
    const auto mask = line_band_mask(f.points, w, h, 6.0);
    const RgbImage plate = median_plate(*f.clip);
    QualityReport plain, preserved, flow_map;
    int frames = 0;
    for (bool preserve : {false, true}) {
        SynthesisSettings settings;
        settings.preserve_detail = preserve;
        auto streams = std::make_shared<ParticleStreams>(f.bank, f.points, settings);
        const Synthesizer synth(streams, {}, Background::plate(plate), settings);
        frames = 3 * synth.period_frames() + 5;
        std::vector<std::vector<float>> ours;
        for (int t = 1; t <= frames; ++t) ours.push_back(luma(to_display(synth.render(t))));
        (preserve ? preserved : plain) = measure_quality(clip_luma, ours, w, h, mask);
        if (preserve) {
            const FlowMapBaseline baseline(velocity_field(*streams, w, h, 12.0), f.clip->linear(0), plate, 32);
            std::vector<std::vector<float>> advected;
            for (int t = 1; t <= frames; ++t) advected.push_back(luma(to_display(baseline.render(t))));
            flow_map = measure_quality(clip_luma, advected, w, h, mask);
        }
    }
    std::printf("pulsing: preserved %.4f, plain %.4f, flow map %.4f, clip %.4f; HF ratio preserved %.3f plain %.3f; "
                "patch d preserved %.4f (self %.4f)\n",
                preserved.pulsing, plain.pulsing, flow_map.pulsing, preserved.clip_pulsing, preserved.hf_power_ratio,
                plain.hf_power_ratio, preserved.patch_distance, preserved.clip_self_distance);
    EXPECT_LT(preserved.pulsing, plain.pulsing);
    EXPECT_LT(preserved.pulsing, flow_map.pulsing);
    EXPECT_GT(preserved.hf_power_ratio, plain.hf_power_ratio);
    EXPECT_EQ(preserved.share_above_p99, 0.0);
}

// The banded renderer (the default) must give the frames of the
// straightforward whole-frame pass (SynthesisSettings::reference_rendering)
// to float rounding, on identity, warped and keyed lines, with and without
// detail preservation, with patches crossing every image border and many
// input frames meeting at a pixel; and not depend on the thread count.
namespace {

struct OverlapScene {
    std::shared_ptr<formats::ParticleBank> bank;
    std::vector<std::vector<Eigen::Vector2d>> inputs;
    RgbImage plate;
};

// 83 x 70 (not a multiple of the band height), 8 x 8 patches, 6 lines 16 px
// apart (one diagonal, one crossing the left border, all crossing the top and
// bottom), 5 start frames for 30-frame lives: the diagonal order wraps 5 times
// along every path. Random premultiplied textures, some texels half transparent.
OverlapScene overlap_scene() {
    OverlapScene s;
    auto bank = std::make_shared<formats::ParticleBank>();
    const int patch = 8, life = 30, count = 5;
    bank->patch_size_px = patch;
    bank->clip_width_px = 83;
    bank->clip_height_px = 70;
    bank->clip_frame_count = count + life;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.05f, 0.95f);
    for (int l = 0; l < 6; ++l) {
        const std::string id = "in-" + std::to_string(l);
        if (l < 5) s.inputs.push_back({{-2.0 + 16.0 * l, -6.0}, {8.0 + 16.0 * l, 76.0}});
        else s.inputs.push_back({{2.0, -3.0}, {80.0, 73.0}});
        bank->lines.push_back({id, static_cast<float>(formats::polyline_length(s.inputs.back()))});
        for (int p = 0; p < count; ++p) {
            formats::TrackedParticle particle;
            particle.line_id = id;
            particle.start_frame = p;
            for (int a = 0; a < life; ++a) {
                particle.arc_length_px.push_back(3.7f * a);
                for (int t = 0; t < patch * patch; ++t) {
                    const float alpha = u(rng) < 0.2f ? 0.5f : 1.0f;
                    particle.texture_rgba.insert(particle.texture_rgba.end(), {u(rng) * alpha, u(rng) * alpha, u(rng) * alpha, alpha});
                }
            }
            bank->particles.push_back(std::move(particle));
        }
    }
    s.bank = bank;
    s.plate = RgbImage(83, 70, 0.3f);
    return s;
}

// Every input line bent (warped) and, for two of them, moving (keyed).
std::vector<OutputLine> overlap_outputs(const OverlapScene& s) {
    std::vector<OutputLine> out;
    for (std::size_t l = 0; l < s.inputs.size(); ++l) {
        OutputLine o;
        o.from = "in-" + std::to_string(l);
        o.line.id = "out-" + std::to_string(l);
        const Eigen::Vector2d a = s.inputs[l].front(), b = s.inputs[l].back();
        const auto bent = [&](double amplitude) {
            std::vector<Eigen::Vector2d> points;
            for (int i = 0; i <= 12; ++i) {
                const double t = i / 12.0;
                points.push_back(a + t * (b - a) + Eigen::Vector2d(amplitude * std::sin(6.0 * t), 0.0));
            }
            return points;
        };
        if (l % 3 == 1) {
            o.line.keys.push_back({1, bent(2.0)});
            o.line.keys.push_back({20, bent(-5.0)});
        } else {
            o.line.points = bent(4.0);
        }
        out.push_back(o);
    }
    return out;
}

float max_difference(const std::vector<float>& a, const std::vector<float>& b) {
    EXPECT_EQ(a.size(), b.size());
    float worst = 0.0f;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
    return worst;
}

}  // namespace

TEST(FlowSynthesis, BandedRenderingEqualsTheWholeFramePass) {
    const OverlapScene scene = overlap_scene();
    for (bool warped : {false, true})
        for (bool preserve : {true, false})
            for (double sharpness : {1.0, 4.0})
              for (double fade_px : {0.0, 12.0}) {
                SynthesisSettings settings;
                settings.preserve_detail = preserve;
                settings.overlap_sharpness = sharpness;
                settings.edge_fade_px = fade_px;
                auto streams = std::make_shared<ParticleStreams>(scene.bank, scene.inputs, settings);
                const std::vector<OutputLine> outputs = warped ? overlap_outputs(scene) : std::vector<OutputLine>{};
                const Synthesizer banded(streams, outputs, Background::plate(scene.plate), settings);
                SynthesisSettings reference_settings = settings;
                reference_settings.reference_rendering = true;
                const Synthesizer reference(streams, outputs, Background::plate(scene.plate), reference_settings);
                float worst = 0.0f, worst_coverage = 0.0f, textured = 0.0f;
                for (int frame = 1; frame <= 2 * banded.period_frames() + 3; ++frame) {
                    std::vector<float> coverage, reference_coverage;
                    const RgbImage a = banded.render(frame, &coverage);
                    const RgbImage b = reference.render(frame, &reference_coverage);
                    worst = std::max(worst, max_difference(a.rgb, b.rgb));
                    worst_coverage = std::max(worst_coverage, max_difference(coverage, reference_coverage));
                    textured = std::max(textured, max_difference(a.rgb, scene.plate.rgb));
                }
                SCOPED_TRACE(std::string(warped ? "warped and keyed lines" : "identity lines") +
                             (preserve ? ", detail preserved" : ", plain blending") + ", overlap sharpness " +
                             std::to_string(sharpness) + ", edge fade " + std::to_string(fade_px));
                EXPECT_LE(worst, 1e-4f);
                EXPECT_LE(worst_coverage, 1e-4f);
                EXPECT_GT(textured, 0.2f);  // the frames are not just the plate
            }
    // The comparison covers detail preservation and overlap sharpening at
    // work: each changes the frames.
    SynthesisSettings plain, detail, mixed;
    plain.preserve_detail = false;
    mixed.preserve_detail = false;
    mixed.overlap_sharpness = 1.0;
    auto streams = std::make_shared<ParticleStreams>(scene.bank, scene.inputs, SynthesisSettings{});
    const Synthesizer blended(streams, {}, Background::plate(scene.plate), plain);
    const Synthesizer preserved(streams, {}, Background::plate(scene.plate), detail);
    const Synthesizer unsharpened(streams, {}, Background::plate(scene.plate), mixed);
    EXPECT_GT(max_difference(preserved.render(4).rgb, blended.render(4).rgb), 0.05f);
    EXPECT_GT(max_difference(unsharpened.render(4).rgb, blended.render(4).rgb), 0.05f);
}

// SynthesisSettings::edge_fade_px scales the layer's coverage c by
// clamp(2 T / M - 1, 0, 1): T the coverage smoothed by two boxes of radius
// fade / 2 (averaged over the samples inside the frame), M the largest T
// within fade px. Checked against that rule computed here directly, on the
// unfaded render's coverage.
TEST(FlowSynthesis, AnEdgeFadeScalesTheLayersCoverageByItsTentOverItsLargest) {
    const OverlapScene scene = overlap_scene();
    SynthesisSettings settings, faded_settings;
    faded_settings.edge_fade_px = 12.0;
    auto streams = std::make_shared<ParticleStreams>(scene.bank, scene.inputs, settings);
    const Synthesizer plain(streams, overlap_outputs(scene), Background::plate(scene.plate), settings);
    const Synthesizer faded(streams, overlap_outputs(scene), Background::plate(scene.plate), faded_settings);
    const int w = scene.plate.width, h = scene.plate.height, r = 6;
    std::vector<float> c0, c1;
    plain.render(7, &c0);
    faded.render(7, &c1);
    const auto at = [w](const std::vector<double>& v, int x, int y) { return v[static_cast<std::size_t>(y) * w + x]; };
    const auto box = [&](const std::vector<double>& in, bool along_x) {
        std::vector<double> out(in.size());
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                double sum = 0.0;
                int count = 0;
                for (int d = -r; d <= r; ++d) {
                    const int xx = along_x ? x + d : x, yy = along_x ? y : y + d;
                    if (xx < 0 || xx >= w || yy < 0 || yy >= h) continue;
                    sum += at(in, xx, yy);
                    ++count;
                }
                out[static_cast<std::size_t>(y) * w + x] = sum / count;
            }
        return out;
    };
    std::vector<double> tent(c0.begin(), c0.end());
    for (int repeat = 0; repeat < 2; ++repeat) tent = box(box(tent, true), false);
    double worst = 0.0, largest_before = 0.0, largest_after = 0.0;
    int rim = 0, kept = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double largest = 0.0;
            for (int yy = std::max(0, y - 2 * r); yy <= std::min(h - 1, y + 2 * r); ++yy)
                for (int xx = std::max(0, x - 2 * r); xx <= std::min(w - 1, x + 2 * r); ++xx)
                    largest = std::max(largest, at(tent, xx, yy));
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            const double expected =
                c0[i] > 0.0f && largest > 0.0 ? c0[i] * std::clamp(2.0 * tent[i] / largest - 1.0, 0.0, 1.0) : 0.0;
            worst = std::max(worst, std::abs(expected - c1[i]));
            largest_before = std::max(largest_before, static_cast<double>(c0[i]));
            largest_after = std::max(largest_after, static_cast<double>(c1[i]));
            if (c0[i] > 0.9f && c1[i] < 0.5f) ++rim;
            if (c0[i] > 0.9f && c1[i] > 0.9f) ++kept;
        }
    EXPECT_LE(worst, 1e-5);
    // It fades a rim and keeps what lies within; the layer never vanishes,
    // even where it is thinner than the fade.
    EXPECT_GT(rim, 50);
    std::printf("[ measured ] of the pixels the layer covers above 0.9: %d faded below 0.5, %d kept above 0.9\n", rim, kept);
    EXPECT_GT(kept, 50);
    EXPECT_NEAR(largest_after, largest_before, 1e-6);
}

TEST(FlowSynthesis, FramesDoNotDependOnTheThreadCount) {
    const OverlapScene scene = overlap_scene();
    for (bool warped : {false, true}) {
        SynthesisSettings settings;
        auto streams = std::make_shared<ParticleStreams>(scene.bank, scene.inputs, settings);
        const Synthesizer synth(streams, warped ? overlap_outputs(scene) : std::vector<OutputLine>{},
                                Background::plate(scene.plate), settings);
        std::map<int, std::vector<float>> single;
        for (int frame = 1; frame <= 11; ++frame) single[frame] = synth.render(frame).rgb;
        for (int threads : {1, 2, 3, 0}) {
            std::map<int, std::vector<float>> got;
            const int delivered = synth.render_frames(1, 11, threads, [&](int f, const RgbImage& image) {
                EXPECT_EQ(got.count(f), 0u);
                EXPECT_EQ(static_cast<int>(got.size()) + 1, f);  // in order
                got[f] = image.rgb;
                return true;
            });
            EXPECT_EQ(delivered, 11);
            for (int frame = 1; frame <= 11; ++frame)
                EXPECT_EQ(got[frame], single[frame]) << threads << " thread(s), frame " << frame;  // bit for bit
        }
        // The sink stops the rendering: frames before it are delivered, in order.
        std::vector<int> seen;
        const int delivered = synth.render_frames(3, 40, 2, [&](int f, const RgbImage&) {
            seen.push_back(f);
            return f < 6;
        });
        EXPECT_EQ(delivered, 3);
        EXPECT_EQ(seen, (std::vector<int>{3, 4, 5, 6}));
    }
}

// prepare_synthesis from inputs in memory (the benchmarks' path, a host's)
// renders what the file version renders from the same bank and drawing, for
// plain synthesis and a drawn edit; and a job that needs the clip's frames
// is refused when the sources have none.
TEST(FlowSynthesisJob, InMemorySourcesRenderWhatTheFilesRender) {
    const std::string dir = flowvid::testing::scratch_dir("synthesis_job_sources");
    auto bank = toy_bank(10, 6);
    formats::FlowLineSet drawing;
    drawing.width = bank->clip_width_px;
    drawing.height = bank->clip_height_px;
    drawing.inputs.push_back({"in-1", toy_line()[0]});
    formats::FlowLine bent;
    bent.id = "out-1";
    bent.from = "in-1";
    bent.points = {{20.0, 5.0}, {40.0, 50.0}, {28.0, 95.0}};
    drawing.outputs.push_back(bent);
    const std::string bank_path = dir + "/bank.exr", drawing_path = dir + "/lines.json";
    formats::write_particle_bank(bank_path, *bank);
    formats::write_flowline_set(drawing_path, drawing);

    for (const bool edit : {false, true}) {
        SynthesisJob job;
        job.bank_path = bank_path;
        job.flowlines_path = drawing_path;
        job.background = "none";
        job.edit = edit;
        job.interpolate = false;
        const PreparedSynthesis from_files = prepare_synthesis(job);
        SynthesisSources sources;  // the bank as the file holds it (textures in half floats)
        sources.bank = std::make_shared<formats::ParticleBank>(formats::read_particle_bank(bank_path));
        sources.drawing = drawing;
        sources.drawing_name = "memory";
        const PreparedSynthesis from_memory = prepare_synthesis(std::move(sources), job);
        ASSERT_EQ(from_memory.synthesizer->period_frames(), from_files.synthesizer->period_frames());
        EXPECT_EQ(from_memory.outputs.size(), edit ? 1u : 0u);
        double largest_difference = 0.0, largest_value = 0.0;
        for (int frame = 1; frame <= 8; ++frame) {
            const RgbImage a = from_files.synthesizer->render(frame), b = from_memory.synthesizer->render(frame);
            ASSERT_EQ(a.rgb.size(), b.rgb.size());
            for (std::size_t i = 0; i < a.rgb.size(); ++i) {
                largest_difference = std::max(largest_difference, static_cast<double>(std::abs(a.rgb[i] - b.rgb[i])));
                largest_value = std::max(largest_value, static_cast<double>(a.rgb[i]));
            }
        }
        EXPECT_EQ(largest_difference, 0.0) << (edit ? "edit" : "synthesis");
        EXPECT_GT(largest_value, 0.05) << "the frames show the particles";
    }

    SynthesisJob needs_clip;
    needs_clip.background = "median";
    SynthesisSources no_clip;
    no_clip.bank = bank;
    no_clip.drawing = drawing;
    EXPECT_THROW(prepare_synthesis(std::move(no_clip), needs_clip), UsageError);
    SynthesisJob edit_without_outputs;
    edit_without_outputs.background = "none";
    edit_without_outputs.edit = true;
    SynthesisSources plain_drawing;
    plain_drawing.bank = bank;
    plain_drawing.drawing = drawing;
    plain_drawing.drawing.outputs.clear();
    plain_drawing.drawing_name = "memory";
    try {
        prepare_synthesis(std::move(plain_drawing), edit_without_outputs);
        ADD_FAILURE() << "an edit without output lines was accepted";
    } catch (const ValidationError& error) {
        EXPECT_NE(std::string(error.what()).find("memory"), std::string::npos) << error.what();
    }
}
