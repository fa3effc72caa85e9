#pragma once
// The nearest of a set of 2-D segments (pixels) to query points. The silhouette
// cost asks it once per observed outline point against ~1 px contour pieces:
// a scan is O(points x pieces) and took most of a rigid fit's time.

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace flowvid::rigid {

struct Segment2 {
    Eigen::Vector2d a = Eigen::Vector2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
};

struct NearestSegment {
    std::size_t index = 0;  // into the segments given
    double t = 0.0;         // closest point = a + t (b - a), t in [0, 1]
    double distance2_px2 = 0.0;
    bool found = false;     // false only when there are no segments
};

// Closest point of one segment (t clamped to the segment).
NearestSegment closest_on_segment(const Segment2& segment, const Eigen::Vector2d& point);

// The reference: every segment in index order, the lowest index on ties.
NearestSegment nearest_segment_by_scan(const std::vector<Segment2>& segments, const Eigen::Vector2d& point);

// The same answer as the scan (the same segment, t and distance, bit for
// bit, ties included) through a uniform grid of cells: rings of cells are
// searched outward from the query's cell until no cell left unseen can hold
// a segment as near as the best found.
class NearestSegmentGrid {
public:
    // Keeps a copy of the segments. For the ~1 px contour pieces, 3 px cells
    // measured fastest (bench_rigid: 2 to 12 px tried).
    void build(const std::vector<Segment2>& segments, double cell_px = 3.0);
    NearestSegment nearest(const Eigen::Vector2d& point) const;
    std::size_t size() const { return m_segments.size(); }

private:
    std::vector<Segment2> m_segments;
    double m_cell_px = 3.0;
    Eigen::Vector2d m_origin = Eigen::Vector2d::Zero();
    int m_columns = 0, m_rows = 0;
    // Cell c's segment indices (ascending): m_entries[m_start[c] .. m_start[c + 1]).
    std::vector<std::size_t> m_start;
    std::vector<std::size_t> m_entries;
    std::vector<std::size_t> m_fill;  // build's write positions, kept to reuse its memory
};

}  // namespace flowvid::rigid
