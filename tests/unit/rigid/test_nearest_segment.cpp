// The grid search must give the scan's answer bit for bit: the silhouette
// cost's value and gradient depend on which piece is nearest.
#include "flowvid/rigid/nearest_segment.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using flowvid::rigid::nearest_segment_by_scan;
using flowvid::rigid::NearestSegment;
using flowvid::rigid::NearestSegmentGrid;
using flowvid::rigid::Segment2;

namespace {

// A closed outline of ~1 px pieces, as the silhouette contour gives.
std::vector<Segment2> outline(const Eigen::Vector2d& centre, double radius_px, int pieces) {
    std::vector<Segment2> out;
    for (int i = 0; i < pieces; ++i) {
        const double a0 = 2.0 * M_PI * i / pieces, a1 = 2.0 * M_PI * (i + 1) / pieces;
        const double r0 = radius_px * (1.0 + 0.2 * std::sin(5.0 * a0)), r1 = radius_px * (1.0 + 0.2 * std::sin(5.0 * a1));
        out.push_back({centre + r0 * Eigen::Vector2d(std::cos(a0), std::sin(a0)),
                       centre + r1 * Eigen::Vector2d(std::cos(a1), std::sin(a1))});
    }
    return out;
}

void expect_same(const NearestSegment& grid, const NearestSegment& scan, const Eigen::Vector2d& q) {
    ASSERT_EQ(grid.found, scan.found);
    EXPECT_EQ(grid.index, scan.index) << q.transpose();
    EXPECT_EQ(grid.t, scan.t) << q.transpose();
    EXPECT_EQ(grid.distance2_px2, scan.distance2_px2) << q.transpose();
}

}  // namespace

TEST(NearestSegment, GridFindsTheScansPieceForPointsNearAndFarFromAnOutline) {
    const std::vector<Segment2> segments = outline({240.0, 180.0}, 90.0, 600);
    std::mt19937 random(7);
    std::uniform_real_distribution<double> x(-200.0, 680.0), y(-200.0, 560.0), jitter(-4.0, 4.0);
    for (double cell : {1.0, 3.0, 8.0, 40.0, 1000.0}) {
        NearestSegmentGrid grid;
        grid.build(segments, cell);
        // Uniform points, including far outside the grid, and points within a few px of the outline.
        for (int k = 0; k < 2000; ++k) {
            const Eigen::Vector2d q(x(random), y(random));
            expect_same(grid.nearest(q), nearest_segment_by_scan(segments, q), q);
        }
        for (const Segment2& s : segments) {
            const Eigen::Vector2d q = 0.5 * (s.a + s.b) + Eigen::Vector2d(jitter(random), jitter(random));
            expect_same(grid.nearest(q), nearest_segment_by_scan(segments, q), q);
        }
    }
}

TEST(NearestSegment, TiesGoToTheLowestIndexAsInTheScan) {
    // Two copies of each segment, and points equidistant from two segments.
    std::vector<Segment2> segments;
    for (int i = 0; i < 20; ++i) segments.push_back({{10.0 * i, 0.0}, {10.0 * i + 10.0, 0.0}});
    for (int i = 0; i < 20; ++i) segments.push_back({{10.0 * i, 0.0}, {10.0 * i + 10.0, 0.0}});
    for (int i = 0; i < 20; ++i) segments.push_back({{10.0 * i, 20.0}, {10.0 * i + 10.0, 20.0}});
    NearestSegmentGrid grid;
    grid.build(segments, 4.0);
    for (double qx = -15.0; qx <= 215.0; qx += 2.5)
        for (double qy : {-7.0, 0.0, 10.0, 13.0, 31.0}) {
            const Eigen::Vector2d q(qx, qy);
            const NearestSegment scan = nearest_segment_by_scan(segments, q);
            expect_same(grid.nearest(q), scan, q);
            EXPECT_LT(scan.index, 20u + (qy > 10.0 ? 40u : 0u)) << "the first copy wins";
        }
    // Exactly between a segment end and the next segment's start: the lower index.
    const NearestSegment hit = grid.nearest({10.0, 5.0});
    EXPECT_EQ(hit.index, 0u);
    EXPECT_EQ(hit.t, 1.0);
}

TEST(NearestSegment, NoSegmentsFindNothingAndBadCellsAreRefused) {
    NearestSegmentGrid grid;
    grid.build({}, 8.0);
    EXPECT_FALSE(grid.nearest({1.0, 2.0}).found);
    EXPECT_THROW(grid.build({{{0.0, 0.0}, {1.0, 0.0}}}, 0.0), std::invalid_argument);
    EXPECT_THROW(grid.build({{{0.0, NAN}, {1.0, 0.0}}}, 1.0), std::invalid_argument);
    // A single point-like segment: the distance to its point.
    grid.build({{{3.0, 4.0}, {3.0, 4.0}}}, 8.0);
    const NearestSegment hit = grid.nearest({0.0, 0.0});
    EXPECT_TRUE(hit.found);
    EXPECT_DOUBLE_EQ(hit.distance2_px2, 25.0);
}
