// Angle maps (thesis 2.4.3) on synthetic stripes whose orientation is known
// analytically: straight stripes at many angles, noise, curved (circular)
// stripes, and a synthetic fold line for the gradient mask (eq. 2.19).

#include "flowvid/video/angle_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

using namespace flowvid;
using namespace flowvid::video;

namespace {

constexpr double kPi = std::numbers::pi;

// Stripes running along direction `angle` (image coordinates, y down) with
// period `period_px`: intensity varies along the normal (-sin, cos).
ImageF straight_stripes(int width, int height, double angle, double period_px, double phase = 0.3) {
    ImageF image(width, height);
    const double nx = -std::sin(angle), ny = std::cos(angle);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            image.at(x, y) = static_cast<float>(0.5 + 0.5 * std::sin(2.0 * kPi * (nx * x + ny * y) / period_px + phase));
    return image;
}

double degrees(double radians) { return radians * 180.0 / kPi; }

// Largest |error| of the angle map against `truth(x, y)` over valid pixels at
// least `border` pixels inside the image.
template <typename Truth>
double max_error_rad(const AngleMap& map, int border, Truth truth, long long* checked = nullptr) {
    double worst = 0.0;
    long long n = 0;
    for (int y = border; y < map.height - border; ++y)
        for (int x = border; x < map.width - border; ++x) {
            const std::size_t i = map.index(x, y);
            if (!map.valid[i]) continue;
            worst = std::max(worst, std::abs(orientation_difference(static_cast<double>(map.angle_rad[i]), truth(x, y))));
            ++n;
        }
    if (checked) *checked = n;
    return worst;
}

}  // namespace

TEST(AngleMap, OrientationDifferenceWrapsModPi) {
    EXPECT_NEAR(orientation_difference(0.1, kPi - 0.1), 0.2, 1e-12);
    EXPECT_NEAR(orientation_difference(kPi / 2 - 0.05, -kPi / 2 + 0.05), -0.1, 1e-12);
    EXPECT_NEAR(orientation_difference(1.0, 1.0 + 3 * kPi), 0.0, 1e-12);
    EXPECT_NEAR(orientation_difference(0.3f, -0.2f), 0.5f, 1e-6f);
    EXPECT_NEAR(orientation_difference(1.5f, -1.5f), 3.0f - static_cast<float>(kPi), 1e-6f);
}

// Straight stripes at 24 orientations over the half circle, period 12 px (the
// captures' stripes are 10-14 px): the angle is recovered everywhere inside
// to within 0.02 degrees (the steering is exact; what is left comes from the
// pixel sampling of the kernels and float arithmetic).
TEST(AngleMap, RecoversStraightStripesAtEveryOrientation) {
    AngleMapper mapper(AngleMapSettings::for_stripe_period(12.0));
    double worst = 0.0;
    for (int k = 0; k < 24; ++k) {
        const double angle = -kPi / 2 + kPi * (k + 0.5) / 24.0;
        const AngleMap map = mapper.compute(straight_stripes(96, 80, angle, 12.0));
        long long checked = 0;
        worst = std::max(worst, max_error_rad(map, 20, [&](int, int) { return angle; }, &checked));
        EXPECT_GT(checked, 1000);
    }
    std::printf("[measured] straight stripes, 24 orientations: worst error %.4f deg\n", degrees(worst));
    EXPECT_LT(degrees(worst), 0.02) << "worst error " << degrees(worst) << " deg";
}

// The filters work over a range of periods around the tuned one, and the
// coherence of one clean orientation is high.
TEST(AngleMap, ToleratesPeriodMismatchAndReportsCoherence) {
    AngleMapper mapper(AngleMapSettings::for_stripe_period(12.0));
    for (double period : {8.0, 10.0, 16.0, 20.0}) {
        const double angle = 0.35;
        const AngleMap map = mapper.compute(straight_stripes(96, 96, angle, period));
        const double error = degrees(max_error_rad(map, 24, [&](int, int) { return angle; }));
        std::printf("[measured] period %.0f px (filters tuned to 12): worst error %.4f deg, coherence %.3f\n", period,
                    error, map.coherence[map.index(48, 48)]);
        EXPECT_LT(error, 0.1) << "period " << period;
        EXPECT_GT(map.coherence[map.index(48, 48)], 1.0f) << "period " << period;
    }
}

// Sensor noise of sigma 0.05 (ten times the captures' relative noise) moves
// the orientation by well under a degree thanks to the coefficient blur.
TEST(AngleMap, IsRobustToNoise) {
    ImageF image = straight_stripes(120, 100, -0.6, 12.0);
    std::mt19937 rng(7);
    std::normal_distribution<float> noise(0.0f, 0.05f);
    for (float& v : image.pixels) v += noise(rng);
    AngleMapper mapper(AngleMapSettings::for_stripe_period(12.0));
    const AngleMap map = mapper.compute(image);
    const double error = degrees(max_error_rad(map, 20, [](int, int) { return -0.6; }));
    std::printf("[measured] noise sigma 0.05: worst error %.4f deg\n", error);
    EXPECT_LT(error, 1.0);
}

// Concentric circular stripes: the stripe direction is the tangent of the
// circle, angle = atan2(y - cy, x - cx) + pi/2 (mod pi). Away from the centre
// (radius > 3 periods) the error stays below 0.1 degree.
TEST(AngleMap, FollowsCurvedStripes) {
    const int w = 160, h = 160;
    const double cx = 80.3, cy = 79.6, period = 12.0;
    ImageF image(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            image.at(x, y) = static_cast<float>(0.5 + 0.5 * std::sin(2 * kPi * std::hypot(x - cx, y - cy) / period));
    AngleMapper mapper(AngleMapSettings::for_stripe_period(period));
    const AngleMap map = mapper.compute(image);
    double worst = 0.0;
    long long n = 0;
    for (int y = 16; y < h - 16; ++y)
        for (int x = 16; x < w - 16; ++x) {
            const double r = std::hypot(x - cx, y - cy);
            if (r < 3 * period) continue;
            const std::size_t i = map.index(x, y);
            ASSERT_TRUE(map.valid[i]);
            const double truth = std::atan2(y - cy, x - cx) + kPi / 2;
            worst = std::max(worst, std::abs(orientation_difference(static_cast<double>(map.angle_rad[i]), truth)));
            ++n;
        }
    EXPECT_GT(n, 10000);
    std::printf("[measured] circular stripes, r > 3 periods: worst error %.4f deg\n", degrees(worst));
    EXPECT_LT(degrees(worst), 0.1) << "worst " << degrees(worst) << " deg";
    // Curvature 1/r shows as an angle-map gradient of 1/r radians per pixel.
    const std::size_t i = map.index(80 + 50, 80);
    EXPECT_NEAR(map.gradient_rad_per_px[i], 1.0 / std::hypot(130 - cx, 80 - cy), 0.003);
}

// A fold: stripes at +25 degrees left of a vertical line, -25 degrees right of
// it. The gradient mask (eq. 2.19) marks a band along the line and nothing
// in the planar halves; the silhouette restricts the map and its margin.
TEST(AngleMap, GradientMaskHighlightsAFoldLine) {
    const int w = 160, h = 120, fold_x = 80;
    const double a = 25.0 * kPi / 180.0;
    const ImageF left = straight_stripes(w, h, a, 12.0), right = straight_stripes(w, h, -a, 12.0);
    ImageF image(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) image.at(x, y) = x < fold_x ? left.at(x, y) : right.at(x, y);
    metrics::Silhouette silhouette(w, h);
    for (int y = 10; y < h - 10; ++y)
        for (int x = 10; x < w - 10; ++x) silhouette.set(x, y, true);

    AngleMapSettings settings = AngleMapSettings::for_stripe_period(12.0);
    settings.gradient_threshold_rad_per_px = 0.03;
    AngleMapper mapper(settings);
    const AngleMap map = mapper.compute(image, silhouette);

    long long near_fold = 0, near_fold_masked = 0, far_masked = 0, far = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = map.index(x, y);
            if (!silhouette.at(x, y)) {
                EXPECT_FALSE(map.valid[i]);
                continue;
            }
            if (!map.valid[i]) continue;
            const int d = std::abs(x - fold_x);
            if (d <= 2) {
                ++near_fold;
                near_fold_masked += map.gradient_mask[i];
            } else if (d >= 20) {
                ++far;
                far_masked += map.gradient_mask[i];
            }
        }
    EXPECT_GT(near_fold, 300);
    EXPECT_EQ(near_fold_masked, near_fold);  // the whole line is marked
    EXPECT_GT(far, 4000);
    EXPECT_EQ(far_masked, 0);  // the planar halves are not
    // The margin keeps the outline out of the map.
    EXPECT_FALSE(map.valid[map.index(10, 60)]);
    EXPECT_TRUE(map.valid[map.index(10 + settings.edge_margin_px + 1, 60)]);
    // Either side of the fold keeps its own orientation.
    EXPECT_NEAR(map.angle_rad[map.index(40, 60)], a, 0.01);
    EXPECT_NEAR(map.angle_rad[map.index(120, 60)], -a, 0.01);
}

TEST(AngleMap, RejectsMismatchedSizesAndBadSettings) {
    AngleMapper mapper;
    EXPECT_THROW(mapper.compute(ImageF(10, 10), metrics::Silhouette(10, 11)), std::invalid_argument);
    AngleMapSettings bad;
    bad.filter_scale_px = 0.0;
    EXPECT_THROW(AngleMapper{bad}, std::invalid_argument);
    // An empty silhouette gives an empty map, not an error.
    const AngleMap map = mapper.compute(ImageF(10, 10), metrics::Silhouette(10, 10));
    EXPECT_EQ(map.valid_count(), 0);
}
