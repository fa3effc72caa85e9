// Input flow lines proposed from dense optical flow (auto_lines.hpp), against
// procedural clips whose motion is known (flow/synthetic.hpp): a textured
// band that flows down (or up) at 2 px/frame through a still texture. The
// lines must lie in the band, run with the flow, report its speed, and be the
// same run after run. Plus the line distance measure by hand, and the
// streamline tracer on a uniform field.

#include "flowvid/flow/auto_lines.hpp"
#include "flowvid/flow/synthetic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

using Polylines = std::vector<std::vector<Eigen::Vector2d>>;

constexpr double kBandCentreX = 80.0;
constexpr double kBandHalfWidthPx = 32.0;
constexpr double kSpeedPxPerFrame = 2.0;

// 160 x 120, 40 frames: the band |x - 80| <= 32 flows along y (down when
// `downward`), the rest is still; texture features of `feature_px`.
SyntheticFlow vertical_band(bool downward, double feature_px = 3.0) {
    SyntheticFlowSpec spec;
    spec.width = 160;
    spec.height = 120;
    spec.frames = 40;
    if (downward)
        spec.curve = {{kBandCentreX, -40.0}, {kBandCentreX, 160.0}};
    else
        spec.curve = {{kBandCentreX, 160.0}, {kBandCentreX, -40.0}};
    spec.band_px = kBandHalfWidthPx;
    spec.speed_px_per_frame = [](double) { return kSpeedPxPerFrame; };
    spec.feature_px = feature_px;
    spec.seed = 7;
    return SyntheticFlow(spec);
}

Polylines points_of(const formats::FlowLineSet& set) {
    Polylines out;
    for (const formats::FlowLine& line : set.inputs) out.push_back(line.points);
    return out;
}

// Checks the proposal for a band flowing down (sign +1) or up (-1).
void expect_lines_along_band(const AutoLines& result, double sign) {
    const Polylines lines = points_of(result.drawing);
    ASSERT_GE(lines.size(), 2u);  // the band is wider than two spacings
    EXPECT_EQ(result.drawing.width, 160);
    EXPECT_EQ(result.drawing.height, 120);
    double total_length = 0.0;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const std::vector<Eigen::Vector2d>& line = lines[i];
        EXPECT_EQ(result.drawing.inputs[i].id, "auto-" + std::to_string(i + 1));
        ASSERT_GE(line.size(), 2u);
        // Inside the band; 3 px for the mask's smoothing at its edge.
        for (const Eigen::Vector2d& p : line) EXPECT_LE(std::fabs(p.x() - kBandCentreX), kBandHalfWidthPx + 3.0) << p.transpose();
        // With the flow: the first point upstream, the chord within 10 degrees of it.
        const Eigen::Vector2d chord = line.back() - line.front();
        EXPECT_GT(sign * chord.y(), 0.0) << "line " << i << " runs against the flow";
        EXPECT_LT(std::atan2(std::fabs(chord.x()), sign * chord.y()) * 180.0 / M_PI, 10.0);
        total_length += formats::polyline_length(line);
    }
    // The band crosses the whole frame: the lines cover most of its length.
    EXPECT_GE(total_length, 0.8 * 120.0);
    // Close to the band's centre line, relative to its half-width.
    const Polylines centre{{{kBandCentreX, 0.0}, {kBandCentreX, 119.0}}};
    const double to_centre = mean_distance_to_lines(lines, centre);
    std::printf("%zu lines, %.1f px total, %.2f px from the centre line, spacing %.1f px, min speed %.3f, median speed "
                "%.3f px/frame, flow area %.3f\n",
                lines.size(), total_length, to_centre, result.spacing_px, result.min_speed_px_per_frame,
                result.median_speed_px_per_frame, result.flow_area_share);
    EXPECT_LE(to_centre, 0.6 * kBandHalfWidthPx);

    // Speed statistics: the band's true speed, and the region about its share (64 / 160).
    EXPECT_NEAR(result.median_speed_px_per_frame, kSpeedPxPerFrame, 0.15 * kSpeedPxPerFrame);
    EXPECT_GT(result.min_speed_px_per_frame, 0.0);
    EXPECT_LT(result.min_speed_px_per_frame, 0.5 * kSpeedPxPerFrame);
    EXPECT_NEAR(result.flow_area_share, 0.4, 0.05);
    EXPECT_EQ(result.frame_pairs, 39);
    EXPECT_GE(result.spacing_px, 24.0);
    EXPECT_LE(result.spacing_px, 128.0);
}

}  // namespace

TEST(AutoLines, LinesFollowADownwardBandAndReportItsSpeed) {
    MemoryFrames clip = vertical_band(true).clip();
    expect_lines_along_band(propose_input_lines(clip), +1.0);
}

TEST(AutoLines, LinesOfAnUpwardFlowStartAtTheBottom) {
    MemoryFrames clip = vertical_band(false).clip();
    expect_lines_along_band(propose_input_lines(clip), -1.0);
}

// Measured on frames scaled down by two (a coarser texture, so that it
// survives): positions and speeds still in the clip's pixels.
TEST(AutoLines, AnalysisAtHalfSizeReportsFullSizePixels) {
    MemoryFrames clip = vertical_band(true, 6.0).clip();
    AutoLineSettings settings;
    settings.analysis_short_side_px = 60;
    expect_lines_along_band(propose_input_lines(clip, settings), +1.0);
}

TEST(AutoLines, SameClipGivesTheSameLines) {
    MemoryFrames clip = vertical_band(true).clip();
    const AutoLines a = propose_input_lines(clip);
    const AutoLines b = propose_input_lines(clip);
    EXPECT_EQ(a.drawing, b.drawing);  // bit for bit
    EXPECT_EQ(a.spacing_px, b.spacing_px);
    EXPECT_EQ(a.min_speed_px_per_frame, b.min_speed_px_per_frame);
    EXPECT_EQ(a.median_speed_px_per_frame, b.median_speed_px_per_frame);
    EXPECT_EQ(a.flow_area_share, b.flow_area_share);
}

TEST(AutoLines, GivenSettingsAreUsed) {
    MemoryFrames clip = vertical_band(true).clip();
    AutoLineSettings settings;
    settings.spacing_px = 30.0;
    settings.min_speed_px_per_frame = 1.0;
    settings.max_frames = 21;
    settings.step_frames = 2;
    const AutoLines result = propose_input_lines(clip, settings);
    EXPECT_EQ(result.spacing_px, 30.0);
    EXPECT_EQ(result.min_speed_px_per_frame, 1.0);
    EXPECT_EQ(result.frame_pairs, 19);  // pairs (0, 2) .. (18, 20)
    // Speeds stay per frame with a step of two.
    EXPECT_NEAR(result.median_speed_px_per_frame, kSpeedPxPerFrame, 0.15 * kSpeedPxPerFrame);
    EXPECT_FALSE(result.drawing.inputs.empty());
}

TEST(AutoLines, AStillClipGetsNoLines) {
    const RgbImage still = vertical_band(true).frame(0);
    MemoryFrames clip(std::vector<RgbImage>(6, still), 25.0);
    const AutoLines result = propose_input_lines(clip);
    EXPECT_TRUE(result.drawing.inputs.empty());
    EXPECT_EQ(result.flow_area_share, 0.0);
    EXPECT_EQ(result.median_speed_px_per_frame, 0.0);
}

TEST(AutoLines, ProgressCanCancelAndReachesOne) {
    MemoryFrames clip = vertical_band(true).clip();
    EXPECT_THROW(propose_input_lines(clip, {}, [](const flowvid::ProgressReport&) { return false; }), flowvid::Cancelled);
    std::vector<double> fractions;
    propose_input_lines(clip, {}, [&](const flowvid::ProgressReport& r) {
        EXPECT_EQ(r.stage, "optical flow");
        fractions.push_back(r.fraction);
        return true;
    });
    ASSERT_FALSE(fractions.empty());
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    EXPECT_GT(fractions.front(), 0.0);
    EXPECT_EQ(fractions.back(), 1.0);
}

TEST(AutoLines, RejectsTooShortClipsAndBadSettings) {
    MemoryFrames one(std::vector<RgbImage>(1, RgbImage(32, 32, 0.5f)), 25.0);
    EXPECT_THROW(propose_input_lines(one), std::invalid_argument);
    MemoryFrames three(std::vector<RgbImage>(3, RgbImage(32, 32, 0.5f)), 25.0);
    AutoLineSettings settings;
    settings.step_frames = 3;  // needs 4 frames
    EXPECT_THROW(propose_input_lines(three, settings), std::invalid_argument);
    settings = {};
    settings.spacing_px = -1.0;
    EXPECT_THROW(propose_input_lines(three, settings), std::invalid_argument);
}

// ---- the distance between line sets --------------------------------------------------

TEST(AutoLines, MeanDistanceOfParallelSegmentsIsTheirGap) {
    const Polylines a{{{0.0, 0.0}, {10.0, 0.0}}};
    const Polylines b{{{0.0, 5.0}, {10.0, 5.0}}};
    EXPECT_NEAR(mean_distance_to_lines(a, b), 5.0, 1e-12);
    EXPECT_NEAR(mean_distance_to_lines(b, a), 5.0, 1e-12);
}

TEST(AutoLines, MeanDistanceByHand) {
    // Samples of `from` at x = 0, 2, ..., 10; `to` covers x = 0 .. 5 at y = 5:
    // distances 5, 5, 5, sqrt(26), sqrt(34), sqrt(50).
    const Polylines from{{{0.0, 0.0}, {10.0, 0.0}}};
    const Polylines to{{{0.0, 5.0}, {5.0, 5.0}}};
    const double expected = (15.0 + std::sqrt(26.0) + std::sqrt(34.0) + std::sqrt(50.0)) / 6.0;  // 5.48351...
    EXPECT_NEAR(mean_distance_to_lines(from, to), expected, 1e-12);
    // Back: samples at x = 0, 2, 4, 5 are all 5 px away.
    EXPECT_NEAR(mean_distance_to_lines(to, from), 5.0, 1e-12);
    // A last sample at the end point when the length is no multiple of the step:
    // 0..3 with step 2 samples x = 0, 2, 3 against the point (0, 4): 4, sqrt(20), 5.
    const Polylines short_line{{{0.0, 0.0}, {3.0, 0.0}}};
    const Polylines point{{{0.0, 4.0}}};
    EXPECT_NEAR(mean_distance_to_lines(short_line, point), (4.0 + std::sqrt(20.0) + 5.0) / 3.0, 1e-12);
    // Nearest of several lines.
    const Polylines two{{{0.0, 5.0}, {10.0, 5.0}}, {{0.0, -1.0}, {10.0, -1.0}}};
    EXPECT_NEAR(mean_distance_to_lines(from, two), 1.0, 1e-12);
}

TEST(AutoLines, MeanDistanceOfNothingIsNaN) {
    const Polylines a{{{0.0, 0.0}, {10.0, 0.0}}};
    EXPECT_TRUE(std::isnan(mean_distance_to_lines(a, {})));
    EXPECT_TRUE(std::isnan(mean_distance_to_lines({}, a)));
    EXPECT_TRUE(std::isnan(mean_distance_to_lines(a, Polylines{{}})));
}

// ---- the streamline tracer --------------------------------------------------------------

TEST(AutoLines, UniformFieldGivesEvenlySpacedParallelLines) {
    detail::FlowField field;
    field.width = 120;
    field.height = 80;
    const std::size_t cells = 120 * 80;
    field.vx.assign(cells, 0.0f);
    field.vy.assign(cells, 1.5f);
    field.mask.assign(cells, 1);
    detail::StreamlineSettings settings;
    settings.separation = 16.0;
    settings.min_length = 32.0;
    const Polylines lines = detail::evenly_spaced_streamlines(field, settings);
    ASSERT_GE(lines.size(), 5u);
    std::vector<double> columns;
    for (const auto& line : lines) {
        for (const Eigen::Vector2d& p : line) EXPECT_NEAR(p.x(), line.front().x(), 1e-9);  // straight down
        EXPECT_LT(line.front().y(), line.back().y());                                       // upstream first
        EXPECT_GE(formats::polyline_length(line), 78.0);                                    // top to bottom
        columns.push_back(line.front().x());
    }
    std::sort(columns.begin(), columns.end());
    // Neighbours at least d_sep apart, and no gap wide enough for another line.
    for (std::size_t i = 1; i < columns.size(); ++i) {
        EXPECT_GE(columns[i] - columns[i - 1], settings.separation - 1e-9);
        EXPECT_LE(columns[i] - columns[i - 1], 1.25 * settings.separation + 1.0);
    }
}

TEST(AutoLines, SimplifyKeepsCornersAndDropsCollinearPoints) {
    std::vector<Eigen::Vector2d> points;
    for (int i = 0; i <= 10; ++i) points.emplace_back(i, 0.0);
    for (int i = 1; i <= 10; ++i) points.emplace_back(10.0, i);
    const std::vector<Eigen::Vector2d> simple = detail::simplify_polyline(points, 0.5);
    ASSERT_EQ(simple.size(), 3u);
    EXPECT_EQ(simple[1], Eigen::Vector2d(10.0, 0.0));
    EXPECT_EQ(simple.back(), Eigen::Vector2d(10.0, 10.0));
}
