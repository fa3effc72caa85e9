#include "flowvid/video/angle_map_metric.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::video {

namespace {

void require_size(int w, int h, int ow, int oh, const char* what) {
    if (w != ow || h != oh)
        throw std::invalid_argument(std::string("angle-map metric: ") + what + " is " + std::to_string(ow) + "x" +
                                    std::to_string(oh) + ", the real frame " + std::to_string(w) + "x" + std::to_string(h));
}

render::PixelRect bounding_box(const std::vector<Eigen::Vector2i>& points) {
    if (points.empty()) return {};
    render::PixelRect r{points[0].x(), points[0].y(), points[0].x() + 1, points[0].y() + 1};
    for (const Eigen::Vector2i& p : points) {
        r.x0 = std::min(r.x0, p.x());
        r.y0 = std::min(r.y0, p.y());
        r.x1 = std::max(r.x1, p.x() + 1);
        r.y1 = std::max(r.y1, p.y() + 1);
    }
    return r;
}

// Sum over `from` of the squared distance to the nearest point of `to`, with
// an exact Euclidean distance transform over the bounding box of both point
// sets (every nearest point lies inside it, and so does the segment to it).
double sum_squared_distances(const std::vector<Eigen::Vector2i>& from, const std::vector<Eigen::Vector2i>& to,
                             int width, int height) {
    if (from.empty()) return 0.0;
    if (to.empty()) {
        const double far = static_cast<double>(width + height);  // as silhouette_edge_distance
        return far * far * static_cast<double>(from.size());
    }
    const render::PixelRect box = bounding_box(from).united(bounding_box(to));
    cv::Mat features(box.height(), box.width(), CV_8UC1, cv::Scalar(255));
    for (const Eigen::Vector2i& p : to) features.at<std::uint8_t>(p.y() - box.y0, p.x() - box.x0) = 0;
    cv::Mat distance;
    cv::distanceTransform(features, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
    double sum = 0.0;
    for (const Eigen::Vector2i& p : from) {
        const double d = distance.at<float>(p.y() - box.y0, p.x() - box.x0);
        sum += d * d;
    }
    return sum;
}

}  // namespace

void prepare_reference(ReferenceFrame& reference) {
    reference.edge_distance = metrics::edge_distance_field(reference.silhouette);
}

FrameError angle_map_frame_error(const ReferenceFrame& real, const AngleMap& sim, const metrics::Silhouette& sim_silhouette,
                                 const AngleMapMetricSettings& settings) {
    const int w = real.silhouette.width, h = real.silhouette.height;
    require_size(w, h, real.angles.width, real.angles.height, "the real angle map");
    require_size(w, h, sim.width, sim.height, "the simulated angle map");
    require_size(w, h, sim_silhouette.width, sim_silhouette.height, "the simulated silhouette");
    FrameError e;

    // Eq. 2.20 over pixels valid in both maps: only the union of the two
    // computed regions can hold any.
    const render::PixelRect region = real.angles.region.intersected(sim.region);
    const bool either = settings.mask_source == GradientMaskSource::real_or_simulated;
    const double planar = settings.planar_weight;
    double fold = 0.0, masked_sum = 0.0;
    for (int y = region.y0; y < region.y1; ++y) {
        const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
        for (int x = region.x0; x < region.x1; ++x) {
            const std::size_t i = row + static_cast<std::size_t>(x);
            if (!real.angles.valid[i] || !sim.valid[i]) continue;
            ++e.overlap_px;
            const bool fold_pixel = real.angles.gradient_mask[i] || (either && sim.gradient_mask[i]);
            const double d = video::orientation_difference(real.angles.angle_rad[i], sim.angle_rad[i]);
            if (fold_pixel) {
                ++e.masked_px;
                masked_sum += d * d;
                fold += d * d;
            } else if (planar > 0.0) {
                fold += planar * d * d;
            }
        }
    }
    e.fold_rad2 = fold;
    e.rms_angle_rad = e.masked_px > 0 ? std::sqrt(masked_sum / static_cast<double>(e.masked_px)) : 0.0;

    if (settings.silhouette_term == SilhouetteTerm::pixel_xor) {
        e.silhouette = static_cast<double>(metrics::silhouette_xor(real.silhouette, sim_silhouette));
    } else {
        const std::vector<Eigen::Vector2i> real_edges = metrics::silhouette_edge_pixels(real.silhouette);
        const std::vector<Eigen::Vector2i> sim_edges = metrics::silhouette_edge_pixels(sim_silhouette);
        double sim_to_real = 0.0;
        if (!real.edge_distance.values.empty()) {
            for (const Eigen::Vector2i& p : sim_edges) {
                const double d = real.edge_distance.at(p.x(), p.y());
                sim_to_real += d * d;
            }
        } else {
            sim_to_real = sum_squared_distances(sim_edges, real_edges, w, h);
        }
        e.silhouette = sim_to_real + sum_squared_distances(real_edges, sim_edges, w, h);
    }
    e.total = e.fold_rad2 + settings.alpha * e.silhouette;
    return e;
}

SequenceError combine_frames(const std::vector<FrameError>& frames, const std::vector<double>& weights) {
    if (frames.size() != weights.size())
        throw std::invalid_argument("combine_frames: " + std::to_string(frames.size()) + " frames but " +
                                    std::to_string(weights.size()) + " weights");
    SequenceError out;
    out.frames = frames;
    for (std::size_t k = 0; k < frames.size(); ++k) out.total += weights[k] * frames[k].total;
    return out;
}

std::vector<double> decaying_frame_weights(int count, int full_weight_frames, double half_life_frames) {
    std::vector<double> weights(static_cast<std::size_t>(std::max(count, 0)), 1.0);
    if (half_life_frames <= 0.0) return weights;
    for (int k = std::max(full_weight_frames, 0); k < count; ++k)
        weights[static_cast<std::size_t>(k)] = std::exp2(-(k - full_weight_frames + 1) / half_life_frames);
    return weights;
}

}  // namespace flowvid::video
