// Camera drift (issue #30): a clip whose camera drifts by known sub-pixel
// amounts while "water" churns along a line. The estimate must find the
// drift (not the water's motion), the stabilised frames must show the view
// of the clip's central frame (the drawing carried into it), and a still
// camera must leave the frames bit for bit as they were, even with
// flickering light in the flow.

#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

constexpr int kWidth = 160, kHeight = 120;

// A smooth, richly textured scene (sums of sinusoids) seen with the camera
// moved by `shift` (the scene point x appears at x + shift), with noise that
// changes every frame in a band around x = 80 (the flow) whose brightness
// flickers by `flicker`.
RgbImage scene_frame(Eigen::Vector2d shift, int frame, double flicker) {
    RgbImage image(kWidth, kHeight);
    std::mt19937 noise(static_cast<unsigned>(frame) + 1);
    std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
    const double gain = 1.0 + flicker * std::sin(0.9 * frame);
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            const double sx = x - shift.x(), sy = y - shift.y();
            double value = 0.5 + 0.12 * std::sin(0.21 * sx + 0.7) * std::cos(0.17 * sy) + 0.08 * std::sin(0.05 * sx * 1.3 + 0.11 * sy) +
                           0.06 * std::cos(0.33 * sy + 0.13 * sx);
            if (std::abs(x - 80) < 14) value = 0.3 + 0.4 * uniform(noise) * gain;  // the flow: new every frame
            for (int c = 0; c < 3; ++c) image.pixel(x, y)[c] = static_cast<float>(std::clamp(value, 0.0, 1.0));
        }
    return image;
}

const std::vector<std::vector<Eigen::Vector2d>> kLine = {{Eigen::Vector2d(80, 0), Eigen::Vector2d(80, kHeight - 1)}};

// The drawing of kLine: one input line, "in-1", on the whole frame.
formats::FlowLineSet line_drawing() {
    formats::FlowLineSet drawing;
    drawing.width = kWidth;
    drawing.height = kHeight;
    formats::FlowLine line;
    line.id = "in-1";
    line.points = kLine.front();
    drawing.inputs.push_back(line);
    return drawing;
}

CameraMotionSettings small_frame_settings() {
    CameraMotionSettings settings;
    settings.exclude_around_lines_px = 24.0;  // the flow band is 14 px either side of the line
    return settings;
}

}  // namespace

TEST(CameraDrift, FindsASubPixelDriftAroundTheFlowAndUndoesIt) {
    std::vector<Eigen::Vector2d> shifts;
    std::vector<RgbImage> frames;
    for (int i = 0; i < 12; ++i) {
        shifts.emplace_back(0.45 * i, -0.2 * i + 0.03 * i * i);  // up to 5 px sideways
        frames.push_back(scene_frame(shifts.back(), i, 0.0));
    }
    MemoryFrames clip(frames, 25.0);
    const CameraMotion motion = estimate_camera_motion(clip, kLine, small_frame_settings());
    ASSERT_FALSE(motion.still());
    ASSERT_EQ(motion.first_to_frame.size(), frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
        // The first frame's pixel x is where the frame shows x + shift, at
        // every corner and the centre, within about a tenth of a pixel.
        for (const Eigen::Vector2d& x : {Eigen::Vector2d(0, 0), Eigen::Vector2d(kWidth - 1, kHeight - 1),
                                         Eigen::Vector2d(kWidth / 2, kHeight / 2), Eigen::Vector2d(0, kHeight - 1)}) {
            const Eigen::Vector2d seen = motion.first_to_frame[i].leftCols<2>() * x + motion.first_to_frame[i].col(2);
            EXPECT_NEAR((seen - x - shifts[i]).norm(), 0.0, 0.12) << "frame " << i << " at " << x.transpose() << ", "
                                                                   << to_string(motion.model);
        }
    }
    EXPECT_NEAR(motion.largest_offset_px, shifts.back().norm(), 0.1);

    // The view is the middle of the drift: the frame whose camera is nearest
    // every other's (the drift is nearly even, so frame 5 or 6 of 0..11).
    EXPECT_GE(motion.view_frame, 5);
    EXPECT_LE(motion.view_frame, 6);
    const RgbImage& view = frames[static_cast<std::size_t>(motion.view_frame)];

    // Stabilised, the first and the last frame show the view frame's scene
    // away from the flow and the borders.
    StabilisedFrames stabilised(clip, motion);
    for (int index : {0, 11}) {
        const RgbImage seen = stabilised.frame(index);
        const RgbImage& filmed = frames[static_cast<std::size_t>(index)];
        double sum = 0.0, drifting = 0.0;
        int n = 0;
        for (int y = 8; y < kHeight - 8; ++y)
            for (int x = 8; x < kWidth - 8; ++x) {
                if (std::abs(x - 80) < 22) continue;  // the flow band, wherever the camera put it
                sum += std::pow(seen.pixel(x, y)[0] - view.pixel(x, y)[0], 2.0);
                drifting += std::pow(filmed.pixel(x, y)[0] - view.pixel(x, y)[0], 2.0);
                ++n;
            }
        EXPECT_LT(std::sqrt(sum / n), 0.004) << index;      // about 1/250 of the range: resampling only
        EXPECT_GT(std::sqrt(drifting / n), 0.02) << index;  // and the drift was plain to see
    }

    // The last frame saw the view's pixels from x + 2.2 or more: its right-most
    // 2 columns it did not see at all. They show the view frame there, not the
    // frame's own border column repeated (which differs from it).
    const RgbImage last = stabilised.frame(11);
    double unseen_error = 0.0, repeated_border = 0.0;
    for (int y = 20; y < kHeight - 20; ++y)
        for (int x = kWidth - 2; x < kWidth; ++x) {
            unseen_error = std::max(unseen_error, static_cast<double>(std::fabs(last.pixel(x, y)[0] - view.pixel(x, y)[0])));
            repeated_border = std::max(repeated_border, static_cast<double>(std::fabs(
                                                            frames.back().pixel(kWidth - 1, y)[0] - view.pixel(x, y)[0])));
        }
    EXPECT_LT(unseen_error, 1e-6);
    EXPECT_GT(repeated_border, 0.05);

    // Lines drawn on the first frame are carried into the view with the
    // scene, and back.
    formats::FlowLineSet drawing;
    formats::FlowLine input, output;
    input.id = "in-1";
    input.points = {Eigen::Vector2d(30, 10), Eigen::Vector2d(40, 100)};
    output.id = "out-1";
    output.from = "in-1";
    output.keys = {{1, {Eigen::Vector2d(50, 20), Eigen::Vector2d(60, 90)}}};
    drawing.inputs = {input};
    drawing.outputs = {output};
    const formats::FlowLineSet in_view = drawing_in_view(drawing, motion);
    const Eigen::Vector2d view_shift = shifts[static_cast<std::size_t>(motion.view_frame)];
    EXPECT_NEAR((in_view.inputs[0].points[1] - input.points[1] - view_shift).norm(), 0.0, 0.12);
    EXPECT_NEAR((in_view.outputs[0].keys[0].points[0] - output.keys[0].points[0] - view_shift).norm(), 0.0, 0.12);
    const auto back = polylines_as_drawn({in_view.inputs[0].points}, motion);
    EXPECT_NEAR((back[0][0] - input.points[0]).norm(), 0.0, 1e-9);
    const formats::FlowLineSet as_drawn = drawing_as_drawn(in_view, motion);
    EXPECT_NEAR((as_drawn.outputs[0].keys[0].points[1] - output.keys[0].points[1]).norm(), 0.0, 1e-9);

    // Asked for the first frame's view, the frames are brought into it.
    CameraMotionSettings first_view = small_frame_settings();
    first_view.view = CameraMotionSettings::View::first_frame;
    const CameraMotion from_first = estimate_camera_motion(clip, kLine, first_view);
    EXPECT_EQ(from_first.view_frame, 0);
    EXPECT_EQ(drawing_in_view(drawing, from_first), drawing);
}

TEST(CameraDrift, AStillCameraWithFlickeringFlowLeavesTheFramesUnchanged) {
    std::vector<RgbImage> frames;
    for (int i = 0; i < 10; ++i) frames.push_back(scene_frame(Eigen::Vector2d::Zero(), i, 0.5));
    MemoryFrames clip(frames, 25.0);
    const CameraMotion motion = estimate_camera_motion(clip, kLine, small_frame_settings());
    EXPECT_TRUE(motion.still()) << describe(motion);
    EXPECT_LT(motion.largest_offset_px, 0.05);
    StabilisedFrames stabilised(clip, motion);
    for (int i = 0; i < 10; ++i) EXPECT_EQ(stabilised.frame(i).rgb, frames[static_cast<std::size_t>(i)].rgb);

    // The same through the in-memory reader synth and quality use.
    const formats::FlowLineSet drawing = line_drawing();
    CameraMotion read_motion;
    const ClipFrames read = read_clip_stabilised(clip, drawing, read_motion);
    EXPECT_TRUE(read_motion.still());
    EXPECT_EQ(read.count(), 10);
}

// A bank stores the view it was tracked in (particle bank 1.1): synthesis
// replays it in exactly that view without estimating the drift again (the
// estimate reads the whole clip), and a bank without one (1.0) has the drift
// estimated from the clip, as before.
TEST(CameraDrift, SynthesisReplaysABankInTheViewItWasTrackedIn) {
    const std::string dir = flowvid::testing::scratch_dir("drift_bank");
    std::filesystem::create_directories(dir + "/frames");
    std::vector<Eigen::Vector2d> shifts;
    std::vector<RgbImage> frames;
    for (int i = 0; i < 12; ++i) {
        shifts.emplace_back(0.45 * i, -0.2 * i + 0.03 * i * i);
        frames.push_back(scene_frame(shifts.back(), i, 0.0));
        char name[64];
        std::snprintf(name, sizeof name, "/frames/%04d.png", i + 1);
        write_image(dir + name, to_linear(frames.back()));
    }
    flowvid::testing::write_text(dir + "/capture.json", R"({
  "format": "flowvid.capture", "version": 1, "kind": "video.flow", "fps": 25,
  "frames": {"pattern": "frames/%04d.png", "first": 1, "count": 12},
  "flowlines": "lines.json",
  "source": {"origin": "procedural scene of flowvid's tests", "licence": "CC0"}
})");
    const formats::FlowLineSet drawing = line_drawing();
    formats::write_flowline_set(dir + "/lines.json", drawing);

    // A bank whose stored view is frame 2 with the drift halved: no estimate
    // of this clip gives that, so a synthesis that shows it read the bank.
    formats::ParticleBank bank;
    bank.patch_size_px = 8;
    bank.fps = 25.0;
    bank.clip_width_px = kWidth;
    bank.clip_height_px = kHeight;
    bank.clip_frame_count = 12;
    bank.source_clip = dir;
    bank.lines.push_back({"in-1", static_cast<float>(kHeight - 1)});
    for (int p = 0; p < 4; ++p) {
        formats::TrackedParticle particle;
        particle.line_id = "in-1";
        particle.start_frame = 2 * p;
        for (int a = 0; a < 4; ++a) {
            particle.arc_length_px.push_back(10.0f + 25.0f * a);
            for (int t = 0; t < 64; ++t) particle.texture_rgba.insert(particle.texture_rgba.end(), {0.6f, 0.7f, 0.8f, 1.0f});
        }
        bank.particles.push_back(particle);
    }
    formats::BankCamera stored;
    stored.model = formats::BankCameraModel::translation;
    stored.view_frame = 2;
    for (const Eigen::Vector2d& shift : shifts)
        stored.first_to_frame.push_back({1.0f, 0.0f, static_cast<float>(0.5 * shift.x()), 0.0f, 1.0f, static_cast<float>(0.5 * shift.y())});
    stored.largest_offset_px = 2.7f;
    stored.worst_correlation = 0.97f;
    bank.camera = stored;
    formats::write_particle_bank(dir + "/bank.exr", bank);

    SynthesisJob job;
    job.bank_path = dir + "/bank.exr";
    job.flowlines_path = dir + "/lines.json";
    job.background = "median";  // the clip is read
    const PreparedSynthesis replayed = prepare_synthesis(job);
    ASSERT_TRUE(replayed.camera.has_value());
    EXPECT_EQ(to_bank_camera(*replayed.camera), stored);  // bit for bit
    // The drawing is carried into the stored view: frame 2's half drift.
    EXPECT_NEAR((replayed.drawing.inputs[0].points[0] - kLine.front()[0] - 0.5 * shifts[2]).norm(), 0.0, 1e-6);

    // Without a camera (a 1.0 bank) the drift is estimated: the whole drift,
    // seen from the middle of its path.
    bank.camera.reset();
    formats::write_particle_bank(dir + "/bank.exr", bank);
    const PreparedSynthesis estimated = prepare_synthesis(job);
    ASSERT_TRUE(estimated.camera.has_value());
    EXPECT_FALSE(estimated.camera->still());
    EXPECT_GE(estimated.camera->view_frame, 5);
    EXPECT_LE(estimated.camera->view_frame, 6);
    EXPECT_NEAR(estimated.camera->first_to_frame[11](0, 2), shifts[11].x(), 0.15);

    // A still camera stored with the bank is used as filmed, estimated or not.
    bank.camera = formats::BankCamera();
    formats::write_particle_bank(dir + "/bank.exr", bank);
    const PreparedSynthesis still = prepare_synthesis(job);
    ASSERT_TRUE(still.camera.has_value());
    EXPECT_TRUE(still.camera->still());
    EXPECT_EQ(still.drawing.inputs[0].points, kLine.front());
}
