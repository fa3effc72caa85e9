#include "flowvid/video/stripe_scan.hpp"

#include "flowvid/video/cloth_footage.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <map>
#include <optional>
#include <queue>
#include <stdexcept>

namespace flowvid::video {
namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr double kPi = 3.141592653589793;
const float kNaN = std::numeric_limits<float>::quiet_NaN();

struct Rect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1)
};

// A Gaussian of standard deviation sigma, truncated at 3 sigma, sum 1.
std::vector<double> gaussian_kernel(double sigma) {
    const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
    std::vector<double> k(static_cast<std::size_t>(2 * radius + 1));
    double sum = 0.0;
    for (int i = -radius; i <= radius; ++i) sum += k[static_cast<std::size_t>(i + radius)] = std::exp(-0.5 * i * i / (sigma * sigma));
    for (double& v : k) v /= sum;
    return k;
}

// out = kernel_x (x) kernel_y * in over `r` (zero outside the image); T is
// double or std::complex<double>, kernels may be complex.
template <typename T, typename KX, typename KY>
void filter_separable(const std::vector<T>& in, int width, int height, const Rect& r, const std::vector<KX>& kx,
                      const std::vector<KY>& ky, std::vector<T>& scratch, std::vector<T>& out) {
    const int rx = static_cast<int>(kx.size() / 2), ry = static_cast<int>(ky.size() / 2);
    const auto at = [width](int x, int y) { return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x); };
    scratch.assign(in.size(), T{});
    out.assign(in.size(), T{});
    for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
            T sum{};
            for (int i = -rx; i <= rx; ++i) {
                const int xi = x + i;
                if (xi < 0 || xi >= width) continue;
                sum += in[at(xi, y)] * kx[static_cast<std::size_t>(i + rx)];
            }
            scratch[at(x, y)] = sum;
        }
    for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
            T sum{};
            for (int j = -ry; j <= ry; ++j) {
                const int yj = y + j;
                if (yj < r.y0 || yj >= r.y1 || yj < 0 || yj >= height) continue;
                sum += scratch[at(x, yj)] * ky[static_cast<std::size_t>(j + ry)];
            }
            out[at(x, y)] = sum;
        }
}

double wrap_angle(double a) {
    a = std::fmod(a + kPi, kTwoPi);
    if (a < 0.0) a += kTwoPi;
    return a - kPi;
}

}  // namespace

StripeScanner::StripeScanner(formats::CameraModel camera, formats::Projector projector, StripeScanSettings settings)
    : m_camera(std::move(camera)), m_projector(std::move(projector)), m_settings(settings) {
    if (m_camera.width <= 0 || m_camera.height <= 0) throw std::invalid_argument("stripe scan: the camera has no image size");
    if (!(m_projector.pattern.period_px > 0.0)) throw std::invalid_argument("stripe scan: the stripe period must be positive");
    if (m_projector.pattern.axis != "rows" && m_projector.pattern.axis != "columns")
        throw std::invalid_argument("stripe scan: unknown pattern axis '" + m_projector.pattern.axis + "'");
    if (!(m_settings.stripe_gradient.norm() > 0.0) || !m_settings.stripe_gradient.allFinite())
        throw std::invalid_argument("stripe scan: the stripes' image gradient must be finite and non-zero");
    m_rows = m_projector.pattern.axis == "rows";
    m_camera_centre = m_camera.centre_world();
    m_world_from_camera = m_camera.camera_from_world.topLeftCorner<3, 3>().transpose();
}

double StripeScanner::projector_coordinate(const Eigen::Vector3d& world_m) const {
    const Eigen::Vector2d q = m_projector.camera.project(world_m);
    return m_rows ? q.y() : q.x();
}

Eigen::Vector3d StripeScanner::triangulate(const Eigen::Vector2d& pixel, double v_p) const {
    const Eigen::Vector3d nan3 = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    if (!std::isfinite(v_p) || !pixel.allFinite()) return nan3;
    const Eigen::Vector3d direction = m_world_from_camera * m_camera.ray_camera(pixel);  // X = C + s d, s = camera depth
    const Eigen::Matrix3d R = m_projector.camera.camera_from_world.topLeftCorner<3, 3>();
    const Eigen::Vector3d t = m_projector.camera.camera_from_world.topRightCorner<3, 1>();
    const Eigen::Matrix3d& K = m_projector.camera.K;
    // Without projector distortion the points of one v_p form the plane
    // q . X + c = 0 through the projector's centre.
    Eigen::Vector3d q;
    double c;
    if (m_rows) {
        q = K(1, 1) * R.row(1).transpose() - (v_p - K(1, 2)) * R.row(2).transpose();
        c = K(1, 1) * t(1) - (v_p - K(1, 2)) * t(2);
    } else {
        q = K(0, 0) * R.row(0).transpose() + K(0, 1) * R.row(1).transpose() - (v_p - K(0, 2)) * R.row(2).transpose();
        c = K(0, 0) * t(0) + K(0, 1) * t(1) - (v_p - K(0, 2)) * t(2);
    }
    const double denominator = q.dot(direction);
    if (std::abs(denominator) < 1e-12 * q.norm() * direction.norm()) return nan3;
    double s = -(q.dot(m_camera_centre) + c) / denominator;
    if (m_projector.camera.has_distortion()) {
        // Newton along the ray on the distorted coordinate, from the plane's answer.
        for (int iteration = 0; iteration < 20 && std::isfinite(s); ++iteration) {
            const double h = 1e-6 * std::max(std::abs(s), 1e-3);
            const double f = projector_coordinate(m_camera_centre + s * direction) - v_p;
            const double slope = (projector_coordinate(m_camera_centre + (s + h) * direction) - v_p - f) / h;
            if (!std::isfinite(f) || !(std::abs(slope) > 0.0)) return nan3;
            const double step = f / slope;
            s -= step;
            if (std::abs(step) < 1e-12 * std::abs(s)) break;
        }
    }
    if (!(s > 0.0)) return nan3;
    const Eigen::Vector3d point = m_camera_centre + s * direction;
    if (!(m_projector.camera.to_camera(point).z() > 0.0)) return nan3;
    return point;
}

StripeScan StripeScanner::scan(const ImageF& gray, const metrics::Silhouette& silhouette,
                               const std::vector<Eigen::Vector3d>& pins_m, const StripeScan* previous) {
    const int width = m_camera.width, height = m_camera.height;
    if (gray.width != width || gray.height != height || silhouette.width != width || silhouette.height != height)
        throw std::invalid_argument("stripe scan: the frame and its silhouette must be " + std::to_string(width) + "x" +
                                    std::to_string(height) + " like the camera");
    const std::size_t total = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    const auto at = [width](int x, int y) { return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x); };
    const auto pixel_of = [width](std::size_t i) {
        return Eigen::Vector2d(static_cast<double>(i % static_cast<std::size_t>(width)), static_cast<double>(i / static_cast<std::size_t>(width)));
    };
    StripeScan out;
    out.width = width;
    out.height = height;
    out.projector_coordinate.assign(width, height, kNaN);
    out.modulation.assign(width, height, 0.0f);
    out.points_m.assign(total, Eigen::Vector3f::Constant(kNaN));

    // The silhouette's bounding box, grown by the filters' reach.
    Rect box{width, height, 0, 0};
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            if (silhouette.at(x, y)) {
                ++out.silhouette_px;
                box.x0 = std::min(box.x0, x);
                box.y0 = std::min(box.y0, y);
                box.x1 = std::max(box.x1, x + 1);
                box.y1 = std::max(box.y1, y + 1);
            }
    if (out.silhouette_px == 0) return out;

    const double period = m_projector.pattern.period_px;
    const Eigen::Vector2d frequency = kTwoPi / period * m_settings.stripe_gradient;  // radians per image pixel
    const double image_period = kTwoPi / frequency.norm();
    const std::vector<double> mean_kernel = gaussian_kernel(image_period);
    // The filter bank: the expected frequency, scaled and turned, for stripes
    // that folds and tilt compress, stretch or rotate.
    std::vector<Eigen::Vector2d> bank;
    for (const double scale : m_settings.bank_scales)
        for (const double turn_deg : m_settings.bank_turns_deg) {
            const double a = turn_deg * kPi / 180.0;
            bank.push_back(scale * Eigen::Vector2d(std::cos(a) * frequency.x() - std::sin(a) * frequency.y(),
                                                   std::sin(a) * frequency.x() + std::cos(a) * frequency.y()));
        }
    if (bank.empty()) bank.push_back(frequency);
    int reach = static_cast<int>(mean_kernel.size() / 2) + 1;
    for (const Eigen::Vector2d& k : bank)
        reach = std::max(reach, static_cast<int>(std::ceil(3.0 * m_settings.window_periods * kTwoPi / k.norm())) + 1);
    const Rect r{std::max(0, box.x0 - reach), std::max(0, box.y0 - reach), std::min(width, box.x1 + reach),
                 std::min(height, box.y1 + reach)};

    // Local mean inside the silhouette (normalised convolution).
    std::vector<double> inside(total, 0.0), masked(total, 0.0), scratch, inside_mean, masked_mean;
    for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x)
            if (silhouette.at(x, y)) {
                inside[at(x, y)] = 1.0;
                masked[at(x, y)] = gray.at(x, y);
            }
    filter_separable(inside, width, height, r, mean_kernel, mean_kernel, scratch, inside_mean);
    filter_separable(masked, width, height, r, mean_kernel, mean_kernel, scratch, masked_mean);
    std::vector<double> local_mean(total, 0.0);
    std::vector<std::complex<double>> detail(total);
    for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
            const std::size_t i = at(x, y);
            if (inside_mean[i] > 1e-6) local_mean[i] = masked_mean[i] / inside_mean[i];
            if (silhouette.at(x, y)) detail[i] = gray.at(x, y) - local_mean[i];
        }

    // Complex Gabor filters: correlation with window(y) exp(-i k . y),
    // separable in x and y (filter_separable sums in[x + i] kernel[i]). Per
    // pixel the filter with the strongest modulation gives the phase.
    std::vector<double> phase(total, 0.0), best_modulation(total, 0.0);
    std::vector<Eigen::Vector2d> local_frequency(total, frequency);  // the strongest filter's, radians per pixel
    std::vector<std::complex<double>> complex_scratch, response, gabor_x, gabor_y;
    std::vector<double> window_weight;
    for (const Eigen::Vector2d& k : bank) {
        const std::vector<double> window = gaussian_kernel(std::max(0.5, m_settings.window_periods * kTwoPi / k.norm()));
        const int wr = static_cast<int>(window.size() / 2);
        gabor_x.resize(window.size());
        gabor_y.resize(window.size());
        for (int i = -wr; i <= wr; ++i) {
            gabor_x[static_cast<std::size_t>(i + wr)] = window[static_cast<std::size_t>(i + wr)] * std::polar(1.0, -k.x() * i);
            gabor_y[static_cast<std::size_t>(i + wr)] = window[static_cast<std::size_t>(i + wr)] * std::polar(1.0, -k.y() * i);
        }
        filter_separable(detail, width, height, r, gabor_x, gabor_y, complex_scratch, response);
        filter_separable(inside, width, height, r, window, window, scratch, window_weight);
        for (int y = box.y0; y < box.y1; ++y)
            for (int x = box.x0; x < box.x1; ++x) {
                const std::size_t i = at(x, y);
                const double w = window_weight[i], mean = local_mean[i];
                if (!silhouette.at(x, y) || !(w > 1e-6) || !(mean > 1e-6)) continue;
                const double modulation = 2.0 * std::abs(response[i]) / (w * mean);
                if (modulation <= best_modulation[i]) continue;
                best_modulation[i] = modulation;
                local_frequency[i] = k;
                // sin(phi) correlated with exp(-i k y) gives exp(i phi) / (2i): phi = arg + pi/2.
                phase[i] = std::arg(response[i]) + 0.5 * kPi;
            }
    }

    // Valid pixels: inside the silhouette by the margin, modulated enough.
    const int margin = std::max(0, m_settings.edge_margin_px);
    std::vector<std::uint8_t> valid(total, 0);
    for (int y = box.y0; y < box.y1; ++y)
        for (int x = box.x0; x < box.x1; ++x) {
            if (!silhouette.at(x, y)) continue;
            bool deep = true;
            for (int j = -margin; j <= margin && deep; ++j)
                for (int i = -margin; i <= margin && deep; ++i) {
                    const int xi = x + i, yj = y + j;
                    deep = xi >= 0 && yj >= 0 && xi < width && yj < height && silhouette.at(xi, yj);
                }
            const std::size_t i = at(x, y);
            out.modulation.pixels[i] = static_cast<float>(best_modulation[i]);
            valid[i] = deep && best_modulation[i] >= m_settings.min_modulation ? 1 : 0;
        }

    // Quality-guided unwrapping into regions.
    std::vector<int> region(total, -1);
    std::vector<double> unwrapped(total, 0.0);
    std::vector<std::size_t> order;
    for (int y = box.y0; y < box.y1; ++y)
        for (int x = box.x0; x < box.x1; ++x)
            if (valid[at(x, y)]) order.push_back(at(x, y));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return out.modulation.pixels[a] > out.modulation.pixels[b];
    });
    struct Edge {
        float quality;
        std::size_t pixel, from;
        bool operator<(const Edge& o) const {
            return quality != o.quality ? quality < o.quality : pixel > o.pixel;  // max-heap on quality, ties by index
        }
    };
    std::vector<long long> region_size;
    const auto push_neighbours = [&](std::priority_queue<Edge>& queue, std::size_t p) {
        const int x = static_cast<int>(p % static_cast<std::size_t>(width)), y = static_cast<int>(p / static_cast<std::size_t>(width));
        const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; ++k) {
            const int xn = x + dx[k], yn = y + dy[k];
            if (xn < 0 || yn < 0 || xn >= width || yn >= height) continue;
            const std::size_t n = at(xn, yn);
            if (valid[n] && region[n] < 0) queue.push({out.modulation.pixels[n], n, p});
        }
    };
    for (const std::size_t seed : order) {
        if (region[seed] >= 0) continue;
        const int id = static_cast<int>(region_size.size());
        region_size.push_back(1);
        region[seed] = id;
        unwrapped[seed] = phase[seed];
        std::priority_queue<Edge> queue;
        push_neighbours(queue, seed);
        while (!queue.empty()) {
            const Edge e = queue.top();
            queue.pop();
            if (region[e.pixel] >= 0) continue;
            // The step the local stripe frequency predicts decides the whole
            // periods (compressed stripes step by more than pi a pixel); a
            // measured step far from it is an edge of the surface.
            const long long delta = static_cast<long long>(e.pixel) - static_cast<long long>(e.from);
            const Eigen::Vector2d offset_px = std::abs(delta) == 1 ? Eigen::Vector2d(static_cast<double>(delta), 0.0)
                                                                    : Eigen::Vector2d(0.0, delta > 0 ? 1.0 : -1.0);
            const double predicted = 0.5 * (local_frequency[e.pixel] + local_frequency[e.from]).dot(offset_px);
            const double surprise = wrap_angle(phase[e.pixel] - phase[e.from] - predicted);
            if (std::abs(surprise) > m_settings.max_step_rad) continue;  // another edge may reach it
            const double step = predicted + surprise;
            region[e.pixel] = id;
            unwrapped[e.pixel] = unwrapped[e.from] + step;
            ++region_size[static_cast<std::size_t>(id)];
            push_neighbours(queue, e.pixel);
        }
    }
    const int regions = static_cast<int>(region_size.size());

    // Absolute periods from the pins: v_p extrapolated (plane fit of v_p over
    // the region's pixels near the pin's image) to the pin's pixel.
    std::vector<std::map<long long, double>> votes(static_cast<std::size_t>(regions));  // offset -> support
    // The margin keeps the pixels nearest a (sharp) corner out: reach past it.
    const double radius = m_settings.pin_radius_px + 2.0 * m_settings.edge_margin_px;
    for (const Eigen::Vector3d& pin : pins_m) {
        const Eigen::Vector2d p = m_camera.project(pin);
        const double v_pin = projector_coordinate(pin);
        if (!p.allFinite() || !std::isfinite(v_pin)) continue;
        std::map<int, std::vector<std::size_t>> near;
        for (int y = std::max(0, static_cast<int>(std::floor(p.y() - radius))); y <= std::min(height - 1, static_cast<int>(std::ceil(p.y() + radius))); ++y)
            for (int x = std::max(0, static_cast<int>(std::floor(p.x() - radius))); x <= std::min(width - 1, static_cast<int>(std::ceil(p.x() + radius))); ++x) {
                const std::size_t i = at(x, y);
                if (region[i] >= 0 && region_size[static_cast<std::size_t>(region[i])] >= m_settings.min_region_px &&
                    (Eigen::Vector2d(x, y) - p).norm() <= radius)
                    near[region[i]].push_back(i);
            }
        for (const auto& [id, pixels] : near) {
            if (pixels.size() < 6) continue;
            Eigen::MatrixXd A(static_cast<Eigen::Index>(pixels.size()), 3);
            Eigen::VectorXd b(static_cast<Eigen::Index>(pixels.size()));
            for (std::size_t k = 0; k < pixels.size(); ++k) {
                const Eigen::Vector2d d = pixel_of(pixels[k]) - p;
                A.row(static_cast<Eigen::Index>(k)) << 1.0, d.x(), d.y();
                b(static_cast<Eigen::Index>(k)) = period * unwrapped[pixels[k]] / kTwoPi;
            }
            const Eigen::Vector3d fit = A.colPivHouseholderQr().solve(b);
            // The extrapolation names the periods to about one; the surface
            // near the pin must also lie near it in 3D (a period is several
            // centimetres of depth): of the neighbouring offsets, the one
            // whose points are closest to the pin.
            const long long extrapolated = std::llround((v_pin - fit(0)) / period);
            long long offset = extrapolated;
            double closest = std::numeric_limits<double>::infinity();
            for (long long candidate = extrapolated - 1; candidate <= extrapolated + 1; ++candidate) {
                std::vector<double> distances;
                for (const std::size_t i : pixels) {
                    const Eigen::Vector3d X = triangulate(pixel_of(i), period * (unwrapped[i] / kTwoPi + static_cast<double>(candidate)));
                    if (X.allFinite()) distances.push_back((X - pin).norm());
                }
                if (distances.size() < pixels.size() / 2) continue;
                std::nth_element(distances.begin(), distances.begin() + static_cast<std::ptrdiff_t>(distances.size() / 2), distances.end());
                if (distances[distances.size() / 2] < closest) {
                    closest = distances[distances.size() / 2];
                    offset = candidate;
                }
            }
            votes[static_cast<std::size_t>(id)][offset] += static_cast<double>(pixels.size());
        }
    }
    // The previous frame: the swatch moves far less than a period's depth
    // (centimetres) between frames, so each pixel's v_p changes by less than
    // half a period; the overlap's median names the region's periods.
    if (previous && previous->width == width && previous->height == height) {
        std::vector<std::vector<double>> shifts(static_cast<std::size_t>(regions));
        for (const std::size_t i : order) {
            const int id = region[i];
            const float v_before = previous->projector_coordinate.pixels[i];
            if (id < 0 || region_size[static_cast<std::size_t>(id)] < m_settings.min_region_px || !std::isfinite(v_before)) continue;
            shifts[static_cast<std::size_t>(id)].push_back((v_before - period * unwrapped[i] / kTwoPi) / period);
        }
        for (int id = 0; id < regions; ++id) {
            std::vector<double>& v = shifts[static_cast<std::size_t>(id)];
            if (static_cast<double>(v.size()) < m_settings.min_temporal_overlap * static_cast<double>(region_size[static_cast<std::size_t>(id)]))
                continue;
            std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
            if (votes[static_cast<std::size_t>(id)].empty())  // the pins come first: an error would propagate
                votes[static_cast<std::size_t>(id)][std::llround(v[v.size() / 2])] = static_cast<double>(v.size());
        }
    }
    std::vector<std::optional<long long>> offset(static_cast<std::size_t>(regions));
    for (int id = 0; id < regions; ++id) {
        const auto& v = votes[static_cast<std::size_t>(id)];
        // Pins that disagree on a region's periods show an unwrapping path
        // that slipped a period (a fold, an occluding edge): which side is
        // right is unknown, so none is measured.
        if (v.size() != 1) {
            if (v.size() > 1) ++out.regions_inconsistent;
            continue;
        }
        offset[static_cast<std::size_t>(id)] = v.begin()->first;
    }

    const auto camera_depth = [&](std::size_t i, double v_p) {
        const Eigen::Vector3d X = triangulate(pixel_of(i), v_p);
        return X.allFinite() ? (X - m_camera_centre).norm() : std::numeric_limits<double>::quiet_NaN();
    };
    // Pinless regions: the offset that continues a referenced neighbour's
    // depth across their border (pixel pairs up to 2 px apart), when one
    // offset clearly does. Repeated while regions join.
    for (bool joined = true; joined;) {
        joined = false;
        for (int id = 0; id < regions; ++id) {
            if (offset[static_cast<std::size_t>(id)] || region_size[static_cast<std::size_t>(id)] < m_settings.min_region_px) continue;
            std::vector<std::pair<std::size_t, std::size_t>> border;  // (this region's pixel, referenced pixel)
            for (const std::size_t i : order) {
                if (region[i] != id) continue;
                const int x = static_cast<int>(i % static_cast<std::size_t>(width)), y = static_cast<int>(i / static_cast<std::size_t>(width));
                for (int j = -2; j <= 2; ++j)
                    for (int k = -2; k <= 2; ++k) {
                        const int xn = x + k, yn = y + j;
                        if (xn < 0 || yn < 0 || xn >= width || yn >= height) continue;
                        const std::size_t n = at(xn, yn);
                        if (region[n] >= 0 && region[n] != id && offset[static_cast<std::size_t>(region[n])]) border.emplace_back(i, n);
                    }
            }
            if (border.size() < 10) continue;
            // Candidates around the offset that continues v_p itself.
            std::vector<double> continuation;
            for (const auto& [i, n] : border) {
                const double v_n = period * (unwrapped[n] / kTwoPi + static_cast<double>(*offset[static_cast<std::size_t>(region[n])]));
                continuation.push_back((v_n - period * unwrapped[i] / kTwoPi) / period);
            }
            std::nth_element(continuation.begin(), continuation.begin() + static_cast<std::ptrdiff_t>(continuation.size() / 2), continuation.end());
            const long long centre = std::llround(continuation[continuation.size() / 2]);
            double best = std::numeric_limits<double>::infinity(), second = best;
            long long best_offset = centre;
            for (long long candidate = centre - 2; candidate <= centre + 2; ++candidate) {
                std::vector<double> gaps;
                for (const auto& [i, n] : border) {
                    const double v_n = period * (unwrapped[n] / kTwoPi + static_cast<double>(*offset[static_cast<std::size_t>(region[n])]));
                    const double v_i = period * (unwrapped[i] / kTwoPi + static_cast<double>(candidate));
                    const double gap = std::abs(camera_depth(i, v_i) - camera_depth(n, v_n));
                    if (std::isfinite(gap)) gaps.push_back(gap);
                }
                if (gaps.size() < border.size() / 2) continue;
                std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
                const double median = gaps[gaps.size() / 2];
                if (median < best) {
                    second = best;
                    best = median;
                    best_offset = candidate;
                } else if (median < second) {
                    second = median;
                }
            }
            if (best <= m_settings.border_tolerance_m && second >= 2.0 * best + m_settings.border_tolerance_m) {
                offset[static_cast<std::size_t>(id)] = best_offset;
                joined = true;
            }
        }
    }

    // Triangulation of every referenced pixel.
    for (int id = 0; id < regions; ++id) {
        if (offset[static_cast<std::size_t>(id)] && region_size[static_cast<std::size_t>(id)] >= m_settings.min_region_px) ++out.regions_referenced;
        else ++out.regions_dropped;
    }
    for (const std::size_t i : order) {
        const int id = region[i];
        if (id < 0 || !offset[static_cast<std::size_t>(id)] || region_size[static_cast<std::size_t>(id)] < m_settings.min_region_px) continue;
        const double v_p = period * (unwrapped[i] / kTwoPi + static_cast<double>(*offset[static_cast<std::size_t>(id)]));
        const Eigen::Vector3d X = triangulate(pixel_of(i), v_p);
        if (!X.allFinite()) continue;
        out.projector_coordinate.pixels[i] = static_cast<float>(v_p);
        out.points_m[i] = X.cast<float>();
        ++out.measured_px;
    }
    return out;
}

StripeScanner scanner_for(const formats::Capture& capture, StripeScanSettings settings) {
    if (!(settings.stripe_gradient.norm() > 0.0)) settings.stripe_gradient = expected_stripe_gradient(capture);  // validates
    return StripeScanner(*capture.camera, *capture.projector, settings);
}

std::vector<Eigen::Vector3d> pin_positions_at(const formats::Capture& capture, int number) {
    std::vector<Eigen::Vector3d> pins;
    if (!capture.swatch) return pins;
    for (const formats::Pin& pin : capture.swatch->pins) {
        if (pin.positions_m.empty()) continue;
        const std::size_t i = static_cast<std::size_t>(std::clamp(number - 1, 0, static_cast<int>(pin.positions_m.size()) - 1));
        pins.push_back(pin.positions_m[i]);
    }
    return pins;
}

}  // namespace flowvid::video
