// The stripe renderer against analytic ray casting: a known plane seen by the
// captures' camera and lit by their projector. The projector coordinate of
// every pixel and the positions of the stripes along image columns must
// agree with the analytic projection to far below a pixel.

#include "flowvid/video/stripe_render.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

using namespace flowvid;
using namespace flowvid::video;

namespace {

constexpr double kPi = std::numbers::pi;

formats::Capture calibration() {
    return formats::read_capture(flowvid::testing::shared_path("captures/cloth-cotton-static-1"));
}

struct Plane {
    Eigen::Vector3d origin;  // a corner
    Eigen::Vector3d u;       // edge vectors
    Eigen::Vector3d v;
    Eigen::Vector3d normal() const { return u.cross(v).normalized(); }
};

// A (n+1) x (n+1) grid over the plane (flat: the subdivision must not matter).
void plane_mesh(const Plane& plane, int n, std::vector<Eigen::Vector3d>& vertices, std::vector<std::array<int, 3>>& triangles) {
    vertices.clear();
    for (int r = 0; r <= n; ++r)
        for (int c = 0; c <= n; ++c)
            vertices.push_back(plane.origin + plane.u * (static_cast<double>(c) / n) + plane.v * (static_cast<double>(r) / n));
    triangles = grid_triangles(n + 1, n + 1);
}

// The analytic projector row seen at image point (x, y): the camera ray
// through it meets the plane at p, which the projector sees at row
// fy y_p / z_p + cy (no distortion in the captures).
double analytic_projector_row(const formats::Capture& capture, const Plane& plane, double x, double y) {
    const formats::CameraModel& camera = *capture.camera;
    const Eigen::Vector3d ray_camera = camera.K.inverse() * Eigen::Vector3d(x, y, 1.0);
    const Eigen::Matrix3d R = camera.camera_from_world.topLeftCorner<3, 3>();
    const Eigen::Vector3d direction = R.transpose() * ray_camera;
    const Eigen::Vector3d centre = camera.centre_world();
    const Eigen::Vector3d n = plane.normal();
    const double t = n.dot(plane.origin - centre) / n.dot(direction);
    const Eigen::Vector3d p = centre + t * direction;
    const formats::CameraModel& projector = capture.projector->camera;
    const Eigen::Vector3d q = projector.to_camera(p);
    return projector.K(1, 1) * q.y() / q.z() + projector.K(1, 2);
}

Plane vertical_plane() {
    return {Eigen::Vector3d(-0.15, 0.01, 0.9), Eigen::Vector3d(0.3, 0.0, 0.0), Eigen::Vector3d(0.0, 0.0, 0.3)};
}

Plane tilted_plane() {
    // Turned 25 degrees about z and leaning 20 degrees back.
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(25.0 * kPi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d lean = Eigen::AngleAxisd(-20.0 * kPi / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
    const Eigen::Matrix3d R = turn * lean;
    return {Eigen::Vector3d(-0.12, 0.0, 0.92), R * Eigen::Vector3d(0.28, 0.0, 0.0), R * Eigen::Vector3d(0.0, 0.0, 0.28)};
}

}  // namespace

TEST(StripeRender, ProjectorCoordinateMatchesAnalyticRayCasting) {
    const formats::Capture capture = calibration();
    StripeRenderSettings settings;
    settings.projector_coordinates = true;
    StripeRenderer renderer(*capture.camera, *capture.projector, settings);
    for (const Plane& plane : {vertical_plane(), tilted_plane()}) {
        std::vector<Eigen::Vector3d> vertices;
        std::vector<std::array<int, 3>> triangles;
        plane_mesh(plane, 6, vertices, triangles);
        const StripeImage out = renderer.render(vertices, triangles);
        double worst = 0.0, worst_intensity = 0.0;
        long long covered = 0;
        for (int y = 0; y < out.image.height; ++y)
            for (int x = 0; x < out.image.width; ++x) {
                if (!out.silhouette.at(x, y)) continue;
                const float v = out.projector_coordinate.at(x, y);
                ASSERT_TRUE(std::isfinite(v));
                const double truth = analytic_projector_row(capture, plane, x, y);
                worst = std::max(worst, std::abs(v - truth));
                const double intensity = 0.5 + 0.5 * std::sin(2 * kPi * truth / capture.projector->pattern.period_px);
                worst_intensity = std::max(worst_intensity, std::abs(out.image.at(x, y) - intensity));
                ++covered;
            }
        std::printf("[measured] plane: %lld px covered, worst projector-row error %.2e px, intensity error %.2e\n",
                    covered, worst, worst_intensity);
        EXPECT_GT(covered, 15000);
        EXPECT_LT(worst, 2e-3);  // projector pixels (float output: ~3e-5 relative to 400)
        EXPECT_LT(worst_intensity, 1e-4);
    }
}

// Stripe phase in the image: along every image column, the rising crossings of
// intensity 0.5 (phase 0 mod 2 pi) found by linear interpolation between
// pixel centres agree with the analytic crossing (v_p = k * period, solved by
// bisection on the exact ray cast) to a few hundredths of a pixel.
TEST(StripeRender, StripePhaseAlongColumnsIsSubPixel) {
    const formats::Capture capture = calibration();
    StripeRenderer renderer(*capture.camera, *capture.projector);
    const double period = capture.projector->pattern.period_px;
    for (const Plane& plane : {vertical_plane(), tilted_plane()}) {
        std::vector<Eigen::Vector3d> vertices;
        std::vector<std::array<int, 3>> triangles;
        plane_mesh(plane, 3, vertices, triangles);
        const StripeImage out = renderer.render(vertices, triangles);
        double worst = 0.0, sum_squared = 0.0;
        long long crossings = 0;
        for (int x = 0; x < out.image.width; x += 3) {
            for (int y = 0; y + 1 < out.image.height; ++y) {
                if (!out.silhouette.at(x, y) || !out.silhouette.at(x, y + 1)) continue;
                const double a = out.image.at(x, y) - 0.5, b = out.image.at(x, y + 1) - 0.5;
                // A crossing of phase 0 (rising in phase): sin goes from - to +
                // as v_p grows; v_p may grow or fall with y, so test both.
                if ((a < 0.0) == (b < 0.0)) continue;
                const double va = analytic_projector_row(capture, plane, x, y);
                const double vb = analytic_projector_row(capture, plane, x, y + 1);
                const double k = std::floor(std::max(va, vb) / period) * period;
                // Phase 0 crossing only (not phase pi): k * period lies between va and vb.
                if (!(std::min(va, vb) <= k && k <= std::max(va, vb))) continue;
                const double measured = y + a / (a - b);
                double lo = y, hi = y + 1.0;
                const bool rising = vb > va;
                for (int i = 0; i < 60; ++i) {
                    const double mid = 0.5 * (lo + hi);
                    const bool below = analytic_projector_row(capture, plane, x, mid) < k;
                    if (below == rising)
                        lo = mid;
                    else
                        hi = mid;
                }
                const double error = measured - 0.5 * (lo + hi);
                worst = std::max(worst, std::abs(error));
                sum_squared += error * error;
                ++crossings;
            }
        }
        const double rms = std::sqrt(sum_squared / std::max(crossings, 1LL));
        std::printf("[measured] stripe crossings: %lld, RMS %.4f px, worst %.4f px\n", crossings, rms, worst);
        EXPECT_GT(crossings, 500);
        EXPECT_LT(worst, 0.02);
        EXPECT_LT(rms, 0.01);
    }
}

TEST(StripeRender, SilhouetteShadingAndGridTriangles) {
    const formats::Capture capture = calibration();
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    plane_mesh(vertical_plane(), 4, vertices, triangles);
    EXPECT_EQ(triangles.size(), 2u * 4 * 4);
    // Front faces point towards u x v: for the vertical plane, -y (towards the camera).
    const Eigen::Vector3d n = (vertices[static_cast<std::size_t>(triangles[0][1])] - vertices[static_cast<std::size_t>(triangles[0][0])])
                                  .cross(vertices[static_cast<std::size_t>(triangles[0][2])] - vertices[static_cast<std::size_t>(triangles[0][0])]);
    EXPECT_LT(n.y(), 0.0);

    StripeRenderer flat(*capture.camera, *capture.projector);
    StripeRenderSettings shaded_settings;
    shaded_settings.shading = StripeShading::lambertian;
    shaded_settings.ambient = 0.0;
    StripeRenderer shaded(*capture.camera, *capture.projector, shaded_settings);
    const StripeImage a = flat.render(vertices, triangles), b = shaded.render(vertices, triangles);
    EXPECT_EQ(a.silhouette.pixels, b.silhouette.pixels);
    // Lambertian: the ratio is |n . l| towards the projector, in (0, 1].
    const Eigen::Vector3d centre = vertices[vertices.size() / 2];
    const Eigen::Vector2d pixel = capture.camera->project(centre);
    const int x = static_cast<int>(std::lround(pixel.x())), y = static_cast<int>(std::lround(pixel.y()));
    ASSERT_TRUE(a.silhouette.at(x, y));
    const Eigen::Vector3d l = (capture.projector->camera.centre_world() - centre).normalized();
    const double expected = std::abs(l.y());
    EXPECT_NEAR(b.image.at(x, y) / a.image.at(x, y), expected, 0.01);
    // Outside the silhouette: the background value.
    EXPECT_EQ(a.image.at(2, 2), 0.0f);
    EXPECT_FALSE(a.silhouette.at(2, 2));

    formats::Projector bad = *capture.projector;
    bad.pattern.axis = "diagonal";
    EXPECT_THROW(StripeRenderer(*capture.camera, bad), std::invalid_argument);
}
