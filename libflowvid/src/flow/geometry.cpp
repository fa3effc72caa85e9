#include "flowvid/flow/geometry.hpp"

#include "flowvid/error.hpp"
#include "series_statistics.hpp"

#include <algorithm>
#include <limits>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace flowvid::flow {

LineGeometry::LineGeometry(const std::vector<Eigen::Vector2d>& points, double smoothing_px) {
    for (const Eigen::Vector2d& p : points)
        if (m_points.empty() || (p - m_points.back()).norm() > 1e-9) m_points.push_back(p);
    if (m_points.size() < 2) throw std::invalid_argument("a flow line needs two distinct points");
    m_arc = formats::cumulative_arc_lengths(m_points);
    m_length = m_arc.back();

    // Raw tangents sampled every half pixel, then a moving average over the
    // smoothing window (prefix sums), normalised.
    const int samples = static_cast<int>(std::ceil(m_length * 2.0)) + 1;
    std::vector<Eigen::Vector2d> prefix(static_cast<std::size_t>(samples) + 1, Eigen::Vector2d::Zero());
    std::size_t segment = 0;
    for (int k = 0; k < samples; ++k) {
        const double s = std::min(k * 0.5, m_length);
        while (segment + 2 < m_points.size() && m_arc[segment + 1] <= s) ++segment;
        const Eigen::Vector2d d = (m_points[segment + 1] - m_points[segment]).normalized();
        prefix[static_cast<std::size_t>(k) + 1] = prefix[static_cast<std::size_t>(k)] + d;
    }
    const int table = static_cast<int>(std::ceil(m_length)) + 1;
    m_tangents.resize(static_cast<std::size_t>(table));
    const int half = std::max(0, static_cast<int>(std::lround(smoothing_px * 2.0)));
    for (int i = 0; i < table; ++i) {
        const int centre = std::min(i * 2, samples - 1);
        const int lo = std::max(0, centre - half);
        const int hi = std::min(samples - 1, centre + half);
        Eigen::Vector2d t = prefix[static_cast<std::size_t>(hi) + 1] - prefix[static_cast<std::size_t>(lo)];
        if (t.norm() < 1e-12) t = (m_points[1] - m_points[0]);
        m_tangents[static_cast<std::size_t>(i)] = t.normalized();
    }
}

Eigen::Vector2d LineGeometry::point(double s) const {
    if (s <= 0.0) return m_points.front() + s * (m_points[1] - m_points[0]).normalized();
    if (s >= m_length) {
        const std::size_t n = m_points.size();
        return m_points.back() + (s - m_length) * (m_points[n - 1] - m_points[n - 2]).normalized();
    }
    const auto it = std::upper_bound(m_arc.begin(), m_arc.end(), s);
    const std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - m_arc.begin())) - 1;
    const double len = m_arc[i + 1] - m_arc[i];
    const double t = len > 0.0 ? (s - m_arc[i]) / len : 0.0;
    return m_points[i] + t * (m_points[i + 1] - m_points[i]);
}

Eigen::Vector2d LineGeometry::tangent(double s) const {
    const double c = std::clamp(s, 0.0, static_cast<double>(m_tangents.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(c), m_tangents.size() - 1);
    const std::size_t j = std::min(i + 1, m_tangents.size() - 1);
    const double f = c - static_cast<double>(i);
    const Eigen::Vector2d t = (1.0 - f) * m_tangents[i] + f * m_tangents[j];
    return t.normalized();
}

LineGeometry::Projection LineGeometry::project(const Eigen::Vector2d& q, double extension_px) const {
    Projection best;
    best.distance = std::numeric_limits<double>::infinity();
    const std::size_t segments = m_points.size() - 1;
    for (std::size_t i = 0; i < segments; ++i) {
        const Eigen::Vector2d a = m_points[i];
        const Eigen::Vector2d d = m_points[i + 1] - a;
        const double len = d.norm();
        if (len <= 0.0) continue;
        const Eigen::Vector2d u = d / len;
        double t = (q - a).dot(u);
        const double lo = i == 0 ? -extension_px : 0.0;
        const double hi = i + 1 == segments ? len + extension_px : len;
        t = std::clamp(t, lo, hi);
        const Eigen::Vector2d foot = a + t * u;
        const Eigen::Vector2d r = q - foot;
        const double distance = r.norm();
        if (distance < best.distance) {
            const Eigen::Vector2d normal(-u.y(), u.x());
            best.distance = distance;
            best.s = m_arc[i] + t;
            best.n = r.dot(normal) >= 0.0 ? distance : -distance;
        }
    }
    return best;
}

namespace {

std::vector<Eigen::Vector2d> resample(const std::vector<Eigen::Vector2d>& line, int samples) {
    const double length = formats::polyline_length(line);
    std::vector<Eigen::Vector2d> out(static_cast<std::size_t>(samples));
    for (int i = 0; i < samples; ++i)
        out[static_cast<std::size_t>(i)] = formats::point_at_arc_length(line, length * i / std::max(1, samples - 1));
    return out;
}

Eigen::Vector2d direction(const std::vector<Eigen::Vector2d>& line) {
    const Eigen::Vector2d d = line.back() - line.front();
    return d.norm() > 0.0 ? Eigen::Vector2d(d.normalized()) : Eigen::Vector2d(0.0, 1.0);
}

int blend_samples(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
    const double length = std::max(formats::polyline_length(a), formats::polyline_length(b));
    return std::clamp(static_cast<int>(std::ceil(length / 4.0)) + 1, 16, 256);
}

}  // namespace

std::vector<Eigen::Vector2d> blend_polylines(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b,
                                             double w, int samples) {
    const std::vector<Eigen::Vector2d> ra = resample(a, samples);
    const std::vector<Eigen::Vector2d> rb = resample(b, samples);
    std::vector<Eigen::Vector2d> out(ra.size());
    for (std::size_t i = 0; i < ra.size(); ++i) out[i] = (1.0 - w) * ra[i] + w * rb[i];
    return out;
}

double length_inside_frame(const std::vector<Eigen::Vector2d>& points, int width, int height) {
    double inside = 0.0;
    for (std::size_t i = 1; i < points.size(); ++i) {
        // Clip the segment p + t d, t in [0, 1], to the rectangle one slab at a time.
        const Eigen::Vector2d p = points[i - 1], d = points[i] - points[i - 1];
        double t0 = 0.0, t1 = 1.0;
        const double lo[2] = {0.0, 0.0}, hi[2] = {static_cast<double>(width), static_cast<double>(height)};
        for (int axis = 0; axis < 2 && t0 <= t1; ++axis) {
            if (d[axis] == 0.0) {
                if (p[axis] < lo[axis] || p[axis] > hi[axis]) t1 = -1.0;
                continue;
            }
            double a = (lo[axis] - p[axis]) / d[axis], b = (hi[axis] - p[axis]) / d[axis];
            if (a > b) std::swap(a, b);
            t0 = std::max(t0, a);
            t1 = std::min(t1, b);
        }
        if (t1 > t0) inside += (t1 - t0) * d.norm();
    }
    return inside;
}

LineGap line_gap(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b, int samples) {
    const std::vector<Eigen::Vector2d> ra = resample(a, samples);
    const std::vector<Eigen::Vector2d> rb = resample(b, samples);
    LineGap gap;
    for (std::size_t i = 0; i < ra.size(); ++i) {
        const double d = (ra[i] - rb[i]).norm();
        gap.mean_px += d;
        gap.max_px = std::max(gap.max_px, d);
    }
    gap.mean_px /= static_cast<double>(ra.size());
    return gap;
}

std::vector<std::vector<int>> neighbour_chains(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px,
                                               double max_angle_deg) {
    const int n = static_cast<int>(lines.size());
    const double cos_max = std::cos(max_angle_deg * M_PI / 180.0);
    std::vector<Eigen::Vector2d> dirs, centroids;
    for (const auto& line : lines) {
        dirs.push_back(direction(line));
        const std::vector<Eigen::Vector2d> r = resample(line, 32);
        Eigen::Vector2d c = Eigen::Vector2d::Zero();
        for (const auto& p : r) c += p;
        centroids.push_back(c / static_cast<double>(r.size()));
    }
    const auto compatible = [&](int i, int j) {
        return dirs[static_cast<std::size_t>(i)].dot(dirs[static_cast<std::size_t>(j)]) >= cos_max &&
               line_gap(lines[static_cast<std::size_t>(i)], lines[static_cast<std::size_t>(j)]).mean_px <= max_gap_px;
    };
    // Groups: connected components of "compatible".
    std::vector<int> parent(static_cast<std::size_t>(n));
    std::iota(parent.begin(), parent.end(), 0);
    const auto find = [&](int i) {
        while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
        return i;
    };
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j)
            if (compatible(i, j)) parent[static_cast<std::size_t>(find(i))] = find(j);
    std::vector<std::vector<int>> chains;
    std::vector<bool> done(static_cast<std::size_t>(n), false);
    for (int i = 0; i < n; ++i) {
        const int root = find(i);
        if (done[static_cast<std::size_t>(root)]) continue;
        done[static_cast<std::size_t>(root)] = true;
        std::vector<int> group;
        Eigen::Vector2d mean = Eigen::Vector2d::Zero();
        for (int j = 0; j < n; ++j)
            if (find(j) == root) {
                group.push_back(j);
                mean += dirs[static_cast<std::size_t>(j)];
            }
        mean = mean.norm() > 0.0 ? Eigen::Vector2d(mean.normalized()) : Eigen::Vector2d(0.0, 1.0);
        // Across the flow, left to right as seen looking downstream on screen
        // (for a downward flow: increasing x).
        const Eigen::Vector2d across(mean.y(), -mean.x());
        std::stable_sort(group.begin(), group.end(), [&](int a, int b) {
            return centroids[static_cast<std::size_t>(a)].dot(across) < centroids[static_cast<std::size_t>(b)].dot(across);
        });
        std::vector<int> chain;
        for (int member : group) {
            if (!chain.empty() && !compatible(chain.back(), member)) {
                chains.push_back(chain);
                chain.clear();
            }
            chain.push_back(member);
        }
        if (!chain.empty()) chains.push_back(chain);
    }
    return chains;
}

std::vector<double> distance_to_polylines(const std::vector<std::vector<Eigen::Vector2d>>& lines, int width, int height,
                                          double reach_px) {
    std::vector<double> distance(static_cast<std::size_t>(width) * height, std::numeric_limits<double>::infinity());
    for (const auto& line : lines)
        for (std::size_t i = 0; i + 1 < line.size(); ++i) {
            const Eigen::Vector2d a = line[i];
            const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), line[i + 1].x()) - reach_px)));
            const int x1 = std::min(width - 1, static_cast<int>(std::ceil(std::max(a.x(), line[i + 1].x()) + reach_px)));
            const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), line[i + 1].y()) - reach_px)));
            const int y1 = std::min(height - 1, static_cast<int>(std::ceil(std::max(a.y(), line[i + 1].y()) + reach_px)));
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x) {
                    double& best = distance[static_cast<std::size_t>(y) * width + x];
                    best = std::min(best, distance_to_segment(Eigen::Vector2d(x, y), a, line[i + 1]));
                }
        }
    return distance;
}

std::vector<WideNeighbours> wide_neighbours(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px,
                                            double min_gap_px, double max_angle_deg) {
    std::vector<WideNeighbours> out;
    for (const std::vector<int>& chain : neighbour_chains(lines, max_gap_px, max_angle_deg))
        for (std::size_t k = 0; k + 1 < chain.size(); ++k) {
            const double gap = line_gap(lines[static_cast<std::size_t>(chain[k])], lines[static_cast<std::size_t>(chain[k + 1])]).mean_px;
            if (gap > min_gap_px) out.push_back({chain[k], chain[k + 1], gap});
        }
    std::sort(out.begin(), out.end(), [](const WideNeighbours& x, const WideNeighbours& y) { return x.mean_gap_px > y.mean_gap_px; });
    return out;
}

PatchSizeChoice patch_size_from_lines(const std::vector<std::vector<Eigen::Vector2d>>& lines, double max_gap_px) {
    PatchSizeChoice choice;
    std::vector<double> gaps;
    for (const WideNeighbours& pair : wide_neighbours(lines, max_gap_px, 0.0)) gaps.push_back(pair.mean_gap_px);
    choice.neighbour_pairs = static_cast<int>(gaps.size());
    if (gaps.empty()) return choice;
    choice.median_gap_px = detail::percentile(gaps, 0.5);
    choice.patch_px = std::clamp(8 * static_cast<int>(std::lround(choice.median_gap_px / 2.0 / 8.0)), 16, 96);
    return choice;
}

std::vector<InterpolatedLine> interpolate_between(const std::vector<std::vector<Eigen::Vector2d>>& lines,
                                                  const std::vector<std::vector<int>>& chains, double spacing_px) {
    std::vector<InterpolatedLine> out;
    if (spacing_px <= 0.0) return out;
    for (const std::vector<int>& chain : chains)
        for (std::size_t k = 1; k < chain.size(); ++k) {
            const int a = chain[k - 1], b = chain[k];
            const double gap = line_gap(lines[static_cast<std::size_t>(a)], lines[static_cast<std::size_t>(b)]).max_px;
            const int between = std::max(0, static_cast<int>(std::ceil(gap / spacing_px - 1e-9)) - 1);
            for (int i = 1; i <= between; ++i) out.push_back({a, b, static_cast<double>(i) / (between + 1)});
        }
    return out;
}

std::vector<Eigen::Vector2d> interpolated_points(const formats::FlowLine& a, const formats::FlowLine& b, double weight,
                                                 double frame, int samples) {
    const std::vector<Eigen::Vector2d> pa = formats::points_at_frame(a, frame);
    const std::vector<Eigen::Vector2d> pb = formats::points_at_frame(b, frame);
    return blend_polylines(pa, pb, weight, samples > 0 ? samples : blend_samples(pa, pb));
}

std::string interpolated_line_id(const std::string& a, const std::string& b, double weight) {
    char text[32];
    std::snprintf(text, sizeof text, "@%.3f", weight);
    return a + "~" + b + text;
}

bool parse_interpolated_line_id(const std::string& id, std::string& a, std::string& b, double& weight) {
    const std::size_t at = id.rfind('@');
    if (at == std::string::npos) return false;
    const std::size_t tilde = id.rfind('~', at);
    if (tilde == std::string::npos || tilde == 0 || tilde + 1 >= at) return false;
    char* end = nullptr;
    const std::string number = id.substr(at + 1);
    weight = std::strtod(number.c_str(), &end);
    if (end == number.c_str() || *end != '\0' || !(weight > 0.0 && weight < 1.0)) return false;
    a = id.substr(0, tilde);
    b = id.substr(tilde + 1, at - tilde - 1);
    return true;
}

std::vector<formats::FlowLine> densify_input_lines(const formats::FlowLineSet& drawing, double spacing_px,
                                                   double max_gap_px, double max_angle_deg) {
    std::vector<formats::FlowLine> out = drawing.inputs;
    if (spacing_px <= 0.0) return out;
    std::vector<std::vector<Eigen::Vector2d>> polylines;
    for (const formats::FlowLine& line : drawing.inputs) polylines.push_back(line.points);
    const auto chains = neighbour_chains(polylines, max_gap_px, max_angle_deg);
    for (const InterpolatedLine& inter : interpolate_between(polylines, chains, spacing_px)) {
        const formats::FlowLine& a = drawing.inputs[static_cast<std::size_t>(inter.a)];
        const formats::FlowLine& b = drawing.inputs[static_cast<std::size_t>(inter.b)];
        formats::FlowLine line;
        line.id = interpolated_line_id(a.id, b.id, inter.weight);
        std::string ia, ib;
        double w = inter.weight;
        parse_interpolated_line_id(line.id, ia, ib, w);  // the rounded weight the id records
        line.points = interpolated_points(a, b, w, 1.0);
        out.push_back(std::move(line));
    }
    return out;
}

std::string segment_line_id(const std::string& id, double a, double b) {
    char text[64];
    std::snprintf(text, sizeof text, "[%.1f:%.1f]", a, b);
    return id + text;
}


std::vector<Eigen::Vector2d> sub_polyline(const std::vector<Eigen::Vector2d>& points, double from_px, double to_px) {
    const std::vector<double> arc = formats::cumulative_arc_lengths(points);
    std::vector<Eigen::Vector2d> out{formats::point_at_arc_length(points, from_px)};
    for (std::size_t i = 0; i < points.size(); ++i)
        if (arc[i] > from_px + 1e-9 && arc[i] < to_px - 1e-9) out.push_back(points[i]);
    out.push_back(formats::point_at_arc_length(points, to_px));
    return out;
}

bool parse_segment_id(const std::string& id, std::string& base, double& from_px, double& to_px) {
    if (id.size() < 5 || id.back() != ']') return false;
    const std::size_t open = id.rfind('[');
    if (open == std::string::npos || open == 0) return false;
    const std::string inner = id.substr(open + 1, id.size() - open - 2);
    const std::size_t colon = inner.find(':');
    if (colon == std::string::npos) return false;
    char* end = nullptr;
    const std::string a = inner.substr(0, colon), b = inner.substr(colon + 1);
    from_px = std::strtod(a.c_str(), &end);
    if (end == a.c_str() || *end != '\0') return false;
    to_px = std::strtod(b.c_str(), &end);
    if (end == b.c_str() || *end != '\0' || !(to_px > from_px) || from_px < 0.0) return false;
    base = id.substr(0, open);
    return true;
}

InputLineIndex::InputLineIndex(const formats::FlowLineSet& drawing) {
    m_by_id.reserve(drawing.inputs.size());
    // The first of equal ids wins, as formats::find_input_line's scan does.
    for (const formats::FlowLine& line : drawing.inputs) m_by_id.emplace(line.id, &line);
}

const formats::FlowLine* InputLineIndex::find(const std::string& id) const {
    const auto found = m_by_id.find(id);
    return found == m_by_id.end() ? nullptr : found->second;
}

std::vector<Eigen::Vector2d> input_line_points(const InputLineIndex& inputs, const std::string& id,
                                               const std::string& file) {
    if (const formats::FlowLine* line = inputs.find(id)) return line->points;
    std::string base;
    double from_px = 0.0, to_px = 0.0;
    if (parse_segment_id(id, base, from_px, to_px)) {
        const std::vector<Eigen::Vector2d> whole = input_line_points(inputs, base, file);
        return sub_polyline(whole, from_px, to_px);
    }
    std::string a, b;
    double w = 0.0;
    if (parse_interpolated_line_id(id, a, b, w)) {
        const formats::FlowLine* la = inputs.find(a);
        const formats::FlowLine* lb = inputs.find(b);
        if (la && lb) return interpolated_points(*la, *lb, w, 1.0);
    }
    throw ValidationError({Problem{Problem::Severity::error, file, "inputs",
                                   "the bank's line " + id + " is not an input line of this drawing",
                                   "give the flow lines the bank was tracked with (flowvid track --flowlines)"}});
}

}  // namespace flowvid::flow
