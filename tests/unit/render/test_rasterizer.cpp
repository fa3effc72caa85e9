// The software rasterizer against analytic projections: silhouettes of a
// plane and a rotated cube pixel by pixel, areas, depth and barycentrics,
// the fill rule on shared edges, near-plane clipping, distortion.

#include "flowvid/render/rasterizer.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <random>

using namespace flowvid;
using render::Framebuffer;
using render::RasterSettings;
using render::VertexSpace;

namespace {

formats::CameraModel test_camera() {
    formats::CameraModel camera;
    camera.width = 480;
    camera.height = 360;
    camera.K << 640.0, 0.0, 239.5, 0.0, 640.0, 179.5, 0.0, 0.0, 1.0;
    return camera;
}

// Signed distance of p to the boundary of a convex polygon (counter-clockwise
// or clockwise): positive inside.
double convex_inside_distance(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
    double area2 = 0.0;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const Eigen::Vector2d& a = poly[i];
        const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
        area2 += a.x() * b.y() - a.y() * b.x();
    }
    const double orientation = area2 > 0 ? 1.0 : -1.0;
    double d = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const Eigen::Vector2d& a = poly[i];
        const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
        const Eigen::Vector2d e = b - a;
        d = std::min(d, orientation * (e.x() * (p.y() - a.y()) - e.y() * (p.x() - a.x())) / e.norm());
    }
    return d;
}

double polygon_area(const std::vector<Eigen::Vector2d>& poly) {
    double area2 = 0.0;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const Eigen::Vector2d& a = poly[i];
        const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
        area2 += a.x() * b.y() - a.y() * b.x();
    }
    return std::abs(area2) / 2.0;
}

// Convex hull (monotone chain), counter-clockwise.
std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> points) {
    std::sort(points.begin(), points.end(),
              [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
    auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
    };
    std::vector<Eigen::Vector2d> hull(2 * points.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
        hull[k++] = points[i];
    }
    for (std::size_t i = points.size() - 1, t = k + 1; i-- > 0;) {
        while (k >= t && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
        hull[k++] = points[i];
    }
    hull.resize(k - 1);
    return hull;
}

struct Cube {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
};

// An axis-aligned cube of half-size h (outward counter-clockwise faces), then rotated and moved.
Cube make_cube(double h, const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
    Cube c;
    for (int i = 0; i < 8; ++i)
        c.vertices.push_back(R * Eigen::Vector3d((i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h) + t);
    c.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                   {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    return c;
}

}  // namespace

TEST(Rasterizer, PlaneSilhouetteMatchesAnalyticProjection) {
    const formats::CameraModel camera = test_camera();
    // A tilted square plane 0.6 m wide about 3.2 m away.
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    const Eigen::Vector3d centre(0.13, -0.07, 3.2);
    std::vector<Eigen::Vector3d> vertices;
    for (auto [u, v] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) vertices.push_back(R * Eigen::Vector3d(0.3 * u, 0.3 * v, 0) + centre);
    const std::vector<std::array<int, 3>> triangles = {{0, 1, 2}, {0, 2, 3}};
    std::vector<Eigen::Vector2d> polygon;
    for (const Eigen::Vector3d& v : vertices) polygon.push_back(camera.project_camera_point(v));

    const Framebuffer fb = render::rasterize(vertices, triangles, VertexSpace::camera, camera);
    long long wrong = 0, count = 0;
    double worst_wrong_distance = 0.0;
    for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x) {
            const double d = convex_inside_distance(polygon, Eigen::Vector2d(x, y));
            const bool expected = d > 0;
            count += fb.covered(x, y);
            if (fb.covered(x, y) != expected) {
                ++wrong;
                worst_wrong_distance = std::max(worst_wrong_distance, std::abs(d));
            }
        }
    // Point sampling at pixel centres is exact: no pixel is misclassified
    // (every edge within 0.5 px holds a fortiori).
    EXPECT_EQ(wrong, 0) << "worst misclassified centre is " << worst_wrong_distance << " px from the edge";
    EXPECT_NEAR(static_cast<double>(count), polygon_area(polygon), 0.01 * polygon_area(polygon));

    RasterSettings aa;
    aa.supersampling = 8;
    const Framebuffer fine = render::rasterize(vertices, triangles, VertexSpace::camera, camera, aa);
    EXPECT_NEAR(fine.covered_area_px(), polygon_area(polygon), 0.001 * polygon_area(polygon));
}

TEST(Rasterizer, RotatedCubeSilhouetteDepthAndBarycentrics) {
    formats::CameraModel camera = test_camera();
    // Given in world space through a camera that is not at the origin.
    camera.camera_from_world.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    camera.camera_from_world.topRightCorner<3, 1>() = Eigen::Vector3d(0.05, -0.1, 0.3);
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX())).toRotationMatrix();
    const Cube cube = make_cube(0.25, R, Eigen::Vector3d(-0.2, 0.1, 3.1));

    std::vector<Eigen::Vector2d> projected;
    for (const Eigen::Vector3d& v : cube.vertices) projected.push_back(camera.project(v));
    const std::vector<Eigen::Vector2d> hull = convex_hull(projected);

    const Framebuffer fb = render::rasterize(cube.vertices, cube.triangles, VertexSpace::world, camera);
    long long wrong = 0;
    double max_reprojection_px = 0.0, max_depth_error = 0.0;
    const Eigen::Matrix3d Rc = camera.camera_from_world.topLeftCorner<3, 3>();
    const Eigen::Vector3d tc = camera.camera_from_world.topRightCorner<3, 1>();
    for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x) {
            const bool expected = convex_inside_distance(hull, Eigen::Vector2d(x, y)) > 0;
            if (fb.covered(x, y) != expected) ++wrong;
            if (!fb.covered(x, y)) continue;
            // The interpolated world point lies on the pixel's ray...
            const std::optional<Eigen::Vector3d> world = render::interpolate(fb, cube.triangles, cube.vertices, x, y);
            ASSERT_TRUE(world.has_value());
            max_reprojection_px = std::max(max_reprojection_px, (camera.project(*world) - Eigen::Vector2d(x, y)).norm());
            // ... at the entry point of the ray into the cube (slab test in the cube's frame).
            const Eigen::Vector3d dir_cam = camera.K.inverse() * Eigen::Vector3d(x, y, 1.0);
            const Eigen::Vector3d origin_world = -Rc.transpose() * tc;
            const Eigen::Vector3d dir_world = Rc.transpose() * dir_cam;
            const Eigen::Vector3d o = R.transpose() * (origin_world - Eigen::Vector3d(-0.2, 0.1, 3.1));
            const Eigen::Vector3d d = R.transpose() * dir_world;
            double t_in = -1e9, t_out = 1e9;
            for (int k = 0; k < 3; ++k) {
                const double t1 = (-0.25 - o[k]) / d[k], t2 = (0.25 - o[k]) / d[k];
                t_in = std::max(t_in, std::min(t1, t2));
                t_out = std::min(t_out, std::max(t1, t2));
            }
            if (t_in < t_out) {
                const double expected_depth = t_in * dir_cam.z();  // dir_cam has z = 1 per unit t... scaled below
                max_depth_error = std::max(max_depth_error, std::abs(fb.depth_m[fb.index_of(x, y)] - expected_depth));
            }
        }
    EXPECT_EQ(wrong, 0);
    EXPECT_LT(max_reprojection_px, 2e-3);
    EXPECT_LT(max_depth_error, 1e-5);

    RasterSettings aa;
    aa.supersampling = 8;
    const Framebuffer fine = render::rasterize(cube.vertices, cube.triangles, VertexSpace::world, camera, aa);
    EXPECT_NEAR(fine.covered_area_px(), polygon_area(hull), 0.001 * polygon_area(hull));

    // Back-face culling leaves the silhouette of a closed mesh unchanged.
    RasterSettings cull;
    cull.cull_back_faces = true;
    EXPECT_EQ(render::rasterize(cube.vertices, cube.triangles, VertexSpace::world, camera, cull).silhouette(), fb.silhouette());
}

TEST(Rasterizer, CullingBackFacesKeepsANonConvexClosedMeshsSilhouette) {
    // A torus (outward counter-clockwise faces) seen from many directions: its
    // hole and the parts of its ring hidden behind others must survive culling.
    const int rings = 24, sides = 12;
    const double major = 0.12, minor = 0.045;
    std::vector<Eigen::Vector3d> local;
    std::vector<std::array<int, 3>> triangles;
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < sides; ++j) {
            const double u = 2.0 * M_PI * i / rings, v = 2.0 * M_PI * j / sides;
            local.emplace_back((major + minor * std::cos(v)) * std::cos(u), (major + minor * std::cos(v)) * std::sin(u),
                               minor * std::sin(v));
            const int a = i * sides + j, b = ((i + 1) % rings) * sides + j;
            const int c = ((i + 1) % rings) * sides + (j + 1) % sides, d = i * sides + (j + 1) % sides;
            triangles.push_back({a, b, c});
            triangles.push_back({a, c, d});
        }
    const formats::CameraModel camera = test_camera();
    std::mt19937 random(3);
    std::normal_distribution<double> normal(0.0, 1.0);
    int covered = 0;
    for (int k = 0; k < 40; ++k) {
        const Eigen::Quaterniond q = Eigen::Quaterniond(normal(random), normal(random), normal(random), normal(random)).normalized();
        const Eigen::Vector3d t(0.1 * normal(random), 0.1 * normal(random), 1.0 + 0.2 * std::abs(normal(random)));
        std::vector<Eigen::Vector3d> vertices;
        for (const Eigen::Vector3d& p : local) vertices.push_back(q * p + t);
        RasterSettings all, culled;
        all.attributes = culled.attributes = false;
        culled.cull_back_faces = true;
        const Framebuffer a = render::rasterize(vertices, triangles, VertexSpace::camera, camera, all);
        const Framebuffer b = render::rasterize(vertices, triangles, VertexSpace::camera, camera, culled);
        ASSERT_EQ(a.silhouette(), b.silhouette()) << "pose " << k;
        covered += static_cast<int>(a.covered_area_px());
    }
    EXPECT_GT(covered, 40 * 1000);  // the torus fills a good part of each view
}

TEST(Rasterizer, SharedEdgesThroughPixelCentresAreCoveredExactlyOnce) {
    const formats::CameraModel camera = test_camera();
    // A square whose diagonal and sides pass exactly through pixel centres: a
    // 100 x 100 px square at z = 6.4 m has corners at integer pixels.
    const double z = 6.4;
    auto at_pixel = [&](double u, double v) { return Eigen::Vector3d((u - 239.5) * z / 640.0, (v - 179.5) * z / 640.0, z); };
    const std::vector<Eigen::Vector3d> vertices = {at_pixel(100, 50), at_pixel(200, 50), at_pixel(200, 150), at_pixel(100, 150)};
    const std::vector<std::array<int, 3>> first = {{0, 1, 2}}, second = {{0, 2, 3}};
    const Framebuffer a = render::rasterize(vertices, first, VertexSpace::camera, camera);
    const Framebuffer b = render::rasterize(vertices, second, VertexSpace::camera, camera);
    int on_diagonal = 0;
    for (int k = 101; k < 200; ++k) {
        const int x = k, y = k - 50;
        EXPECT_EQ(a.covered(x, y) + b.covered(x, y), 1) << "pixel " << x << "," << y;
        ++on_diagonal;
    }
    EXPECT_EQ(on_diagonal, 99);
    // A finely triangulated version of the same square gives the same silhouette.
    std::vector<Eigen::Vector3d> grid;
    std::vector<std::array<int, 3>> tris;
    const int n = 13;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) grid.push_back(at_pixel(100.0 + 100.0 * i / n, 50.0 + 100.0 * j / n));
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int v = j * (n + 1) + i;
            tris.push_back({v, v + 1, v + n + 2});
            tris.push_back({v, v + n + 2, v + n + 1});
        }
    const std::vector<std::array<int, 3>> both = {{0, 1, 2}, {0, 2, 3}};
    EXPECT_EQ(render::rasterize(grid, tris, VertexSpace::camera, camera).silhouette(),
              render::rasterize(vertices, both, VertexSpace::camera, camera).silhouette());
}

TEST(Rasterizer, ClipsTrianglesCrossingTheNearPlane) {
    const formats::CameraModel camera = test_camera();
    // A floor 1 m below the camera reaching from behind it to 20 m ahead.
    const std::vector<Eigen::Vector3d> floor = {{-5, 1, -2}, {5, 1, -2}, {5, 1, 20}, {-5, 1, 20}};
    const std::vector<std::array<int, 3>> tris = {{0, 1, 2}, {0, 2, 3}};
    const Framebuffer fb = render::rasterize(floor, tris, VertexSpace::camera, camera);
    // Rows below the horizon see the floor where the ray meets it within the
    // quad; rows above do not.
    for (int y : {100, 179, 185, 250, 359})
        for (int x : {0, 120, 239, 400, 479}) {
            const Eigen::Vector3d d = camera.K.inverse() * Eigen::Vector3d(x, y, 1.0);
            bool expected = false;
            double depth = 0.0;
            if (d.y() > 0) {
                const double t = 1.0 / d.y();
                const Eigen::Vector3d p = t * d;
                expected = std::abs(p.x()) < 5 && p.z() < 20;
                depth = p.z();
            }
            EXPECT_EQ(fb.covered(x, y), expected) << x << "," << y;
            if (expected) {
                EXPECT_NEAR(fb.depth_m[fb.index_of(x, y)], depth, 1e-4 * depth);
            }
        }
}

TEST(Rasterizer, DistortedVerticesLandWhereTheCameraProjectsThem) {
    formats::CameraModel camera = test_camera();
    camera.dist = {-0.25, 0.08, 0.001, -0.002, 0.0};
    std::mt19937 random(7);
    std::uniform_real_distribution<double> spread(-0.6, 0.6);
    for (int trial = 0; trial < 20; ++trial) {
        const Eigen::Vector3d centre(spread(random), 0.7 * spread(random), 2.0);
        // A small triangle (about 3 px) around the point.
        const std::vector<Eigen::Vector3d> tri = {centre + Eigen::Vector3d(-0.006, -0.004, 0),
                                                  centre + Eigen::Vector3d(0.006, -0.004, 0),
                                                  centre + Eigen::Vector3d(0, 0.008, 0)};
        const Framebuffer fb = render::rasterize(tri, {{0, 1, 2}}, VertexSpace::camera, camera);
        const Eigen::Vector2d p = camera.project_camera_point(centre);
        EXPECT_TRUE(fb.covered(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y()))))
            << "trial " << trial << " at " << p.transpose();
    }
}

TEST(Rasterizer, RegionsAndRepeatedRendersAreBitIdentical) {
    const formats::CameraModel camera = test_camera();
    const Cube cube = make_cube(0.3, Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, 1, 0.2).normalized()).toRotationMatrix(),
                                Eigen::Vector3d(0.1, 0.05, 2.5));
    RasterSettings settings;
    settings.supersampling = 4;
    const Framebuffer a = render::rasterize(cube.vertices, cube.triangles, VertexSpace::camera, camera, settings);
    const Framebuffer b = render::rasterize(cube.vertices, cube.triangles, VertexSpace::camera, camera, settings);
    EXPECT_EQ(a.coverage, b.coverage);
    EXPECT_EQ(a.triangle, b.triangle);
    settings.region = render::PixelRect{150, 80, 330, 260};
    const Framebuffer part = render::rasterize(cube.vertices, cube.triangles, VertexSpace::camera, camera, settings);
    for (int y = 80; y < 260; ++y)
        for (int x = 150; x < 330; ++x) {
            ASSERT_EQ(part.coverage[part.index_of(x, y)], a.coverage[a.index_of(x, y)]);
            ASSERT_EQ(part.triangle[part.index_of(x, y)], a.triangle[a.index_of(x, y)]);
        }
    EXPECT_FALSE(part.holds(10, 10));
}
