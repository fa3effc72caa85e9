#pragma once
// Silhouette metrics of the thesis, section 2.3.3: the pixel XOR count
// (eq. 2.5), the edge distance (eq. 2.6, computed with a Euclidean distance
// transform instead of a search), intersection over union, and the distance
// fields the rigid-body fitter samples.
//
// A silhouette edge pixel is an object pixel with at least one 4-neighbour
// outside the object: for binary silhouettes this is the set of pixels a
// Canny detector marks on the inner side of the boundary (the thesis uses
// Canny). Pixels beyond the image border count as "not outside" by default,
// so an object cut by the border gets no edge along the border, where the
// cut is the camera's and not the object's.

#include "flowvid/formats/capture.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace flowvid::metrics {

// A binary image, row-major from the top row: 1 = object, 0 = background.
struct Silhouette {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> pixels;

    Silhouette() = default;
    Silhouette(int w, int h) : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0) {}
    bool at(int x, int y) const {
        return pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] != 0;
    }
    void set(int x, int y, bool value) {
        pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] = value ? 1 : 0;
    }
    long long area_px() const;
};

// Channel 0 of an image (e.g. a capture mask loaded with formats::load_image)
// thresholded: value >= threshold is object.
Silhouette silhouette_from_image(const formats::Image& image, float threshold = 0.5f);
// The other way, for writing PNGs: one channel, 1.0 = object.
formats::Image silhouette_to_image(const Silhouette& silhouette);

// Eq. 2.5: the number of pixels where the two silhouettes differ. Throws
// std::invalid_argument when the sizes differ (also for the functions below).
long long silhouette_xor(const Silhouette& a, const Silhouette& b);

// |A and B| / |A or B|; 1 when both are empty.
double silhouette_iou(const Silhouette& a, const Silhouette& b);

// Object pixels with a 4-neighbour outside the object (see the note above).
std::vector<Eigen::Vector2i> silhouette_edge_pixels(const Silhouette& silhouette, bool border_is_outside = false);

// A float image of the same size, row-major.
struct DistanceField {
    int width = 0;
    int height = 0;
    std::vector<float> values;
    float at(int x, int y) const {
        return values[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
    }
    // Bilinear value at a sub-pixel position (pixel centres at integers),
    // clamped at the border; `gradient` (optional) receives d value / d (x, y).
    double sample(const Eigen::Vector2d& position, Eigen::Vector2d* gradient = nullptr) const;
};

// Euclidean distance (pixels) from every pixel centre to the nearest edge
// pixel centre of `silhouette` (exact EDT, cv::distanceTransform with
// DIST_MASK_PRECISE). Without any edge pixel every value is width + height.
DistanceField edge_distance_field(const Silhouette& silhouette, bool border_is_outside = false);

// Signed distance to the silhouette boundary, in pixels: negative inside,
// positive outside, zero half-way between an object pixel centre and a
// background pixel centre (where a coverage threshold of 0.5 puts the true
// edge of a straight boundary). Bilinear samples of it are a smooth, sub-pixel
// measure of how far a point is from the observed outline.
DistanceField signed_distance_field(const Silhouette& silhouette);

// Eq. 2.6 (one direction): for every edge pixel of `from`, the squared
// distance to the nearest edge pixel of `to`, summed. `mean_squared_px2` and
// `rms_px` divide by the number of edge pixels of `from`. When `to` has no
// edge pixel, each distance is width + height of the image.
struct EdgeDistance {
    double sum_squared_px2 = 0.0;
    long long edge_pixels = 0;
    double mean_squared_px2 = 0.0;
    double rms_px = 0.0;
};
EdgeDistance silhouette_edge_distance(const Silhouette& from, const Silhouette& to);
// Both directions: the sums and counts added (so each edge pixel of either silhouette counts once).
EdgeDistance symmetric_edge_distance(const Silhouette& a, const Silhouette& b);

}  // namespace flowvid::metrics
