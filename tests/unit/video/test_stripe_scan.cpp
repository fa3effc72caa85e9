// The structured-light scan against exact geometry: triangulation inverts the
// calibrated projections (with and without lens distortion), and a rendered
// folded swatch under the captures' camera and projector is scanned back to
// its true surface.

#include "flowvid/video/stripe_render.hpp"
#include "flowvid/video/stripe_scan.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

using namespace flowvid;
using namespace flowvid::video;

namespace {

constexpr double kPi = std::numbers::pi;

formats::Capture calibration() {
    return formats::read_capture(flowvid::testing::shared_path("captures/cloth-cotton-static-1"));
}

// A swatch hanging from its top corners (like the captures'), with folds:
// waves across the width whose depth grows towards the hem, and a bulge.
void folded_swatch(int n, std::vector<Eigen::Vector3d>& vertices, std::vector<std::array<int, 3>>& triangles) {
    vertices.clear();
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            const double u = static_cast<double>(c) / (n - 1), v = static_cast<double>(r) / (n - 1);  // v = 0 at the hem
            const double depth = 0.025 * (1.0 - v) * std::sin(2.0 * kPi * 1.5 * u) + 0.03 * std::sin(kPi * u) * std::sin(kPi * v);
            vertices.emplace_back(-0.15 + 0.3 * u, depth, 0.66 + 0.3 * v - 0.02 * std::sin(kPi * u) * v);
        }
    triangles = grid_triangles(n, n);
}

formats::CameraModel with_distortion(formats::CameraModel camera) {
    camera.dist = {-0.12, 0.03, 0.0008, -0.0005, 0.002};
    return camera;
}

}  // namespace

TEST(StripeScan, RayInvertsProjectionWithDistortion) {
    const formats::Capture capture = calibration();
    for (const bool distorted : {false, true}) {
        const formats::CameraModel camera = distorted ? with_distortion(*capture.camera) : *capture.camera;
        std::mt19937 random(3);
        std::uniform_real_distribution<double> pixel(0.0, 1.0);
        for (int k = 0; k < 200; ++k) {
            const Eigen::Vector2d p(pixel(random) * (camera.width - 1), pixel(random) * (camera.height - 1));
            const Eigen::Vector3d ray = camera.ray_camera(p);
            EXPECT_LT((camera.project_camera_point(2.0 * ray) - p).norm(), 1e-9) << "pixel " << p.transpose();
        }
    }
}

TEST(StripeScan, TriangulationInvertsCameraAndProjector) {
    const formats::Capture capture = calibration();
    for (const bool distorted : {false, true}) {
        formats::Projector projector = *capture.projector;
        formats::CameraModel camera = *capture.camera;
        if (distorted) {
            camera = with_distortion(camera);
            projector.camera = with_distortion(projector.camera);
        }
        for (const char* axis : {"rows", "columns"}) {
            projector.pattern.axis = axis;
            StripeScanSettings settings;
            settings.stripe_gradient = {0.0, 1.0};
            const StripeScanner scanner(camera, projector, settings);
            std::vector<Eigen::Vector3d> vertices;
            std::vector<std::array<int, 3>> triangles;
            folded_swatch(9, vertices, triangles);
            for (const Eigen::Vector3d& X : vertices) {
                const Eigen::Vector3d back = scanner.triangulate(camera.project(X), scanner.projector_coordinate(X));
                EXPECT_LT((back - X).norm(), 1e-8) << axis << (distorted ? ", distorted" : "") << " at " << X.transpose();
            }
        }
    }
}

TEST(StripeScan, RecoversARenderedFoldedSwatch) {
    const formats::Capture capture = calibration();
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    folded_swatch(61, vertices, triangles);
    StripeRenderSettings render;
    render.shading = StripeShading::lambertian;  // shading the scan must see through
    render.ambient = 0.25;
    render.background = 0.05f;
    render.projector_coordinates = true;
    StripeRenderer renderer(*capture.camera, *capture.projector, render);
    StripeImage image = renderer.render(vertices, triangles);
    // Sensor noise, 1 % of full scale (seeded).
    std::mt19937 random(7);
    std::normal_distribution<float> noise(0.0f, 0.01f);
    for (float& value : image.image.pixels) value = std::max(0.0f, value + noise(random));

    StripeScanner scanner = scanner_for(capture);
    const std::vector<Eigen::Vector3d> pins = {vertices[61 * 60], vertices[61 * 61 - 1]};  // top corners
    const StripeScan scan = scanner.scan(image.image, image.silhouette, pins);

    std::vector<double> errors_mm;
    long long wrong_period = 0;
    for (int y = 0; y < scan.height; ++y)
        for (int x = 0; x < scan.width; ++x) {
            if (!scan.measured(x, y)) continue;
            const float v_true = image.projector_coordinate.at(x, y);
            ASSERT_TRUE(std::isfinite(v_true)) << "measured outside the silhouette at " << x << ", " << y;
            const Eigen::Vector3d truth = scanner.triangulate({x, y}, v_true);
            const Eigen::Vector3f point = scan.points_m[scan.projector_coordinate.index(x, y)];
            errors_mm.push_back(1e3 * (point.cast<double>() - truth).norm());
            if (std::abs(scan.projector_coordinate.at(x, y) - v_true) > 0.5 * capture.projector->pattern.period_px) ++wrong_period;
        }
    ASSERT_FALSE(errors_mm.empty());
    std::sort(errors_mm.begin(), errors_mm.end());
    const double median = errors_mm[errors_mm.size() / 2];
    const double p95 = errors_mm[errors_mm.size() * 95 / 100];
    const double coverage = static_cast<double>(scan.measured_px) / static_cast<double>(scan.silhouette_px);
    std::printf("scan of a folded swatch: coverage %.3f, median %.3f mm, 95th %.3f mm, wrong period %lld of %lld px\n",
                coverage, median, p95, wrong_period, scan.measured_px);
    EXPECT_GT(coverage, 0.85);
    EXPECT_LT(median, 0.5);
    EXPECT_LT(p95, 2.0);
    EXPECT_EQ(wrong_period, 0);
}

// The folded swatch (31 x 31) rendered without shading or noise, and its top corners.
struct CleanFrame {
    StripeImage image;
    std::vector<Eigen::Vector3d> pins;
};

CleanFrame clean_frame(const formats::Capture& capture) {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    folded_swatch(31, vertices, triangles);
    StripeRenderer renderer(*capture.camera, *capture.projector);
    return {renderer.render(vertices, triangles), {vertices[31 * 30], vertices[31 * 31 - 1]}};
}

TEST(StripeScan, WithoutAReferenceNothingIsGuessed) {
    const formats::Capture capture = calibration();
    const StripeImage image = clean_frame(capture).image;
    StripeScanner scanner = scanner_for(capture);
    const StripeScan scan = scanner.scan(image.image, image.silhouette, {});  // no pins: periods unknown
    EXPECT_GT(scan.silhouette_px, 1000);
    EXPECT_EQ(scan.measured_px, 0);
    EXPECT_EQ(scan.regions_referenced, 0);
    EXPECT_GE(scan.regions_dropped, 1);
}

TEST(StripeScan, ThePreviousFrameReferencesRegionsWithoutPins) {
    const formats::Capture capture = calibration();
    const CleanFrame frame = clean_frame(capture);
    const StripeImage& image = frame.image;
    StripeScanner scanner = scanner_for(capture);
    const StripeScan with_pins = scanner.scan(image.image, image.silhouette, frame.pins);
    ASSERT_GT(with_pins.measured_px, 1000);
    // The next frame without pins (e.g. a corner out of view): its periods come from the previous scan.
    const StripeScan next = scanner.scan(image.image, image.silhouette, {}, &with_pins);
    EXPECT_EQ(next.measured_px, with_pins.measured_px);
    for (std::size_t i = 0; i < next.projector_coordinate.pixels.size(); ++i) {
        if (std::isfinite(with_pins.projector_coordinate.pixels[i])) {
            ASSERT_EQ(next.projector_coordinate.pixels[i], with_pins.projector_coordinate.pixels[i]) << "pixel " << i;
        }
    }
}
