#include "flowvid/video/cloth_footage.hpp"

#include "flowvid/error.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::video {

namespace {

cv::Mat disc(int radius) {
    return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
}

}  // namespace

metrics::Silhouette segment_against_background(const formats::Image& frame, const formats::Image& background,
                                               const SegmentationSettings& settings) {
    if (frame.width != background.width || frame.height != background.height)
        throw std::invalid_argument("segmentation: frame " + std::to_string(frame.width) + "x" +
                                    std::to_string(frame.height) + " and background " + std::to_string(background.width) +
                                    "x" + std::to_string(background.height) + " differ in size");
    const int w = frame.width, h = frame.height;
    const int fc = std::max(frame.channels, 1), bc = std::max(background.channels, 1);
    const int channels = std::min(std::min(fc, bc), 3);
    cv::Mat difference(h, w, CV_8UC1);
    for (int y = 0; y < h; ++y) {
        auto* row = difference.ptr<std::uint8_t>(y);
        for (int x = 0; x < w; ++x) {
            float d = 0.0f;
            for (int c = 0; c < channels; ++c) d = std::max(d, std::abs(frame.at(x, y, c) - background.at(x, y, c)));
            row[x] = static_cast<std::uint8_t>(std::clamp(std::lround(d * 255.0f), 0L, 255L));
        }
    }
    double threshold = settings.difference_threshold * 255.0;
    if (threshold <= 0.0) {
        cv::Mat unused;
        threshold = cv::threshold(difference, unused, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
        threshold = std::max(threshold, 6.0);  // never inside the sensor noise (sigma 1/255)
    }
    cv::Mat mask;
    cv::threshold(difference, mask, threshold, 255, cv::THRESH_BINARY);
    if (settings.open_radius_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_OPEN, disc(settings.open_radius_px));
    if (settings.close_radius_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, disc(settings.close_radius_px));
    if (settings.keep_largest_component) {
        cv::Mat labels, stats, centroids;
        const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
        int best = 0, best_area = 0;
        for (int i = 1; i < n; ++i) {
            const int area = stats.at<int>(i, cv::CC_STAT_AREA);
            if (area > best_area) {
                best_area = area;
                best = i;
            }
        }
        mask = best > 0 ? (labels == best) : cv::Mat::zeros(h, w, CV_8UC1);
    }
    if (settings.fill_holes) {
        // Background reachable from the image border stays background; every
        // other background pixel is a hole in the object.
        cv::Mat padded;
        cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
        cv::floodFill(padded, cv::Point(0, 0), 128);
        for (int y = 0; y < h; ++y) {
            const auto* p = padded.ptr<std::uint8_t>(y + 1) + 1;
            auto* m = mask.ptr<std::uint8_t>(y);
            for (int x = 0; x < w; ++x) m[x] = p[x] == 128 ? 0 : 255;
        }
    }
    metrics::Silhouette out(w, h);
    for (int y = 0; y < h; ++y) {
        const auto* m = mask.ptr<std::uint8_t>(y);
        for (int x = 0; x < w; ++x) out.set(x, y, m[x] != 0);
    }
    return out;
}

struct ClothFootage::Impl {
    formats::Capture capture;
    formats::FrameSource source;
    SegmentationSettings segmentation;
    bool masks = false;
    std::optional<formats::Image> background;

    Impl(const formats::Capture& c, SegmentationSettings s) : capture(c), source(c), segmentation(s) {}
};

ClothFootage::ClothFootage(const formats::Capture& capture, SegmentationSettings segmentation) {
    Diagnostics diagnostics(capture.json_path.empty() ? capture.folder + "/capture.json" : capture.json_path);
    if (!capture.is_cloth())
        diagnostics.error("/kind", "is '" + capture.kind + "', cloth fitting needs cloth.static or cloth.waving",
                          "pass a cloth capture");
    if (!capture.camera) diagnostics.error("/camera", "is missing", "add the camera calibration");
    if (!capture.projector)
        diagnostics.error("/projector", "is missing: the angle-map metric needs the stripe projector's calibration",
                          "add the projector calibration and pattern");
    const bool has_masks = !capture.masks.empty();
    const bool has_background = !capture.background.empty();
    using Source = SegmentationSettings::Source;
    if (segmentation.source == Source::masks && !has_masks)
        diagnostics.error("/masks", "is missing but the segmentation asks for masks", "segment against the background");
    if (segmentation.source == Source::background && !has_background)
        diagnostics.error("/background", "is missing but the segmentation asks for the background plate",
                          "use the masks, or add background.png");
    if (segmentation.source == Source::automatic && !has_masks && !has_background)
        diagnostics.error("/masks", "neither masks nor a background plate: the swatch cannot be segmented",
                          "add masks or background.png to the capture");
    diagnostics.throw_if_errors();

    m_impl = std::make_unique<Impl>(capture, segmentation);
    m_impl->masks = segmentation.source == Source::masks || (segmentation.source == Source::automatic && has_masks);
    if (!m_impl->masks) m_impl->background = m_impl->source.background();
}

ClothFootage::~ClothFootage() = default;
ClothFootage::ClothFootage(ClothFootage&&) noexcept = default;
ClothFootage& ClothFootage::operator=(ClothFootage&&) noexcept = default;

const formats::Capture& ClothFootage::capture() const { return m_impl->capture; }
const formats::CameraModel& ClothFootage::camera() const { return *m_impl->capture.camera; }
const formats::Projector& ClothFootage::projector() const { return *m_impl->capture.projector; }
int ClothFootage::first() const { return m_impl->source.first(); }
int ClothFootage::count() const { return m_impl->source.count(); }
int ClothFootage::last() const { return m_impl->source.last(); }
bool ClothFootage::uses_masks() const { return m_impl->masks; }

ClothFrame ClothFootage::frame(int number) {
    ClothFrame out;
    out.number = number;
    const formats::Image rgb = m_impl->source.frame(number);
    out.gray = gray_from_image(rgb, true);
    if (m_impl->masks)
        out.silhouette = metrics::silhouette_from_image(m_impl->source.mask(number), 0.5f);
    else
        out.silhouette = segment_against_background(rgb, *m_impl->background, m_impl->segmentation);
    return out;
}

Eigen::Vector2d expected_stripe_gradient(const formats::Capture& capture) {
    Diagnostics diagnostics(capture.json_path.empty() ? capture.folder + "/capture.json" : capture.json_path);
    if (!capture.camera) diagnostics.error("/camera", "is missing", "add the camera calibration");
    if (!capture.projector) diagnostics.error("/projector", "is missing", "add the projector calibration");
    if (!capture.swatch || capture.swatch->pins.empty() || capture.swatch->pins[0].positions_m.empty())
        diagnostics.error("/swatch/pins", "no pin positions: cannot tell where the swatch hangs",
                          "give at least one pin with positions");
    diagnostics.throw_if_errors();
    const formats::CameraModel& camera = *capture.camera;
    const formats::Projector& projector = *capture.projector;
    const auto& pins = capture.swatch->pins;

    // The swatch centre: half its height below the mean of the pins' first positions.
    Eigen::Vector3d top = Eigen::Vector3d::Zero();
    for (const formats::Pin& pin : pins) top += pin.positions_m.front();
    top /= static_cast<double>(pins.size());
    const Eigen::Vector3d up(0.0, 0.0, 1.0);
    const Eigen::Vector3d centre = top - 0.5 * std::max(capture.swatch->height_m, 0.01) * up;
    // In-plane horizontal direction: along the pins, or else across the view.
    Eigen::Vector3d across = pins.size() >= 2 ? Eigen::Vector3d(pins.back().positions_m.front() - pins.front().positions_m.front())
                                              : Eigen::Vector3d::Zero();
    across.z() = 0.0;
    if (across.norm() < 1e-6) {
        Eigen::Vector3d view = centre - camera.centre_world();
        across = view.cross(up);
    }
    across.normalize();

    const bool rows = projector.pattern.axis != "columns";
    auto stripe = [&](const Eigen::Vector3d& p) {
        const Eigen::Vector2d q = projector.camera.project(p);
        return rows ? q.y() : q.x();
    };
    // d(image)/d(surface) and d(v_p)/d(surface) by central differences (1 mm).
    const double h = 1e-3;
    Eigen::Matrix2d J;
    Eigen::Vector2d g;
    const Eigen::Vector3d directions[2] = {across, up};
    for (int k = 0; k < 2; ++k) {
        const Eigen::Vector3d a = centre + h * directions[k], b = centre - h * directions[k];
        J.col(k) = (camera.project(a) - camera.project(b)) / (2.0 * h);
        g(k) = (stripe(a) - stripe(b)) / (2.0 * h);
    }
    // v_p as a function of the image position: grad = J^-T g.
    const Eigen::Vector2d image_gradient = J.transpose().fullPivLu().solve(g);
    const double per_pixel = image_gradient.norm();
    if (!std::isfinite(per_pixel) || per_pixel <= 0.0)
        throw ValidationError({Problem{Problem::Severity::error, diagnostics.file(), "/projector",
                                       "the projector's stripes do not vary across the swatch as calibrated",
                                       "check projector.camera_from_world and the pattern axis"}});
    return image_gradient;
}

double expected_stripe_period_px(const formats::Capture& capture) {
    return capture.projector->pattern.period_px / expected_stripe_gradient(capture).norm();
}

}  // namespace flowvid::video
