#pragma once
// Geometry of flow lines for tracking, rendering and editing: arc-length
// parameterisation, smoothed tangent frames, projection of pixels onto a line,
// and the interpolation of sparse lines into a dense set (thesis 3.3).
//
// Coordinates are pixels, OpenCV convention (x right, y down, pixel centres at
// integers). Arc length s is measured from the line's first point; the normal
// is the tangent turned by +90 degrees in image coordinates, n = (-t.y, t.x).

#include "flowvid/formats/flowlines.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <string>
#include <unordered_map>
#include <vector>

namespace flowvid::flow {

// A polyline with arc-length lookups. Outside [0, length] it continues
// straight along its end segments, so patches near the ends have a frame.
class LineGeometry {
public:
    LineGeometry() = default;
    // `points`: #P >= 2 pixels (consecutive duplicates are dropped).
    // `smoothing_px`: tangents are averaged over +-smoothing_px of arc, so that
    // the frames used for warping do not jump at polyline corners.
    explicit LineGeometry(const std::vector<Eigen::Vector2d>& points, double smoothing_px = 8.0);

    double length_px() const { return m_length; }
    const std::vector<Eigen::Vector2d>& points() const { return m_points; }
    const std::vector<double>& arc_lengths() const { return m_arc; }

    Eigen::Vector2d point(double s) const;
    Eigen::Vector2d tangent(double s) const;  // unit, smoothed
    Eigen::Vector2d normal(double s) const { const Eigen::Vector2d t = tangent(s); return {-t.y(), t.x()}; }

    struct Projection {
        double s = 0.0;         // arc length of the nearest point (may be < 0 or > length on the extensions)
        double n = 0.0;         // signed offset along the segment's normal, pixels
        double distance = 0.0;  // |n| or distance to the extension
    };
    // Nearest point of the line extended by `extension_px` at both ends.
    Projection project(const Eigen::Vector2d& q, double extension_px = 0.0) const;

private:
    std::vector<Eigen::Vector2d> m_points;
    std::vector<double> m_arc;
    double m_length = 0.0;
    std::vector<Eigen::Vector2d> m_tangents;  // smoothed, one per pixel of arc (index = round(s))
};

// Distance from `p` to the segment [a, b] (to `a` when the segment has no length).
inline double distance_to_segment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d ab = b - a;
    const double length2 = ab.squaredNorm();
    const double t = length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    return (p - (a + t * ab)).norm();
}

// Length of the part of a polyline inside the frame [0, width] x [0, height]
// (each segment clipped to the rectangle): 0 for a line drawn off the clip.
double length_inside_frame(const std::vector<Eigen::Vector2d>& points, int width, int height);

// Both polylines resampled to `samples` points at equal fractions of their arc
// length and blended: (1 - w) a + w b.
std::vector<Eigen::Vector2d> blend_polylines(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b,
                                             double w, int samples = 64);
// Mean and largest distance between the points of two polylines at equal
// fractions of their arc lengths (the "gap" between neighbouring lines).
struct LineGap {
    double mean_px = 0.0;
    double max_px = 0.0;
};
LineGap line_gap(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b, int samples = 32);

// Orders lines into chains of neighbours, the sequences the dense
// interpolation and the dynamic programme run along: lines flowing in similar
// directions (within max_angle_deg, start-to-end) are sorted across the flow;
// consecutive lines further apart than max_gap_px (mean gap) start a new
// chain. Returns indices into `lines`, each chain in order across the flow
// (for a downward flow, left to right).
std::vector<std::vector<int>> neighbour_chains(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px,
                                               double max_angle_deg = 45.0);

// Per pixel of a width x height image (row-major), the distance in pixels to
// the nearest of the polylines; computed within reach_px of them, infinity
// further away.
std::vector<double> distance_to_polylines(const std::vector<std::vector<Eigen::Vector2d>>& lines, int width, int height,
                                          double reach_px);

// Consecutive lines of a chain (neighbour_chains) whose mean gap exceeds
// min_gap_px: synthesis covers about a patch around each line, so between
// such neighbours the background shows. Widest first.
struct WideNeighbours {
    int a = 0;  // indices into `lines`
    int b = 0;
    double mean_gap_px = 0.0;
};
std::vector<WideNeighbours> wide_neighbours(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px,
                                            double min_gap_px, double max_angle_deg = 45.0);

// The default patch side for a drawing: half the median gap between
// neighbouring drawn lines (mean gaps of consecutive lines in
// neighbour_chains within max_gap_px), to the nearest multiple of 8 px, within
// 16..96; 24 (the thesis's) when no line has a neighbour. Patches scale with
// how far apart the artist drew the lines: water drawn ~45 px apart gets 24 px
// (the thesis's), flames drawn ~100 px apart 48 px (the thesis used 100).
struct PatchSizeChoice {
    int patch_px = 24;
    double median_gap_px = 0.0;  // 0 without neighbours
    int neighbour_pairs = 0;
};
PatchSizeChoice patch_size_from_lines(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px = 240.0);

// A line of the dense set between two neighbours of a chain.
struct InterpolatedLine {
    int a = 0;           // index of the first neighbour in the input list
    int b = 0;           // index of the second
    double weight = 0.0;  // 0 = a, 1 = b
};
// Lines to insert between consecutive members of every chain so that
// neighbours are at most spacing_px apart (largest point gap), in chain order.
std::vector<InterpolatedLine> interpolate_between(const std::vector<std::vector<Eigen::Vector2d>>& lines,
                                                  const std::vector<std::vector<int>>& chains, double spacing_px);

// The geometry of an interpolated line at a frame (keyed lines are taken at
// that frame, so interpolating a moving line gives a moving line), with
// `samples` points (0: from the lines' lengths at that frame; the keys of one
// moving line must all have the same count).
std::vector<Eigen::Vector2d> interpolated_points(const formats::FlowLine& a, const formats::FlowLine& b, double weight,
                                                 double frame, int samples = 0);

// Ids of interpolated input lines, "A~B@0.250": readable, and the bank's line
// id alone lets synthesis rebuild the geometry from the sparse drawing.
std::string interpolated_line_id(const std::string& a, const std::string& b, double weight);
// Parses such an id; false for a plain id.
bool parse_interpolated_line_id(const std::string& id, std::string& a, std::string& b, double& weight);

// Segments of long lines (tracking cuts a line a particle cannot cross
// within the clip into segments it can): "ID[120.5:240.0]", arc lengths in
// pixels from the line's start, so the id alone rebuilds the geometry.
std::string segment_line_id(const std::string& id, double from_px, double to_px);
bool parse_segment_id(const std::string& id, std::string& base, double& from_px, double& to_px);
// The part of a polyline between two arc lengths.
std::vector<Eigen::Vector2d> sub_polyline(const std::vector<Eigen::Vector2d>& points, double from_px, double to_px);

// Densifies the input lines of a drawing: the drawn lines plus interpolated
// lines between neighbours (ids from interpolated_line_id). spacing_px <= 0
// returns the drawn lines unchanged.
std::vector<formats::FlowLine> densify_input_lines(const formats::FlowLineSet& drawing, double spacing_px,
                                                   double max_gap_px, double max_angle_deg = 45.0);

// The input lines of a drawing by id, found in constant time: a bank names
// each of its lines, and a scan per name is quadratic on big drawings. Refers
// to `drawing`, which must outlive the index.
class InputLineIndex {
public:
    explicit InputLineIndex(const formats::FlowLineSet& drawing);
    const formats::FlowLine* find(const std::string& id) const;  // nullptr when no drawn input line has `id`

private:
    std::unordered_map<std::string, const formats::FlowLine*> m_by_id;
};

// The polyline of an input line named by a bank: a drawn input line, or an
// interpolated line or a segment rebuilt from its id. Throws ValidationError naming `file`
// (the flow-line file) when the id names no drawn line.
std::vector<Eigen::Vector2d> input_line_points(const InputLineIndex& inputs, const std::string& id,
                                               const std::string& file);

}  // namespace flowvid::flow
