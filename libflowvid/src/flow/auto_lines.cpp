// Input flow lines proposed from dense optical flow (auto_lines.hpp).
#include "flowvid/flow/auto_lines.hpp"

#include "flowvid/flow/geometry.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>

namespace flowvid::flow {
namespace {

// Below this share of the mean speed the mean vector is mostly noise that
// cancels over time (flicker, lighting on still surfaces): not flow. Flames
// measure 0.2 .. 0.4, still surfaces under flickering light below 0.1.
constexpr double kMinDirectionConsistency = 0.15;
// Automatic spacing: lines across the flow region, and the clamp, px.
constexpr double kLinesAcrossFlow = 5.0;
constexpr double kMinAutoSpacingPx = 24.0;
constexpr double kMaxAutoSpacingPx = 128.0;
// Never flow, px/frame: compression noise and sub-pixel camera jitter.
constexpr double kSpeedFloorPxPerFrame = 0.05;
// Cleaning the flow mask: opening then closing with a disc of this radius, px.
constexpr double kMaskCleanRadiusPx = 4.0;
// Douglas-Peucker tolerance of the returned lines, px.
constexpr double kSimplifyTolerancePx = 0.5;
// Share of the progress the flow measurement takes; the rest is the tracing.
constexpr double kFlowProgressShare = 0.9;

// The q-quantile (0..1) of `values` (reordered), the element at floor(q (n - 1)).
double quantile(std::vector<float>& values, double q) {
    if (values.empty()) return 0.0;
    const auto k = static_cast<std::ptrdiff_t>(std::floor(q * static_cast<double>(values.size() - 1)));
    std::nth_element(values.begin(), values.begin() + k, values.end());
    return values[static_cast<std::size_t>(k)];
}

// Luma of a display frame, 8-bit, resized to the analysis size (area
// averaging, so scaling down does not alias the texture the flow follows).
cv::Mat analysis_grey(const RgbImage& display, int analysis_width, int analysis_height) {
    std::vector<float> y = luma(display);
    const cv::Mat full(display.height, display.width, CV_32F, y.data());
    cv::Mat scaled;
    if (analysis_width == display.width && analysis_height == display.height)
        scaled = full;
    else
        cv::resize(full, scaled, cv::Size(analysis_width, analysis_height), 0.0, 0.0, cv::INTER_AREA);
    cv::Mat grey;
    scaled.convertTo(grey, CV_8U, 255.0);  // saturates outside [0, 1]
    return grey;
}

void check_settings(const AutoLineSettings& s) {
    const auto bad = [](double v) { return !std::isfinite(v) || v < 0.0; };
    if (bad(s.spacing_px) || bad(s.min_speed_px_per_frame) || bad(s.min_length_px))
        throw std::invalid_argument("propose_input_lines: spacing, minimum speed and minimum length must be finite and >= 0");
    if (s.step_frames < 1) throw std::invalid_argument("propose_input_lines: step_frames must be >= 1");
    if (s.analysis_short_side_px < 0)
        throw std::invalid_argument("propose_input_lines: analysis_short_side_px must be >= 0");
}

}  // namespace

// ---- streamlines ------------------------------------------------------------------

namespace detail {
namespace {

// Points of the accepted lines in square buckets of `cell`, for "is any
// accepted point within r" in constant time (r <= cell).
class PointBuckets {
public:
    PointBuckets(int width, int height, double cell)
        : m_cell(cell),
          m_columns(static_cast<int>(std::ceil(width / cell)) + 1),
          m_rows(static_cast<int>(std::ceil(height / cell)) + 1),
          m_buckets(static_cast<std::size_t>(m_columns) * static_cast<std::size_t>(m_rows)) {}

    void add(const Eigen::Vector2d& p) { m_buckets[index(column(p.x()), row(p.y()))].push_back(p); }

    bool any_within(const Eigen::Vector2d& p, double radius) const {
        const double r2 = radius * radius;
        for (int r = row(p.y() - radius); r <= row(p.y() + radius); ++r)
            for (int c = column(p.x() - radius); c <= column(p.x() + radius); ++c)
                for (const Eigen::Vector2d& q : m_buckets[index(c, r)])
                    if ((q - p).squaredNorm() < r2) return true;
        return false;
    }

private:
    int column(double x) const { return std::clamp(static_cast<int>(std::floor(x / m_cell)), 0, m_columns - 1); }
    int row(double y) const { return std::clamp(static_cast<int>(std::floor(y / m_cell)), 0, m_rows - 1); }
    std::size_t index(int c, int r) const { return static_cast<std::size_t>(r) * static_cast<std::size_t>(m_columns) + static_cast<std::size_t>(c); }

    double m_cell;
    int m_columns;
    int m_rows;
    std::vector<std::vector<Eigen::Vector2d>> m_buckets;
};

class StreamTracer {
public:
    StreamTracer(const FlowField& field, const StreamlineSettings& settings)
        : m_field(field), m_settings(settings), m_accepted(field.width, field.height, settings.separation) {}

    std::vector<std::vector<Eigen::Vector2d>> run() {
        std::vector<std::vector<Eigen::Vector2d>> lines;
        for (const Eigen::Vector2d& seed : seeds()) {
            if (m_accepted.any_within(seed, m_settings.separation)) continue;
            Eigen::Vector2d down;
            if (!direction(seed, 1.0, down)) continue;
            std::vector<Eigen::Vector2d> upstream = trace(seed, -1.0, -down);
            const std::vector<Eigen::Vector2d> downstream = trace(seed, 1.0, down);
            std::reverse(upstream.begin(), upstream.end());
            upstream.push_back(seed);
            upstream.insert(upstream.end(), downstream.begin(), downstream.end());
            if (formats::polyline_length(upstream) < m_settings.min_length) continue;
            for (const Eigen::Vector2d& p : upstream) m_accepted.add(p);
            lines.push_back(std::move(upstream));
        }
        return lines;
    }

private:
    std::size_t at(int x, int y) const { return static_cast<std::size_t>(y) * static_cast<std::size_t>(m_field.width) + static_cast<std::size_t>(x); }

    bool inside(const Eigen::Vector2d& p) const {
        return p.x() >= 0.0 && p.y() >= 0.0 && p.x() <= m_field.width - 1.0 && p.y() <= m_field.height - 1.0;
    }
    bool in_mask(const Eigen::Vector2d& p) const {
        const int x = static_cast<int>(std::lround(p.x()));
        const int y = static_cast<int>(std::lround(p.y()));
        return m_field.mask[at(x, y)] != 0;
    }

    // Bilinear velocity at p (inside the grid).
    Eigen::Vector2d velocity(const Eigen::Vector2d& p) const {
        const int x0 = std::min(static_cast<int>(std::floor(p.x())), std::max(m_field.width - 2, 0));
        const int y0 = std::min(static_cast<int>(std::floor(p.y())), std::max(m_field.height - 2, 0));
        const int x1 = std::min(x0 + 1, m_field.width - 1);
        const int y1 = std::min(y0 + 1, m_field.height - 1);
        const double fx = std::clamp(p.x() - x0, 0.0, 1.0);
        const double fy = std::clamp(p.y() - y0, 0.0, 1.0);
        const auto lerp2 = [&](const std::vector<float>& v) {
            const double top = (1.0 - fx) * v[at(x0, y0)] + fx * v[at(x1, y0)];
            const double bottom = (1.0 - fx) * v[at(x0, y1)] + fx * v[at(x1, y1)];
            return (1.0 - fy) * top + fy * bottom;
        };
        return {lerp2(m_field.vx), lerp2(m_field.vy)};
    }

    // Unit direction of travel at p (sign -1: upstream); false where the
    // field is too slow to say.
    bool direction(const Eigen::Vector2d& p, double sign, Eigen::Vector2d& out) const {
        const Eigen::Vector2d v = velocity(p);
        const double speed = v.norm();
        if (!(speed > 0.0) || speed < m_settings.min_speed) return false;
        out = sign * v / speed;
        return true;
    }

    // Grid cells every separation / 4 inside the mask and fast enough,
    // fastest first (ties: row, then column), so the main flow gets its lines
    // before slow margins take the room.
    std::vector<Eigen::Vector2d> seeds() const {
        const int spacing = std::max(1, static_cast<int>(std::floor(m_settings.separation / 4.0)));
        struct Seed {
            double speed;
            int x;
            int y;
        };
        std::vector<Seed> found;
        for (int y = spacing / 2; y < m_field.height; y += spacing)
            for (int x = spacing / 2; x < m_field.width; x += spacing) {
                if (!m_field.mask[at(x, y)]) continue;
                const double speed = std::hypot(m_field.vx[at(x, y)], m_field.vy[at(x, y)]);
                if (speed >= m_settings.min_speed && speed > 0.0) found.push_back({speed, x, y});
            }
        std::sort(found.begin(), found.end(), [](const Seed& a, const Seed& b) {
            if (a.speed != b.speed) return a.speed > b.speed;
            return a.y != b.y ? a.y < b.y : a.x < b.x;
        });
        std::vector<Eigen::Vector2d> out;
        out.reserve(found.size());
        for (const Seed& s : found) out.emplace_back(s.x, s.y);
        return out;
    }

    // Midpoint (RK2) steps from `seed` along sign x field until the line
    // leaves the grid or the mask, slows down, kinks, turns too far from
    // `seed_direction`, or comes too close to an accepted line. The seed is
    // not included.
    std::vector<Eigen::Vector2d> trace(const Eigen::Vector2d& seed, double sign, const Eigen::Vector2d& seed_direction) const {
        const double h = m_settings.step;
        const double min_turn_cos = std::cos(m_settings.max_turn_deg * M_PI / 180.0);
        const double kink_cos = std::cos(M_PI / 4.0);  // 45 degrees in one step: a stagnation point, not a bend
        const double test_distance = m_settings.test_ratio * m_settings.separation;
        // Long enough for a line across the whole grid and back.
        const int max_steps = static_cast<int>(4.0 * (m_field.width + m_field.height) / h) + 1;
        std::vector<Eigen::Vector2d> points;
        Eigen::Vector2d x = seed;
        Eigen::Vector2d previous = seed_direction;
        for (int i = 0; i < max_steps; ++i) {
            Eigen::Vector2d d1, d2;
            if (!direction(x, sign, d1)) break;
            const Eigen::Vector2d mid = x + 0.5 * h * d1;
            if (!inside(mid) || !direction(mid, sign, d2)) break;
            const Eigen::Vector2d next = x + h * d2;
            if (!inside(next) || !in_mask(next)) break;
            if (d2.dot(previous) < kink_cos || d2.dot(seed_direction) < min_turn_cos) break;
            if (m_accepted.any_within(next, test_distance)) break;
            points.push_back(next);
            x = next;
            previous = d2;
        }
        return points;
    }

    const FlowField& m_field;
    StreamlineSettings m_settings;
    PointBuckets m_accepted;
};

}  // namespace

std::vector<std::vector<Eigen::Vector2d>> evenly_spaced_streamlines(const FlowField& field,
                                                                    const StreamlineSettings& settings) {
    const std::size_t cells = static_cast<std::size_t>(std::max(field.width, 0)) * static_cast<std::size_t>(std::max(field.height, 0));
    if (field.width <= 0 || field.height <= 0 || field.vx.size() != cells || field.vy.size() != cells ||
        field.mask.size() != cells)
        throw std::invalid_argument("evenly_spaced_streamlines: field arrays must have width x height entries");
    if (!(settings.separation > 0.0) || !(settings.step > 0.0) || !(settings.test_ratio > 0.0))
        throw std::invalid_argument("evenly_spaced_streamlines: separation, step and test ratio must be > 0");
    return StreamTracer(field, settings).run();
}

std::vector<Eigen::Vector2d> simplify_polyline(const std::vector<Eigen::Vector2d>& points, double tolerance) {
    if (points.size() <= 2) return points;
    std::vector<bool> keep(points.size(), false);
    keep.front() = keep.back() = true;
    // Iterative Douglas-Peucker: split each span at its farthest point while
    // that point is farther than the tolerance from the span's chord.
    std::vector<std::pair<std::size_t, std::size_t>> spans{{0, points.size() - 1}};
    while (!spans.empty()) {
        const auto [first, last] = spans.back();
        spans.pop_back();
        double farthest = -1.0;
        std::size_t split = first;
        for (std::size_t i = first + 1; i < last; ++i) {
            const double d = distance_to_segment(points[i], points[first], points[last]);
            if (d > farthest) {
                farthest = d;
                split = i;
            }
        }
        if (farthest > tolerance) {
            keep[split] = true;
            spans.emplace_back(first, split);
            spans.emplace_back(split, last);
        }
    }
    std::vector<Eigen::Vector2d> out;
    for (std::size_t i = 0; i < points.size(); ++i)
        if (keep[i]) out.push_back(points[i]);
    return out;
}

}  // namespace detail

// ---- the proposal -------------------------------------------------------------------

AutoLines propose_input_lines_steadied(const formats::Capture& capture, int max_frames, CameraMotion& camera,
                                       const AutoLineSettings& settings,
                                       const Progress& progress) {
    const auto stage = [&](const std::string& name) {
        return Progress([&progress, name](const ProgressReport& r) { return !progress || progress({name, r.fraction, r.message}); });
    };
    CaptureFrames filmed(capture, max_frames);
    AutoLines lines = propose_input_lines(filmed, settings, stage("optical flow"));
    CaptureFrames again(capture, max_frames);
    bool cancelled = false;
    const Progress drift = stage("camera drift");
    CameraMotionSettings first_view;  // the proposal is drawn over the first frame, as an artist draws
    first_view.view = CameraMotionSettings::View::first_frame;
    camera = estimate_camera_motion(again, drawn_input_polylines(lines.drawing), first_view, [&](const ProgressReport& r) {
        cancelled = !drift(r);
        return !cancelled;
    });
    if (cancelled) throw Cancelled();
    if (camera.still()) return lines;
    CaptureFrames source(capture, max_frames);
    StabilisedFrames steadied(source, camera);
    return propose_input_lines(steadied, settings, stage("optical flow, steadied"));
}

AutoLines propose_input_lines(FrameSequence& frames, const AutoLineSettings& settings,
                              const Progress& progress) {
    check_settings(settings);
    const int width = frames.width();
    const int height = frames.height();
    int used = frames.count();
    if (settings.max_frames > 0) used = std::min(used, settings.max_frames);
    const int step = settings.step_frames;
    if (width <= 0 || height <= 0 || used < step + 1)
        throw std::invalid_argument("propose_input_lines: needs at least step_frames + 1 = " + std::to_string(step + 1) +
                                    " frames, the clip has " + std::to_string(used) + " to use");

    // Analysis size and its scale per axis (rounding makes them differ slightly).
    const double scale = settings.analysis_short_side_px > 0
                             ? std::min(1.0, settings.analysis_short_side_px / static_cast<double>(std::min(width, height)))
                             : 1.0;
    const int aw = std::max(1, static_cast<int>(std::lround(width * scale)));
    const int ah = std::max(1, static_cast<int>(std::lround(height * scale)));
    const double sx = static_cast<double>(aw) / width;
    const double sy = static_cast<double>(ah) / height;
    const double s_mean = 0.5 * (sx + sy);
    const std::size_t cells = static_cast<std::size_t>(aw) * static_cast<std::size_t>(ah);

    // ---- dense flow of every pair, summed per pixel in full-size px/frame
    const int pairs_total = used - step;
    cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
    std::vector<cv::Mat> ring(static_cast<std::size_t>(step) + 1);
    std::vector<double> sum_x(cells, 0.0), sum_y(cells, 0.0), sum_speed(cells, 0.0);
    const double to_full_x = 1.0 / (sx * step);
    const double to_full_y = 1.0 / (sy * step);
    int pairs = 0;
    for (int i = 0; i < used; ++i) {
        const RgbImage image = frames.frame(i);
        if (image.width != width || image.height != height)
            throw std::invalid_argument("propose_input_lines: frame " + std::to_string(i) + " is " +
                                        std::to_string(image.width) + " x " + std::to_string(image.height) +
                                        ", the clip " + std::to_string(width) + " x " + std::to_string(height));
        ring[static_cast<std::size_t>(i % (step + 1))] = analysis_grey(image, aw, ah);
        if (i < step) continue;
        cv::Mat flow;
        dis->calc(ring[static_cast<std::size_t>((i - step) % (step + 1))], ring[static_cast<std::size_t>(i % (step + 1))], flow);
        for (int y = 0; y < ah; ++y) {
            const cv::Vec2f* row = flow.ptr<cv::Vec2f>(y);
            for (int x = 0; x < aw; ++x) {
                const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(aw) + static_cast<std::size_t>(x);
                const double fx = row[x][0] * to_full_x;
                const double fy = row[x][1] * to_full_y;
                sum_x[k] += fx;
                sum_y[k] += fy;
                sum_speed[k] += std::hypot(fx, fy);
            }
        }
        ++pairs;
        report_progress(progress, "optical flow", kFlowProgressShare * pairs / pairs_total);
    }

    // ---- temporal aggregate: mean vector, its speed, direction consistency
    std::vector<float> mean_x(cells), mean_y(cells), speed(cells);
    cv::Mat mask(ah, aw, CV_8U, cv::Scalar(0));
    for (std::size_t k = 0; k < cells; ++k) {
        mean_x[k] = static_cast<float>(sum_x[k] / pairs);
        mean_y[k] = static_cast<float>(sum_y[k] / pairs);
        speed[k] = std::hypot(mean_x[k], mean_y[k]);
    }
    std::vector<float> sorted = speed;
    const double noise = quantile(sorted, 0.5);
    const double p95 = quantile(sorted, 0.95);
    const double p99 = quantile(sorted, 0.99);
    AutoLines result;
    result.frame_pairs = pairs;
    result.min_speed_px_per_frame =
        settings.min_speed_px_per_frame > 0.0
            ? settings.min_speed_px_per_frame
            : std::max(std::min(std::max(3.0 * noise, 0.15 * p99), 0.5 * p95), kSpeedFloorPxPerFrame);
    for (int y = 0; y < ah; ++y)
        for (int x = 0; x < aw; ++x) {
            const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(aw) + static_cast<std::size_t>(x);
            const double mean_speed = sum_speed[k] / pairs;
            const bool consistent = mean_speed > 0.0 && speed[k] >= kMinDirectionConsistency * mean_speed;
            if (speed[k] >= result.min_speed_px_per_frame && consistent) mask.at<std::uint8_t>(y, x) = 1;
        }
    // Opening drops specks of noise, closing fills pinholes in the flow.
    const int radius = std::max(1, static_cast<int>(std::lround(kMaskCleanRadiusPx * s_mean)));
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, disc);
    cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, disc);

    result.drawing.width = width;
    result.drawing.height = height;
    result.drawing.description = "input lines proposed from the clip's optical flow (flowvid auto lines)";
    std::vector<float> region_speeds;
    Eigen::Vector2d flow_sum = Eigen::Vector2d::Zero();
    for (int y = 0; y < ah; ++y)
        for (int x = 0; x < aw; ++x) {
            if (!mask.at<std::uint8_t>(y, x)) continue;
            const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(aw) + static_cast<std::size_t>(x);
            region_speeds.push_back(speed[k]);
            flow_sum += Eigen::Vector2d(mean_x[k], mean_y[k]);
        }
    result.flow_area_share = static_cast<double>(region_speeds.size()) / static_cast<double>(cells);
    result.median_speed_px_per_frame = quantile(region_speeds, 0.5);

    // ---- spacing: a fifth of the region's width across the mean flow
    if (settings.spacing_px > 0.0) {
        result.spacing_px = settings.spacing_px;
    } else if (region_speeds.empty()) {
        result.spacing_px = kMinAutoSpacingPx;
    } else {
        const Eigen::Vector2d along = flow_sum.norm() > 0.0 ? Eigen::Vector2d(flow_sum.normalized()) : Eigen::Vector2d(0.0, 1.0);
        std::vector<float> projection;
        projection.reserve(region_speeds.size());
        for (int y = 0; y < ah; ++y)
            for (int x = 0; x < aw; ++x)
                if (mask.at<std::uint8_t>(y, x))
                    projection.push_back(static_cast<float>(((x + 0.5) / sx - 0.5) * along.x() + ((y + 0.5) / sy - 0.5) * along.y()));
        // 3rd .. 97th percentile: a few stray pixels do not stretch the region.
        const double extent = std::max(1.0, quantile(projection, 0.97) - quantile(projection, 0.03));
        const double area_px = static_cast<double>(region_speeds.size()) / (sx * sy);
        result.spacing_px = std::clamp(area_px / extent / kLinesAcrossFlow, kMinAutoSpacingPx, kMaxAutoSpacingPx);
    }
    const double min_length_px = settings.min_length_px > 0.0 ? settings.min_length_px : 2.0 * result.spacing_px;
    if (region_speeds.empty()) {
        report_progress(progress, "optical flow", 1.0);
        return result;
    }

    // ---- the field the lines follow: the mean flow smoothed inside the
    // region (normalised convolution, so the still surroundings do not slow
    // its edges), over a quarter of the spacing: noise averages out, bends
    // wider than the lines' gap remain.
    cv::Mat weight, vx, vy;
    mask.convertTo(weight, CV_32F);
    const cv::Mat mx(ah, aw, CV_32F, mean_x.data());
    const cv::Mat my(ah, aw, CV_32F, mean_y.data());
    vx = mx.mul(weight);
    vy = my.mul(weight);
    const double sigma = std::max(0.5, 0.25 * result.spacing_px * s_mean);
    cv::GaussianBlur(weight, weight, cv::Size(0, 0), sigma);
    cv::GaussianBlur(vx, vx, cv::Size(0, 0), sigma);
    cv::GaussianBlur(vy, vy, cv::Size(0, 0), sigma);
    detail::FlowField field;
    field.width = aw;
    field.height = ah;
    field.vx.resize(cells);
    field.vy.resize(cells);
    field.mask.resize(cells);
    for (int y = 0; y < ah; ++y)
        for (int x = 0; x < aw; ++x) {
            const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(aw) + static_cast<std::size_t>(x);
            const bool in = mask.at<std::uint8_t>(y, x) != 0;
            const float w = std::max(weight.at<float>(y, x), 1e-3f);
            field.mask[k] = in ? 1 : 0;
            field.vx[k] = in ? vx.at<float>(y, x) / w : 0.0f;
            field.vy[k] = in ? vy.at<float>(y, x) / w : 0.0f;
        }

    detail::StreamlineSettings trace;
    trace.separation = result.spacing_px * s_mean;
    trace.min_speed = 0.5 * result.min_speed_px_per_frame;  // lines may run on into slower water before they stop
    trace.min_length = min_length_px * s_mean;
    trace.step = std::max(0.25, s_mean);  // 1 px of the full-size frame
    const std::vector<std::vector<Eigen::Vector2d>> lines = detail::evenly_spaced_streamlines(field, trace);

    for (const std::vector<Eigen::Vector2d>& line : lines) {
        std::vector<Eigen::Vector2d> full;
        full.reserve(line.size());
        // Pixel centres map to pixel centres: x_full + 0.5 = (x + 0.5) / sx.
        for (const Eigen::Vector2d& p : line) full.emplace_back((p.x() + 0.5) / sx - 0.5, (p.y() + 0.5) / sy - 0.5);
        formats::FlowLine out;
        out.id = "auto-" + std::to_string(result.drawing.inputs.size() + 1);
        out.points = detail::simplify_polyline(full, kSimplifyTolerancePx);
        result.drawing.inputs.push_back(std::move(out));
    }
    report_progress(progress, "optical flow", 1.0);
    return result;
}

// ---- comparing line sets ---------------------------------------------------------------

double mean_distance_to_lines(const std::vector<std::vector<Eigen::Vector2d>>& from,
                              const std::vector<std::vector<Eigen::Vector2d>>& to, double step_px) {
    if (!(step_px > 0.0) || !std::isfinite(step_px)) throw std::invalid_argument("mean_distance_to_lines: step_px must be > 0");
    const auto nearest = [&to](const Eigen::Vector2d& p) {
        double best = std::numeric_limits<double>::infinity();
        for (const std::vector<Eigen::Vector2d>& line : to) {
            if (line.size() == 1) best = std::min(best, (p - line.front()).norm());
            for (std::size_t i = 0; i + 1 < line.size(); ++i) best = std::min(best, distance_to_segment(p, line[i], line[i + 1]));
        }
        return best;
    };
    bool target = false;
    for (const auto& line : to) target = target || !line.empty();
    if (!target) return std::numeric_limits<double>::quiet_NaN();

    double sum = 0.0;
    std::size_t samples = 0;
    const auto sample = [&](const Eigen::Vector2d& p) {
        sum += nearest(p);
        ++samples;
    };
    for (const std::vector<Eigen::Vector2d>& line : from) {
        if (line.empty()) continue;
        sample(line.front());
        // Samples at arc lengths step, 2 step, ... and the last point (unless
        // a sample already fell on it).
        double next = step_px;   // arc length of the next sample
        double start = 0.0;      // arc length at the current segment's start
        double last_sampled = 0.0;
        for (std::size_t i = 0; i + 1 < line.size(); ++i) {
            const Eigen::Vector2d d = line[i + 1] - line[i];
            const double length = d.norm();
            while (length > 0.0 && next <= start + length + 1e-9) {
                sample(line[i] + d * std::min(1.0, (next - start) / length));
                last_sampled = next;
                next += step_px;
            }
            start += length;
        }
        if (start - last_sampled > 1e-9) sample(line.back());
    }
    return samples ? sum / static_cast<double>(samples) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace flowvid::flow
