#include "flowvid/rigid/nearest_segment.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace flowvid::rigid {

namespace {

// Lower distance wins; on equal distances the lower index, as a scan in index order keeps.
bool nearer(const NearestSegment& candidate, const NearestSegment& best) {
    return !best.found || candidate.distance2_px2 < best.distance2_px2 ||
           (candidate.distance2_px2 == best.distance2_px2 && candidate.index < best.index);
}

// Cell coordinate of x, kept far from int overflow for queries far outside the grid.
int cell_of(double x, double origin, double cell) {
    const double c = std::floor((x - origin) / cell);
    return static_cast<int>(std::clamp(c, -1.0e8, 1.0e8));
}

}  // namespace

NearestSegment closest_on_segment(const Segment2& segment, const Eigen::Vector2d& point) {
    const Eigen::Vector2d ab = segment.b - segment.a;
    const double length2 = ab.squaredNorm();
    NearestSegment hit;
    hit.t = length2 > 0.0 ? std::clamp((point - segment.a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    hit.distance2_px2 = (point - (segment.a + hit.t * ab)).squaredNorm();
    hit.found = true;
    return hit;
}

NearestSegment nearest_segment_by_scan(const std::vector<Segment2>& segments, const Eigen::Vector2d& point) {
    NearestSegment best;
    for (std::size_t i = 0; i < segments.size(); ++i) {
        NearestSegment hit = closest_on_segment(segments[i], point);
        hit.index = i;
        if (nearer(hit, best)) best = hit;
    }
    return best;
}

void NearestSegmentGrid::build(const std::vector<Segment2>& segments, double cell_px) {
    if (!(cell_px > 0.0) || !std::isfinite(cell_px)) throw std::invalid_argument("NearestSegmentGrid: the cell size must be positive");
    m_segments = segments;
    m_cell_px = cell_px;
    m_start.clear();
    m_entries.clear();
    m_columns = m_rows = 0;
    if (m_segments.empty()) return;
    Eigen::Vector2d lo = m_segments.front().a, hi = lo;
    for (const Segment2& s : m_segments) {
        if (!s.a.allFinite() || !s.b.allFinite()) throw std::invalid_argument("NearestSegmentGrid: a segment end is not finite");
        lo = lo.cwiseMin(s.a).cwiseMin(s.b);
        hi = hi.cwiseMax(s.a).cwiseMax(s.b);
    }
    m_origin = lo;
    m_columns = cell_of(hi.x(), lo.x(), cell_px) + 1;
    m_rows = cell_of(hi.y(), lo.y(), cell_px) + 1;
    // A segment is listed in every cell its bounding box touches, so each of
    // its points lies in a cell that lists it.
    auto cells_of = [&](const Segment2& s, int& x0, int& x1, int& y0, int& y1) {
        x0 = std::clamp(cell_of(std::min(s.a.x(), s.b.x()), m_origin.x(), cell_px), 0, m_columns - 1);
        x1 = std::clamp(cell_of(std::max(s.a.x(), s.b.x()), m_origin.x(), cell_px), 0, m_columns - 1);
        y0 = std::clamp(cell_of(std::min(s.a.y(), s.b.y()), m_origin.y(), cell_px), 0, m_rows - 1);
        y1 = std::clamp(cell_of(std::max(s.a.y(), s.b.y()), m_origin.y(), cell_px), 0, m_rows - 1);
    };
    const std::size_t cells = static_cast<std::size_t>(m_columns) * static_cast<std::size_t>(m_rows);
    m_start.assign(cells + 1, 0);
    int x0, x1, y0, y1;
    for (const Segment2& s : m_segments) {
        cells_of(s, x0, x1, y0, y1);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) ++m_start[static_cast<std::size_t>(y) * m_columns + x + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) m_start[c + 1] += m_start[c];
    m_entries.resize(m_start[cells]);
    m_fill.assign(m_start.begin(), m_start.end() - 1);
    for (std::size_t i = 0; i < m_segments.size(); ++i) {  // in index order: each cell's list ascends
        cells_of(m_segments[i], x0, x1, y0, y1);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) m_entries[m_fill[static_cast<std::size_t>(y) * m_columns + x]++] = i;
    }
}

NearestSegment NearestSegmentGrid::nearest(const Eigen::Vector2d& point) const {
    NearestSegment best;
    if (m_segments.empty()) return best;
    const int qx = cell_of(point.x(), m_origin.x(), m_cell_px), qy = cell_of(point.y(), m_origin.y(), m_cell_px);
    auto visit_cell = [&](int x, int y) {
        const std::size_t c = static_cast<std::size_t>(y) * m_columns + x;
        for (std::size_t k = m_start[c]; k < m_start[c + 1]; ++k) {
            NearestSegment hit = closest_on_segment(m_segments[m_entries[k]], point);
            hit.index = m_entries[k];
            if (nearer(hit, best)) best = hit;
        }
    };
    // The part of row y between columns x0 and x1 that lies in the grid.
    auto visit_row = [&](int y, int x0, int x1) {
        if (y < 0 || y >= m_rows) return;
        for (int x = std::max(x0, 0); x <= std::min(x1, m_columns - 1); ++x) visit_cell(x, y);
    };
    auto visit_column = [&](int x, int y0, int y1) {
        if (x < 0 || x >= m_columns) return;
        for (int y = std::max(y0, 0); y <= std::min(y1, m_rows - 1); ++y) visit_cell(x, y);
    };
    // Rings before the first that reaches the grid are empty.
    const int dx = qx < 0 ? -qx : std::max(0, qx - (m_columns - 1));
    const int dy = qy < 0 ? -qy : std::max(0, qy - (m_rows - 1));
    // Guards the stopping test against rounding in the cell coordinates.
    constexpr double kMarginPx = 1e-6;
    for (int r = std::max(dx, dy);; ++r) {
        if (r == 0) {
            visit_cell(qx, qy);
        } else {
            visit_row(qy - r, qx - r, qx + r);
            visit_row(qy + r, qx - r, qx + r);
            visit_column(qx - r, qy - r + 1, qy + r - 1);
            visit_column(qx + r, qy - r + 1, qy + r - 1);
        }
        const bool whole_grid = qx - r <= 0 && qy - r <= 0 && qx + r >= m_columns - 1 && qy + r >= m_rows - 1;
        if (whole_grid) break;
        if (!best.found) continue;
        // Every segment not yet seen lies wholly outside the searched block of
        // cells, so no nearer than the block's border.
        const double left = point.x() - (m_origin.x() + (qx - r) * m_cell_px);
        const double right = m_origin.x() + (qx + r + 1) * m_cell_px - point.x();
        const double top = point.y() - (m_origin.y() + (qy - r) * m_cell_px);
        const double bottom = m_origin.y() + (qy + r + 1) * m_cell_px - point.y();
        const double border = std::min({left, right, top, bottom}) - kMarginPx;
        if (border > 0.0 && best.distance2_px2 < border * border) break;
    }
    return best;
}

}  // namespace flowvid::rigid
