// Tracking along flow lines against procedural clips whose motion is known
// exactly (flow/synthetic.hpp): speed profiles within 0.5 px/frame (the issue's
// bar) and sub-pixel positions, stationary and non-stationary, straight and
// curved lines; determinism; and a smoke test on the real waterfall.

#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/sampling.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/flow/tracking.hpp"
#include "flowvid/flow/tracking_job.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

struct Errors {
    double max_step = 0.0;   // |measured - true| step, px/frame
    double rms_step = 0.0;
    double max_position = 0.0;  // |measured - true| arc position, px
    int steps = 0;
    int particles = 0;
};

Errors compare(const formats::ParticleBank& bank, const SyntheticFlow& truth) {
    Errors e;
    double sq = 0.0;
    for (const formats::TrackedParticle& p : bank.particles) {
        ++e.particles;
        for (int a = 0; a < p.life_frames(); ++a) {
            const double true_s = truth.arc_at(p.start_frame, a);
            e.max_position = std::max(e.max_position, std::fabs(p.arc_length_px[static_cast<std::size_t>(a)] - true_s));
            if (a + 1 >= p.life_frames()) continue;
            const double measured = p.arc_length_px[static_cast<std::size_t>(a) + 1] - p.arc_length_px[static_cast<std::size_t>(a)];
            const double expected = truth.arc_at(p.start_frame, a + 1) - true_s;
            const double err = std::fabs(measured - expected);
            e.max_step = std::max(e.max_step, err);
            sq += err * err;
            ++e.steps;
        }
    }
    e.rms_step = e.steps ? std::sqrt(sq / e.steps) : 0.0;
    return e;
}

formats::FlowLine line_of(const std::vector<Eigen::Vector2d>& points, const std::string& id = "in-1") {
    formats::FlowLine line;
    line.id = id;
    line.points = points;
    return line;
}

// Tracks a synthetic flow's curve with non-stationary dynamics, every path to its end.
TrackingResult track_non_stationary(const SyntheticFlow& truth, int start_every) {
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.dynamics = formats::ParticleDynamics::non_stationary;
    settings.start_every = start_every;
    settings.max_path_frames = -1;
    return track_particles(clip, {line_of(truth.spec().curve)}, settings);
}

SyntheticFlowSpec accelerating_fall() {
    SyntheticFlowSpec spec;
    spec.width = 128;
    spec.height = 112;
    spec.frames = 56;
    spec.curve = {{64.0, 4.0}, {64.0, 108.0}};
    spec.band_px = 40.0;
    spec.speed_px_per_frame = [](double s) { return 2.0 + 0.05 * s; };  // 2 .. 8 px/frame, like a fall
    spec.seed = 11;
    return spec;
}

}  // namespace

TEST(FlowTracking, RecoversAcceleratingSpeedProfileOnStraightLine) {
    const SyntheticFlow truth(accelerating_fall());
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.threads = 2;
    settings.start_every = 1;
    settings.max_path_frames = -1;
    const TrackingResult result = track_particles(clip, {line_of(truth.spec().curve)}, settings);
    const Errors e = compare(result.bank, truth);
    std::printf("straight: %d particles, %d steps, step error max %.3f rms %.3f px/frame, position error max %.3f px\n",
                e.particles, e.steps, e.max_step, e.rms_step, e.max_position);
    ASSERT_GT(e.particles, 20);
    EXPECT_LT(e.max_step, 0.5);   // the bar
    EXPECT_LT(e.rms_step, 0.1);   // sub-pixel
    EXPECT_LT(e.max_position, 1.5);  // drift over a whole 26-frame path
    // Every kept particle completed its path: it was last seen within one step of the end.
    for (const auto& p : result.bank.particles) {
        const double end = result.bank.lines[0].length_px;
        EXPECT_GT(p.arc_length_px.back() + 9.0, end);
        EXPECT_LE(p.start_frame + p.life_frames(), result.bank.clip_frame_count);
    }
    ASSERT_EQ(result.report.lines.size(), 1u);
    EXPECT_EQ(result.report.lines[0].uncertain_steps, 0);
    EXPECT_GT(result.report.lines[0].mean_correlation, 0.95);

    // The speed profile from the bank follows v(s) = 2 + 0.05 s.
    const std::vector<double> profile = speed_profile(result.bank, "in-1", 8.0);
    int checked = 0;
    for (std::size_t b = 0; b + 1 < profile.size(); ++b) {
        if (std::isnan(profile[b])) continue;
        const double s = (b + 0.5) * 8.0;
        EXPECT_NEAR(profile[b], 2.0 + 0.05 * s, 0.5) << "bin " << b;
        ++checked;
    }
    EXPECT_GT(checked, 10);
}

TEST(FlowTracking, FollowsCurvedLine) {
    SyntheticFlowSpec spec;
    spec.width = 144;
    spec.height = 112;
    spec.frames = 48;
    // A bend of about 70 degrees (a circular arc of radius 110 px), drawn as 16 segments.
    for (int i = 0; i <= 16; ++i) {
        const double angle = 1.2 * i / 16.0;
        spec.curve.emplace_back(12.0 + 110.0 * std::sin(angle), 6.0 + 110.0 * (1.0 - std::cos(angle)));
    }
    spec.band_px = 30.0;
    spec.speed_px_per_frame = [](double s) { return 3.0 + 0.02 * s; };
    spec.seed = 5;
    const SyntheticFlow truth(spec);
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.patch_size_px = 16;
    settings.start_every = 1;
    settings.max_path_frames = -1;  // one path over the whole line (the truth counts arc from its start)
    const TrackingResult result = track_particles(clip, {line_of(spec.curve)}, settings);
    const Errors e = compare(result.bank, truth);
    std::printf("curved: %d particles, step error max %.3f rms %.3f, position error max %.3f px\n", e.particles,
                e.max_step, e.rms_step, e.max_position);
    ASSERT_GT(e.particles, 10);
    EXPECT_LT(e.max_step, 0.5);
    EXPECT_LT(e.rms_step, 0.15);
    EXPECT_LT(e.max_position, 1.5);
}

TEST(FlowTracking, NonStationaryParticlesKeepTheirOwnSpeed) {
    SyntheticFlowSpec spec = accelerating_fall();
    spec.frames = 64;
    spec.speed_px_per_frame = [](double) { return 4.0; };
    // Particles entering at different frames move at 3.2 .. 4.8 px/frame (slowly
    // varying, so that no particle overtakes another).
    spec.speed_factor = [](double e) { return 1.0 + 0.2 * std::sin(2.0 * M_PI * (e - 20.0) / 96.0); };
    const SyntheticFlow truth(spec);
    const TrackingResult result = track_non_stationary(truth, 1);
    const Errors e = compare(result.bank, truth);
    std::printf("non-stationary: %d particles, step error max %.3f rms %.3f, position error max %.3f px\n", e.particles,
                e.max_step, e.rms_step, e.max_position);
    ASSERT_GT(e.particles, 20);
    EXPECT_LT(e.max_step, 0.5);
    EXPECT_LT(e.max_position, 1.5);
    // The particles' mean speeds differ as their entry frames say.
    double slowest = 1e9, fastest = 0.0;
    for (const auto& p : result.bank.particles) {
        const double speed = (p.arc_length_px.back() - p.arc_length_px.front()) / (p.life_frames() - 1);
        slowest = std::min(slowest, speed);
        fastest = std::max(fastest, speed);
    }
    EXPECT_LT(slowest, 3.5);
    EXPECT_GT(fastest, 4.5);
    EXPECT_EQ(result.bank.dynamics, formats::ParticleDynamics::non_stationary);
}

// Flames surge: the whole flow speeds up within a frame, more than the window
// around a particle's last step reaches (2 -> 16 px/frame against +/- 6 px). A non-stationary particle whose match there fails searches the
// whole window before it extrapolates its last step; without that it falls
// behind the surge and its texture stops following the flow.
TEST(FlowTracking, NonStationaryParticlesFollowASurgeBeyondTheirSearchWindow) {
    SyntheticFlowSpec spec = accelerating_fall();
    spec.frames = 48;
    spec.speed_px_per_frame = [](double) { return 2.0; };
    spec.time_factor = [](double t) { return t < 23.5 ? 1.0 : 8.0; };  // x8 from frame 23.5
    spec.feature_px = 1.5;  // the surge stretches the texture along the flow 8 times
    const SyntheticFlow truth(spec);
    const TrackingResult result = track_non_stationary(truth, 2);
    const Errors e = compare(result.bank, truth);
    int surged = 0;  // particles on the line when the surge came
    for (const auto& p : result.bank.particles)
        if (p.start_frame < 23 && p.start_frame + p.life_frames() > 25) ++surged;
    std::printf("surge: %d particles (%d through the surge), step error max %.3f rms %.3f, position error max %.3f px\n",
                e.particles, surged, e.max_step, e.rms_step, e.max_position);
    ASSERT_GE(surged, 4);
    EXPECT_LT(e.max_step, 0.5);
    EXPECT_LT(e.max_position, 1.5);
}

TEST(FlowTracking, TexturesAreCentredLinearPatchesAndBankRoundTrips) {
    const SyntheticFlow truth(accelerating_fall());
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.start_every = 4;
    settings.max_particles_per_line = 5;
    settings.max_path_frames = -1;
    const TrackingResult result = track_particles(clip, {line_of(truth.spec().curve)}, settings);
    ASSERT_EQ(result.bank.particles.size(), 5u);
    for (std::size_t i = 0; i < 5; ++i) EXPECT_EQ(result.bank.particles[i].start_frame, static_cast<int>(i) * 4);
    // A patch is the 24 x 24 block of whole pixels whose centre is nearest the
    // particle: texel (i, j) is frame pixel origin + (j, i), linearised.
    const formats::TrackedParticle& p = result.bank.particles[2];
    const int age = 6;
    const int f = p.start_frame + age;
    const double s = p.arc_length_px[age];
    const RgbImage frame = truth.frame(f);
    const int ox = patch_origin(64.0, 24), oy = patch_origin(4.0 + s, 24);
    EXPECT_LE(std::fabs(oy + 11.5 - (4.0 + s)), 0.5);
    for (int i : {0, 12, 23})
        for (int j : {0, 12, 23}) {
            if (oy + i < 0) continue;
            const float* texel = p.texture_rgba.data() + (static_cast<std::size_t>(age) * 24 * 24 + static_cast<std::size_t>(i) * 24 + j) * 4;
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(texel[c], srgb_to_linear(frame.pixel(ox + j, oy + i)[c]), 1e-4);
            EXPECT_FLOAT_EQ(texel[3], 1.0f);
        }
    // The first patch hangs over the top edge (line starts at y = 4): alpha 0 there.
    EXPECT_FLOAT_EQ(p.texture_rgba[3], 0.0f);

    const std::string path = flowvid::testing::scratch_dir("flow_tracking") + "/bank.exr";
    formats::write_particle_bank(path, result.bank);
    const formats::ParticleBank back = formats::read_particle_bank(path);
    ASSERT_EQ(back.particles.size(), result.bank.particles.size());
    EXPECT_EQ(back.particles[3].arc_length_px, result.bank.particles[3].arc_length_px);
    EXPECT_NEAR(back.particles[3].texture_rgba[100], result.bank.particles[3].texture_rgba[100], 1e-3);
}

TEST(FlowTracking, DeterministicWhateverTheThreadCount) {
    SyntheticFlowSpec spec = accelerating_fall();
    spec.frames = 30;
    const SyntheticFlow truth(spec);
    MemoryFrames clip = truth.clip();
    std::vector<formats::FlowLine> lines = {line_of({{50.0, 4.0}, {50.0, 108.0}}, "a"),
                                            line_of({{64.0, 4.0}, {64.0, 108.0}}, "b"),
                                            line_of({{78.0, 4.0}, {78.0, 108.0}}, "c")};
    TrackingSettings one;
    one.threads = 1;
    one.start_every = 1;
    TrackingSettings two = one;
    two.threads = 2;
    const TrackingResult a = track_particles(clip, lines, one);
    const TrackingResult b = track_particles(clip, lines, two);
    EXPECT_TRUE(a.bank == b.bank);
}

TEST(FlowTracking, RefusesBadSettings) {
    const SyntheticFlow truth(accelerating_fall());
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.patch_size_px = 2;
    EXPECT_THROW(track_particles(clip, {line_of(truth.spec().curve)}, settings), std::invalid_argument);
    EXPECT_THROW(track_particles(clip, {}, TrackingSettings{}), std::invalid_argument);
}

TEST(FlowTracking, CutsLongLinesIntoSegmentsParticlesCanCross) {
    // Crossing the line takes about 26 frames: with paths of at most 14 frames
    // it is cut in two.
    SyntheticFlowSpec spec = accelerating_fall();
    spec.frames = 36;
    const SyntheticFlow truth(spec);
    MemoryFrames clip = truth.clip();
    TrackingSettings settings;
    settings.start_every = 1;
    settings.max_path_frames = 14;
    const TrackingResult result = track_particles(clip, {line_of(spec.curve)}, settings);
    ASSERT_EQ(result.report.probes.size(), 1u);
    EXPECT_NEAR(result.report.probes[0].travel_frames, truth.travel_frames(104.0), 2.5);
    EXPECT_GE(result.report.probes[0].segments, 2);
    ASSERT_GE(result.tracked_lines.size(), 2u);
    std::string base;
    double from = 0.0, to = 0.0;
    ASSERT_TRUE(parse_segment_id(result.tracked_lines[1].id, base, from, to)) << result.tracked_lines[1].id;
    EXPECT_EQ(base, "in-1");
    // Particles of the second segment enter at its start; their positions
    // (relative to the segment) follow the truth shifted by the travel time to it.
    int checked = 0;
    double worst = 0.0;
    for (const auto& p : result.bank.particles) {
        if (p.line_id != result.tracked_lines[1].id) continue;
        const double entry = p.start_frame - truth.travel_frames(from);
        for (int a = 0; a < p.life_frames(); ++a) {
            const double expected = truth.arc_at(entry, truth.travel_frames(from) + a) - from;
            worst = std::max(worst, std::fabs(p.arc_length_px[static_cast<std::size_t>(a)] - expected));
            ++checked;
        }
    }
    EXPECT_GT(checked, 20);
    EXPECT_LT(worst, 1.5);
}

TEST(FlowTracking, RealWaterfallTracksWithHighCorrelation) {
    const std::string capture_dir = flowvid::testing::shared_path("captures/video-waterfall-cascade");
    if (!std::filesystem::exists(capture_dir)) GTEST_SKIP() << "no shared captures";
    const formats::Capture capture = open_clip(capture_dir);
    const formats::FlowLineSet drawing = formats::import_flowlines_svg(capture.resolve(capture.flowlines));
    CaptureFrames frames(capture, 60);
    TrackingSettings settings;
    std::vector<formats::FlowLine> lines = {drawing.inputs[2], drawing.inputs[3]};  // in-3, in-4: full-height falls
    const TrackingResult result = track_particles(frames, lines, settings);
    // The water here moves 0.1 .. 2 px/frame, too slow to cross a whole line in
    // the clip: the lines are cut, static stretches (rocks) are left out.
    int with_particles = 0;
    for (const LineTrackingStats& s : result.report.lines) {
        std::printf("waterfall %s: %d/%d complete, speed %.2f px/frame, NCC %.3f, uncertain %d/%d, life %.1f\n",
                    s.id.c_str(), s.completed, s.started, s.mean_speed_px_per_frame, s.mean_correlation,
                    s.uncertain_steps, s.steps, s.mean_life_frames);
        if (s.completed == 0) continue;
        ++with_particles;
        EXPECT_GT(s.mean_correlation, 0.7) << s.id;
        EXPECT_LT(s.uncertain_steps, s.steps / 10 + 1) << s.id;
        EXPECT_GT(s.mean_speed_px_per_frame, 0.1) << s.id;
        EXPECT_LT(s.mean_speed_px_per_frame, 3.0) << s.id;
    }
    EXPECT_GE(with_particles, 8);
}

// flow::track_clip is the pipeline `flowvid track` runs: the same bank as its
// steps taken by hand (patch from the drawing, the camera's drift undone into
// the central view with the lines carried there, lines densified two patches
// apart), and it says what it chose.
TEST(FlowTrackingJob, TracksAsItsStepsByHandAndSaysWhatItChose) {
    const std::string capture_dir = flowvid::testing::shared_path("captures/video-waterfall-cascade");
    if (!std::filesystem::exists(capture_dir)) GTEST_SKIP() << "no shared captures";
    const formats::Capture capture = open_clip(capture_dir);
    const formats::FlowLineSet drawing = formats::import_flowlines_svg(capture.resolve(capture.flowlines));
    const int frame_count = 12;

    const int patch_px = patch_size_from_lines(drawn_input_polylines(drawing)).patch_px;
    TrackingSettings settings;
    settings.patch_size_px = patch_px;
    settings.max_path_frames = frame_count;
    CaptureFrames frames(capture, frame_count);
    const CameraMotion camera = estimate_camera_motion(frames, drawn_input_polylines(drawing));
    ASSERT_FALSE(camera.still());
    StabilisedFrames stabilised(frames, camera);
    // The lines drawn on the first frame, carried into the clip's central view.
    const std::vector<formats::FlowLine> lines =
        densify_input_lines(drawing_in_view(drawing, camera), 2.0 * patch_px, 6.0 * patch_px);
    const TrackingResult by_hand = track_particles(stabilised, lines, settings);

    TrackingJob job;
    job.drawing = drawing;
    job.drawing_name = "flowlines.svg";
    job.settings.max_path_frames = frame_count;
    job.settings.patch_size_px = 0;  // chosen from the drawing
    CaptureFrames again(capture, frame_count);
    std::vector<std::string> messages;
    std::vector<std::string> stages;
    const TrackingOutcome outcome = track_clip(again, job, [&](const flowvid::ProgressReport& r) {
        if (r.fraction < 0.0) messages.push_back(r.message);
        else if (stages.empty() || stages.back() != r.stage) stages.push_back(r.stage);
        return true;
    });
    EXPECT_EQ(outcome.patch_px, patch_px);
    EXPECT_DOUBLE_EQ(outcome.densify_px, 2.0 * patch_px);
    ASSERT_EQ(outcome.lines.size(), lines.size());
    for (std::size_t i = 0; i < lines.size(); ++i) EXPECT_EQ(outcome.lines[i].points, lines[i].points) << lines[i].id;
    EXPECT_EQ(outcome.camera.largest_offset_px, camera.largest_offset_px);
    // The bank keeps the view it was tracked in (its maps are ECC's floats).
    ASSERT_TRUE(outcome.result.bank.camera.has_value());
    EXPECT_EQ(*outcome.result.bank.camera, to_bank_camera(camera));
    const CameraMotion kept = from_bank_camera(*outcome.result.bank.camera);
    EXPECT_EQ(kept.view_frame, camera.view_frame);
    for (std::size_t f = 0; f < camera.first_to_frame.size(); ++f)
        EXPECT_EQ(kept.first_to_frame[f], camera.first_to_frame[f]) << "frame " << f;
    ASSERT_EQ(outcome.result.bank.particles.size(), by_hand.bank.particles.size());
    for (std::size_t i = 0; i < by_hand.bank.particles.size(); ++i)
        EXPECT_EQ(outcome.result.bank.particles[i].arc_length_px, by_hand.bank.particles[i].arc_length_px) << i;
    EXPECT_EQ(stages, (std::vector<std::string>{"camera drift", "track"}));
    ASSERT_GE(messages.size(), 3u);
    EXPECT_EQ(messages[0].rfind("patch: " + std::to_string(patch_px) + " px", 0), 0u) << messages[0];
    EXPECT_EQ(messages[1].rfind("densify: ", 0), 0u) << messages[1];
    EXPECT_EQ(messages.back(), describe(camera));
}
