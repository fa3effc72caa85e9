// Frames for flow-based video: colour encodings, clips from image patterns
// and video files, the median plate, backgrounds and the frame writer.

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

using namespace flowvid;
using namespace flowvid::flow;
namespace fs = std::filesystem;

namespace {

RgbImage gradient(int w, int h, float offset) {
    RgbImage image(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float* p = image.pixel(x, y);
            p[0] = std::fmod(offset + 0.01f * x, 1.0f);
            p[1] = 0.02f * y;
            p[2] = 0.5f;
        }
    return image;
}

}  // namespace

TEST(FlowFrames, SrgbEncodingRoundTripsTo8Bits) {
    for (int i = 0; i <= 255; ++i) {
        const float encoded = i / 255.0f;
        const float back = linear_to_srgb(srgb_to_linear(encoded));
        EXPECT_EQ(std::lround(back * 255.0f), i) << i;
    }
    EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.21404f, 1e-5f);
    EXPECT_NEAR(linear_to_srgb(0.21404f), 0.5f, 2e-4f);
}

TEST(FlowFrames, PatternsFoldersAndVideos) {
    const std::string dir = flowvid::testing::scratch_dir("flow_frames2");
    EXPECT_THROW(FrameWriter(dir + "/missing/%03d.png", 32, 24, 25.0), IoError);
    EXPECT_THROW(FrameWriter(dir + "/still.png", 32, 24, 25.0), IoError);  // no frame number
    {
        FrameWriter writer(dir + "/seq", 32, 24, 25.0);  // a folder: seq/%06d.png
        for (int f = 1; f <= 3; ++f) writer.write(f, to_linear(gradient(32, 24, 0.1f * f)));
        EXPECT_EQ(writer.path_of(2), dir + "/seq/000002.png");
    }
    const formats::Capture pattern = open_clip(dir + "/seq/%06d.png");
    EXPECT_EQ(pattern.frames.first, 1);
    EXPECT_EQ(pattern.frames.count, 3);
    EXPECT_DOUBLE_EQ(pattern.fps, 25.0);
    CaptureFrames frames(pattern);
    ASSERT_EQ(frames.count(), 3);
    const RgbImage second = frames.frame(1);
    const RgbImage expected = gradient(32, 24, 0.2f);
    for (int x = 0; x < 32; x += 7)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(second.pixel(x, 5)[c], expected.pixel(x, 5)[c], 0.6f / 255.0f);

    // EXR frames keep linear values.
    {
        FrameWriter writer(dir + "/lin_%02d.exr", 32, 24, 25.0);
        writer.write(7, to_linear(gradient(32, 24, 0.0f)));
    }
    const RgbImage exr = read_image_linear(dir + "/lin_07.exr");
    EXPECT_NEAR(exr.pixel(10, 10)[0], srgb_to_linear(0.1f), 1e-3f);

    // A video file round trip (lossy codec: loose threshold).
    {
        // A writer dropped before close() (an error, Ctrl-C) publishes nothing.
        FrameWriter dropped(dir + "/clip.avi", 32, 24, 25.0);
        dropped.write(1, to_linear(gradient(32, 24, 0.0f)));
    }
    EXPECT_FALSE(fs::exists(dir + "/clip.avi"));
    for (const fs::directory_entry& entry : fs::directory_iterator(dir))
        EXPECT_NE(entry.path().filename().string().rfind(".clip", 0), 0u) << "temporary file left: " << entry.path();
    {
        FrameWriter writer(dir + "/clip.avi", 32, 24, 25.0);
        EXPECT_TRUE(writer.is_video());
        for (int f = 1; f <= 5; ++f) writer.write(f, to_linear(gradient(32, 24, 0.0f)));
        writer.close();  // publishes the video under its name
    }
    const formats::Capture video = open_clip(dir + "/clip.avi");
    EXPECT_EQ(video.frames.count, 5);
    CaptureFrames decoded(video);
    EXPECT_NEAR(decoded.frame(2).pixel(16, 12)[2], 0.5f, 0.05f);

    const std::string message = [&] {
        try {
            open_clip(dir + "/nothing-here");
        } catch (const IoError& e) {
            return std::string(e.what());
        }
        return std::string();
    }();
    EXPECT_NE(message.find("nothing-here"), std::string::npos) << message;
}

TEST(FlowFrames, MedianPlateIgnoresWhatMoves) {
    // A bright square crossing a still gradient: the median is the gradient.
    ClipFrames clip(40, 20, 25.0, "memory");
    for (int t = 0; t < 9; ++t) {
        RgbImage frame = gradient(40, 20, 0.0f);
        for (int y = 5; y < 10; ++y)
            for (int x = 4 * t; x < 4 * t + 5 && x < 40; ++x)
                for (int c = 0; c < 3; ++c) frame.pixel(x, y)[c] = 1.0f;
        clip.append(frame);
    }
    const RgbImage plate = median_plate(clip);
    const RgbImage still = to_linear(gradient(40, 20, 0.0f));
    for (int x = 0; x < 40; x += 3)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(plate.pixel(x, 7)[c], still.pixel(x, 7)[c], 1e-4f) << x;
    const Background looped = Background::looped(std::make_shared<ClipFrames>(clip));
    RgbImage out;
    looped.fill(11, 40, 20, out);  // output frame 11 -> clip frame 10 mod 9 = 1
    EXPECT_EQ(out.rgb, clip.linear(1).rgb);
}

TEST(FlowFrames, QuantilePlatePicksTheRankedSampleOfEveryPixel) {
    // Ten frames of one grey each, in shuffled order: the plate at quantile q
    // is the frame of rank round(q * 9), in linear values.
    const std::vector<int> order{7, 2, 9, 0, 5, 3, 8, 1, 6, 4};
    ClipFrames clip(6, 4, 25.0, "memory");
    for (int grey : order) {
        RgbImage frame(6, 4);
        std::fill(frame.rgb.begin(), frame.rgb.end(), 0.05f + 0.1f * static_cast<float>(grey));
        clip.append(frame);
    }
    const auto frame_of_grey = [&](int grey) {
        return static_cast<int>(std::find(order.begin(), order.end(), grey) - order.begin());
    };
    for (const auto& [quantile, rank] : std::vector<std::pair<double, int>>{{0.0, 0}, {0.1, 1}, {0.5, 5}, {1.0, 9}}) {
        const RgbImage plate = quantile_plate(clip, quantile);
        const float expected = clip.linear(frame_of_grey(rank)).rgb[0];
        for (float v : plate.rgb) ASSERT_EQ(v, expected) << "quantile " << quantile;
    }
    EXPECT_EQ(moving_layer_still_plate(clip).rgb, quantile_plate(clip, kMovingLayerStillQuantile).rgb);
}
