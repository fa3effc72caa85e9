#include "flowvid/metrics/silhouette.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::metrics {

namespace {

void require_same_size(const Silhouette& a, const Silhouette& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::invalid_argument("silhouettes of different sizes: " + std::to_string(a.width) + "x" +
                                    std::to_string(a.height) + " and " + std::to_string(b.width) + "x" +
                                    std::to_string(b.height));
}

// Distance (pixels) from every pixel centre to the nearest pixel where
// `features` is non-zero; `none` where there is no feature at all.
DistanceField distance_to_features(int width, int height, const std::vector<std::uint8_t>& features, float none) {
    DistanceField field;
    field.width = width;
    field.height = height;
    field.values.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), none);
    if (std::none_of(features.begin(), features.end(), [](std::uint8_t v) { return v != 0; })) return field;
    // cv::distanceTransform measures the distance to the nearest *zero* pixel.
    cv::Mat source(height, width, CV_8UC1);
    for (int y = 0; y < height; ++y) {
        std::uint8_t* row = source.ptr<std::uint8_t>(y);
        for (int x = 0; x < width; ++x)
            row[x] = features[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] ? 0 : 255;
    }
    cv::Mat distance;
    cv::distanceTransform(source, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
    for (int y = 0; y < height; ++y) {
        const float* row = distance.ptr<float>(y);
        std::copy(row, row + width, field.values.begin() + static_cast<std::ptrdiff_t>(y) * width);
    }
    return field;
}

}  // namespace

long long Silhouette::area_px() const {
    long long n = 0;
    for (std::uint8_t v : pixels) n += v != 0;
    return n;
}

Silhouette silhouette_from_image(const formats::Image& image, float threshold) {
    Silhouette s(image.width, image.height);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) s.set(x, y, image.at(x, y, 0) >= threshold);
    return s;
}

formats::Image silhouette_to_image(const Silhouette& silhouette) {
    formats::Image image;
    image.width = silhouette.width;
    image.height = silhouette.height;
    image.channels = 1;
    image.encoding = formats::Image::Encoding::srgb;
    image.pixels.resize(silhouette.pixels.size());
    for (std::size_t i = 0; i < silhouette.pixels.size(); ++i) image.pixels[i] = silhouette.pixels[i] ? 1.0f : 0.0f;
    return image;
}

long long silhouette_xor(const Silhouette& a, const Silhouette& b) {
    require_same_size(a, b);
    long long n = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) n += (a.pixels[i] != 0) != (b.pixels[i] != 0);
    return n;
}

double silhouette_iou(const Silhouette& a, const Silhouette& b) {
    require_same_size(a, b);
    long long both = 0, either = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        const bool ia = a.pixels[i] != 0, ib = b.pixels[i] != 0;
        both += ia && ib;
        either += ia || ib;
    }
    return either == 0 ? 1.0 : static_cast<double>(both) / static_cast<double>(either);
}

std::vector<Eigen::Vector2i> silhouette_edge_pixels(const Silhouette& s, bool border_is_outside) {
    std::vector<Eigen::Vector2i> edges;
    auto outside = [&](int x, int y) {
        if (x < 0 || y < 0 || x >= s.width || y >= s.height) return border_is_outside;
        return !s.at(x, y);
    };
    for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x)
            if (s.at(x, y) && (outside(x - 1, y) || outside(x + 1, y) || outside(x, y - 1) || outside(x, y + 1)))
                edges.emplace_back(x, y);
    return edges;
}

double DistanceField::sample(const Eigen::Vector2d& position, Eigen::Vector2d* gradient) const {
    if (width == 0 || height == 0) {
        if (gradient) gradient->setZero();
        return 0.0;
    }
    const double px = std::clamp(position.x(), 0.0, static_cast<double>(width - 1));
    const double py = std::clamp(position.y(), 0.0, static_cast<double>(height - 1));
    const int x0 = std::min(static_cast<int>(std::floor(px)), std::max(width - 2, 0));
    const int y0 = std::min(static_cast<int>(std::floor(py)), std::max(height - 2, 0));
    const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
    const double fx = px - x0, fy = py - y0;
    const double v00 = at(x0, y0), v10 = at(x1, y0), v01 = at(x0, y1), v11 = at(x1, y1);
    const double top = v00 + fx * (v10 - v00), bottom = v01 + fx * (v11 - v01);
    if (gradient) {
        *gradient = {(1.0 - fy) * (v10 - v00) + fy * (v11 - v01), bottom - top};
        // Outside the image the field is continued flat; give no slope there.
        if (position.x() != px) gradient->x() = 0.0;
        if (position.y() != py) gradient->y() = 0.0;
    }
    return top + fy * (bottom - top);
}

DistanceField edge_distance_field(const Silhouette& silhouette, bool border_is_outside) {
    std::vector<std::uint8_t> edges(silhouette.pixels.size(), 0);
    for (const Eigen::Vector2i& e : silhouette_edge_pixels(silhouette, border_is_outside))
        edges[static_cast<std::size_t>(e.y()) * static_cast<std::size_t>(silhouette.width) + static_cast<std::size_t>(e.x())] = 1;
    return distance_to_features(silhouette.width, silhouette.height, edges,
                                static_cast<float>(silhouette.width + silhouette.height));
}

DistanceField signed_distance_field(const Silhouette& silhouette) {
    const float far = static_cast<float>(silhouette.width + silhouette.height);
    std::vector<std::uint8_t> outside(silhouette.pixels.size());
    for (std::size_t i = 0; i < outside.size(); ++i) outside[i] = silhouette.pixels[i] ? 0 : 1;
    const DistanceField to_inside = distance_to_features(silhouette.width, silhouette.height, silhouette.pixels, far);
    const DistanceField to_outside = distance_to_features(silhouette.width, silhouette.height, outside, far);
    DistanceField field;
    field.width = silhouette.width;
    field.height = silhouette.height;
    field.values.resize(silhouette.pixels.size());
    for (std::size_t i = 0; i < field.values.size(); ++i)
        field.values[i] = silhouette.pixels[i] ? -(to_outside.values[i] - 0.5f) : (to_inside.values[i] - 0.5f);
    return field;
}

EdgeDistance silhouette_edge_distance(const Silhouette& from, const Silhouette& to) {
    require_same_size(from, to);
    const DistanceField field = edge_distance_field(to);
    EdgeDistance result;
    for (const Eigen::Vector2i& e : silhouette_edge_pixels(from)) {
        const double d = field.at(e.x(), e.y());
        result.sum_squared_px2 += d * d;
        ++result.edge_pixels;
    }
    if (result.edge_pixels > 0) {
        result.mean_squared_px2 = result.sum_squared_px2 / static_cast<double>(result.edge_pixels);
        result.rms_px = std::sqrt(result.mean_squared_px2);
    }
    return result;
}

EdgeDistance symmetric_edge_distance(const Silhouette& a, const Silhouette& b) {
    const EdgeDistance ab = silhouette_edge_distance(a, b);
    const EdgeDistance ba = silhouette_edge_distance(b, a);
    EdgeDistance result;
    result.sum_squared_px2 = ab.sum_squared_px2 + ba.sum_squared_px2;
    result.edge_pixels = ab.edge_pixels + ba.edge_pixels;
    if (result.edge_pixels > 0) {
        result.mean_squared_px2 = result.sum_squared_px2 / static_cast<double>(result.edge_pixels);
        result.rms_px = std::sqrt(result.mean_squared_px2);
    }
    return result;
}

}  // namespace flowvid::metrics
