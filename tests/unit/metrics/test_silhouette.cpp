// Silhouette metrics (thesis eq. 2.5, 2.6) on shapes whose answers are known.

#include "flowvid/metrics/silhouette.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

using namespace flowvid::metrics;

namespace {

Silhouette rectangle(int width, int height, int x0, int y0, int x1, int y1) {
    Silhouette s(width, height);
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) s.set(x, y, true);
    return s;
}

}  // namespace

TEST(SilhouetteMetrics, XorAndIouOfShiftedRectangles) {
    const Silhouette a = rectangle(64, 48, 10, 10, 30, 20);  // 20 x 10
    const Silhouette b = rectangle(64, 48, 13, 10, 33, 20);  // shifted 3 px right
    EXPECT_EQ(a.area_px(), 200);
    EXPECT_EQ(silhouette_xor(a, b), 2 * 3 * 10);
    EXPECT_DOUBLE_EQ(silhouette_iou(a, b), 170.0 / 230.0);
    EXPECT_EQ(silhouette_xor(a, a), 0);
    EXPECT_DOUBLE_EQ(silhouette_iou(Silhouette(64, 48), Silhouette(64, 48)), 1.0);
    EXPECT_THROW(silhouette_xor(a, Silhouette(63, 48)), std::invalid_argument);
}

TEST(SilhouetteMetrics, EdgePixelsAndEdgeDistance) {
    const Silhouette a = rectangle(64, 48, 10, 10, 30, 20);
    // Inner boundary of a 20 x 10 rectangle: 2 * 20 + 2 * 8 pixels.
    EXPECT_EQ(silhouette_edge_pixels(a).size(), 56u);
    // Cut by the image border: no edge along the border unless asked.
    const Silhouette cut = rectangle(64, 48, 0, 10, 20, 20);
    EXPECT_EQ(silhouette_edge_pixels(cut).size(), 2u * 20 + 8);
    EXPECT_EQ(silhouette_edge_pixels(cut, true).size(), 2u * 20 + 2 * 8);

    // Eq. 2.6 for a shift by 2 px to the right. Edge pixels of a and their
    // squared distance to the nearest edge pixel of b:
    //   top and bottom rows: x = 10 -> 4, x = 11 -> 1, x >= 12 on b's rows -> 0: 2 * 5
    //   left column x = 10, rows 11..18: 2 px to b's left column: 8 * 4
    //   right column x = 29, rows 11..18: min(2, distance to b's top or bottom row):
    //   1 + 6 * 4 + 1
    const Silhouette b = rectangle(64, 48, 12, 10, 32, 20);
    const EdgeDistance d = silhouette_edge_distance(a, b);
    EXPECT_EQ(d.edge_pixels, 56);
    EXPECT_NEAR(d.sum_squared_px2, 10.0 + 32.0 + 26.0, 1e-3);
    EXPECT_NEAR(d.mean_squared_px2, 68.0 / 56.0, 1e-6);
    const EdgeDistance both = symmetric_edge_distance(a, b);
    EXPECT_EQ(both.edge_pixels, 112);
    EXPECT_NEAR(silhouette_edge_distance(a, a).sum_squared_px2, 0.0, 1e-9);
}

TEST(SilhouetteMetrics, SignedDistanceIsZeroHalfWayAcrossTheBoundary) {
    const Silhouette a = rectangle(64, 48, 10, 10, 30, 20);
    const DistanceField phi = signed_distance_field(a);
    EXPECT_FLOAT_EQ(phi.at(10, 15), -0.5f);  // first object pixel
    EXPECT_FLOAT_EQ(phi.at(9, 15), 0.5f);    // first background pixel
    EXPECT_FLOAT_EQ(phi.at(20, 15), -(5.0f - 0.5f));
    EXPECT_FLOAT_EQ(phi.at(40, 15), 11.0f - 0.5f);
    Eigen::Vector2d gradient;
    EXPECT_NEAR(phi.sample({9.5, 15.0}, &gradient), 0.0, 1e-6);  // the boundary of the pixel grid
    EXPECT_NEAR(gradient.x(), -1.0, 1e-6);                       // increasing outwards (to the left)
    EXPECT_NEAR(gradient.y(), 0.0, 1e-6);
    EXPECT_NEAR(phi.sample({9.75, 15.0}), -0.25, 1e-6);
    // An empty silhouette is far away everywhere.
    EXPECT_GT(signed_distance_field(Silhouette(64, 48)).at(5, 5), 100.0f);
}

TEST(SilhouetteMetrics, ConvertsImages) {
    flowvid::formats::Image image;
    image.width = 3;
    image.height = 2;
    image.channels = 1;
    image.pixels = {0.0f, 0.49f, 0.5f, 1.0f, 0.2f, 0.9f};
    const Silhouette s = silhouette_from_image(image);
    EXPECT_EQ(s.pixels, (std::vector<std::uint8_t>{0, 0, 1, 1, 0, 1}));
    EXPECT_EQ(silhouette_to_image(s).pixels, (std::vector<float>{0, 0, 1, 1, 0, 1}));
}
