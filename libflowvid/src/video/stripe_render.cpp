#include "flowvid/video/stripe_render.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace flowvid::video {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// sin(2 pi c): reduced to a quarter period and a Taylor polynomial to x^13
// (error < 1e-8 there). Portable, so rendered images are the same on every
// platform's libm, and several times faster than std::sin.
double sin_of_cycles(double cycles) {
    double t = cycles - std::floor(cycles);  // [0, 1)
    if (t >= 0.5) t -= 1.0;                  // [-0.5, 0.5)
    if (t > 0.25)
        t = 0.5 - t;  // sin(pi - x) = sin(x)
    else if (t < -0.25)
        t = -0.5 - t;
    const double x = kTwoPi * t, x2 = x * x;  // |x| <= pi/2
    return x * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880 +
                x2 * (-1.0 / 39916800 + x2 * (1.0 / 6227020800.0)))))));
}

}  // namespace

StripeRenderer::StripeRenderer(formats::CameraModel camera, formats::Projector projector, StripeRenderSettings settings)
    : m_camera(std::move(camera)), m_projector(std::move(projector)), m_settings(settings) {
    if (m_camera.width <= 0 || m_camera.height <= 0)
        throw std::invalid_argument("stripe renderer: the camera has no image size");
    if (!(m_projector.pattern.period_px > 0.0))
        throw std::invalid_argument("stripe renderer: the projector pattern needs a positive period_px");
    if (m_projector.pattern.axis == "rows")
        m_rows = true;
    else if (m_projector.pattern.axis == "columns")
        m_rows = false;
    else
        throw std::invalid_argument("stripe renderer: unknown pattern axis '" + m_projector.pattern.axis +
                                    "' (rows or columns)");
    if (m_settings.supersampling < 1 || m_settings.supersampling > 8)
        throw std::invalid_argument("stripe renderer: supersampling must be 1..8");
}

double StripeRenderer::projector_coordinate(const Eigen::Vector3d& world_m) const {
    const Eigen::Vector3d p = m_projector.camera.to_camera(world_m);
    if (!(p.z() > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    if (m_projector.camera.has_distortion()) {
        const Eigen::Vector2d uv = m_projector.camera.project_camera_point(p);
        return m_rows ? uv.y() : uv.x();
    }
    const Eigen::Matrix3d& K = m_projector.camera.K;
    return m_rows ? K(1, 1) * p.y() / p.z() + K(1, 2) : (K(0, 0) * p.x() + K(0, 1) * p.y()) / p.z() + K(0, 2);
}

double StripeRenderer::stripe_intensity(const Eigen::Vector3d& world_m) const {
    const double v = projector_coordinate(world_m);
    if (!std::isfinite(v)) return 0.0;
    return 0.5 + 0.5 * std::sin(kTwoPi * v / m_projector.pattern.period_px);
}

StripeImage StripeRenderer::render(const std::vector<Eigen::Vector3d>& vertices_m,
                                   const std::vector<std::array<int, 3>>& triangles) {
    StripeImage out;
    render(vertices_m, triangles, out);
    return out;
}

void StripeRenderer::render(const std::vector<Eigen::Vector3d>& vertices_m,
                            const std::vector<std::array<int, 3>>& triangles, StripeImage& out) {
    const int width = m_camera.width, height = m_camera.height;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    // Reused buffers of the same size: only the previous region can differ
    // from the background, so only it is cleared.
    const std::size_t total = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    const bool reuse = out.image.width == width && out.image.height == height && out.image.pixels.size() == total &&
                       out.silhouette.width == width && out.silhouette.height == height &&
                       out.silhouette.pixels.size() == total && out.background_value == m_settings.background &&
                       (!m_settings.projector_coordinates || out.projector_coordinate.pixels.size() == total);
    if (reuse) {
        const render::PixelRect r = out.region.intersected(render::PixelRect::image(width, height));
        for (int y = r.y0; y < r.y1; ++y) {
            const auto begin = static_cast<std::ptrdiff_t>(out.image.index(r.x0, y));
            const auto end = static_cast<std::ptrdiff_t>(out.image.index(r.x1, y));
            std::fill(out.image.pixels.begin() + begin, out.image.pixels.begin() + end, m_settings.background);
            std::fill(out.silhouette.pixels.begin() + begin, out.silhouette.pixels.begin() + end, std::uint8_t{0});
            if (m_settings.projector_coordinates)
                std::fill(out.projector_coordinate.pixels.begin() + begin, out.projector_coordinate.pixels.begin() + end, nan);
        }
    } else {
        out.image.assign(width, height, m_settings.background);
        out.silhouette.width = width;
        out.silhouette.height = height;
        out.silhouette.pixels.assign(total, 0);
        out.background_value = m_settings.background;
        if (m_settings.projector_coordinates) out.projector_coordinate.assign(width, height, nan);
    }
    if (!m_settings.projector_coordinates) out.projector_coordinate = ImageF();
    out.region = {};

    // Rasterize only the mesh's projected bounding box: clearing and scanning
    // the whole frame would cost more than the swatch itself.
    m_pixels.resize(vertices_m.size());
    Eigen::Vector2d lo(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity());
    Eigen::Vector2d hi = -lo;
    bool behind = false;
    for (std::size_t i = 0; i < vertices_m.size(); ++i) {
        m_pixels[i] = m_camera.project(vertices_m[i]);
        if (!m_pixels[i].allFinite()) {
            behind = true;
            continue;
        }
        lo = lo.cwiseMin(m_pixels[i]);
        hi = hi.cwiseMax(m_pixels[i]);
    }
    render::PixelRect region = behind ? render::PixelRect::image(width, height)
                                      : render::PixelRect::around(lo, hi).expanded(2);
    region = region.intersected(render::PixelRect::image(width, height));
    out.region = region;
    if (region.empty() || triangles.empty()) return;

    render::RasterSettings raster;
    raster.supersampling = m_settings.supersampling;
    raster.region = region;
    raster.attributes = true;
    render::rasterize(render::MeshView{&vertices_m, &triangles}, render::VertexSpace::world, m_camera, raster,
                      m_framebuffer);

    const bool shade = m_settings.shading == StripeShading::lambertian;
    if (shade) {
        m_normals.assign(vertices_m.size(), Eigen::Vector3d::Zero());
        for (const auto& t : triangles) {
            // Area-weighted: the cross product's length is twice the area.
            const Eigen::Vector3d n = (vertices_m[static_cast<std::size_t>(t[1])] - vertices_m[static_cast<std::size_t>(t[0])])
                                          .cross(vertices_m[static_cast<std::size_t>(t[2])] -
                                                 vertices_m[static_cast<std::size_t>(t[0])]);
            for (int k = 0; k < 3; ++k) m_normals[static_cast<std::size_t>(t[k])] += n;
        }
        for (Eigen::Vector3d& n : m_normals) {
            const double length = n.norm();
            if (length > 0.0) n /= length;
        }
    }
    const Eigen::Vector3d projector_centre = m_projector.camera.centre_world();
    // Without distortion v_p = N(p) / D(p) with N, D affine in the world
    // point: N = (K P)_row . [p 1], D = (P)_z . [p 1]. The pixel's point is
    // an affine (barycentric) blend of the triangle's vertices, so N and D
    // are the same blends of their per-vertex values: exact, and 6 products
    // per pixel instead of a projection.
    const bool fast = !m_projector.camera.has_distortion();
    if (fast) {
        const Eigen::Matrix<double, 3, 4> KP = m_projector.camera.K * m_projector.camera.camera_from_world.topRows<3>();
        const Eigen::Vector4d numerator_row = KP.row(m_rows ? 1 : 0).transpose();
        const Eigen::Vector4d depth_row = KP.row(2).transpose();
        m_numerator.resize(vertices_m.size());
        m_denominator.resize(vertices_m.size());
        for (std::size_t i = 0; i < vertices_m.size(); ++i) {
            m_numerator[i] = numerator_row.head<3>().dot(vertices_m[i]) + numerator_row(3);
            m_denominator[i] = depth_row.head<3>().dot(vertices_m[i]) + depth_row(3);
        }
    }
    const double inverse_period = 1.0 / m_projector.pattern.period_px;
    const double ambient = std::clamp(m_settings.ambient, 0.0, 1.0);
    const double nan_d = std::numeric_limits<double>::quiet_NaN();

    for (int y = region.y0; y < region.y1; ++y) {
        for (int x = region.x0; x < region.x1; ++x) {
            const std::size_t fi = m_framebuffer.index_of(x, y);
            const std::size_t oi = out.image.index(x, y);
            if (m_framebuffer.coverage[fi] >= 0.5f) out.silhouette.pixels[oi] = 1;
            const std::int32_t t = m_framebuffer.triangle[fi];
            if (t < 0) continue;
            const std::array<int, 3>& tri = triangles[static_cast<std::size_t>(t)];
            const std::array<float, 3>& b = m_framebuffer.barycentric[fi];
            const auto i0 = static_cast<std::size_t>(tri[0]), i1 = static_cast<std::size_t>(tri[1]),
                       i2 = static_cast<std::size_t>(tri[2]);
            const double b0 = b[0], b1 = b[1], b2 = b[2];
            double v;
            if (fast) {
                const double depth = b0 * m_denominator[i0] + b1 * m_denominator[i1] + b2 * m_denominator[i2];
                v = depth > 0.0 ? (b0 * m_numerator[i0] + b1 * m_numerator[i1] + b2 * m_numerator[i2]) / depth : nan_d;
            } else {
                v = projector_coordinate(vertices_m[i0] * b0 + vertices_m[i1] * b1 + vertices_m[i2] * b2);
            }
            if (!std::isfinite(v)) continue;
            double intensity = 0.5 + 0.5 * sin_of_cycles(v * inverse_period);
            if (shade) {
                const Eigen::Vector3d world = vertices_m[i0] * b0 + vertices_m[i1] * b1 + vertices_m[i2] * b2;
                const Eigen::Vector3d n = m_normals[i0] * b0 + m_normals[i1] * b1 + m_normals[i2] * b2;
                const double length = n.norm();
                const Eigen::Vector3d l = (projector_centre - world).normalized();
                const double cosine = length > 0.0 ? std::abs(n.dot(l)) / length : 1.0;
                intensity *= ambient + (1.0 - ambient) * cosine;
            }
            out.image.pixels[oi] = static_cast<float>(intensity);
            if (m_settings.projector_coordinates) out.projector_coordinate.pixels[oi] = static_cast<float>(v);
        }
    }
}

std::vector<std::array<int, 3>> grid_triangles(int rows, int cols) {
    std::vector<std::array<int, 3>> triangles;
    if (rows < 2 || cols < 2) return triangles;
    triangles.reserve(static_cast<std::size_t>(2 * (rows - 1) * (cols - 1)));
    for (int r = 0; r + 1 < rows; ++r)
        for (int c = 0; c + 1 < cols; ++c) {
            const int a = r * cols + c, b = a + 1, d = a + cols, e = d + 1;
            // (b - a) along u, (e - a) along u + v: u x v is the front.
            triangles.push_back({a, b, e});
            triangles.push_back({a, e, d});
        }
    return triangles;
}

std::vector<Eigen::Vector3d> vertices_of_frame(const formats::VertexAnimation& animation, int frame) {
    if (frame < 0 || frame >= animation.frame_count)
        throw std::out_of_range("vertices_of_frame: frame " + std::to_string(frame) + " of " +
                                std::to_string(animation.frame_count));
    std::vector<Eigen::Vector3d> vertices(static_cast<std::size_t>(animation.vertex_count));
    for (int v = 0; v < animation.vertex_count; ++v)
        vertices[static_cast<std::size_t>(v)] = animation.position(frame, v).cast<double>();
    return vertices;
}

std::vector<Eigen::Vector3d> vertices_from_vector(const Eigen::VectorXd& positions_m) {
    std::vector<Eigen::Vector3d> vertices(static_cast<std::size_t>(positions_m.size() / 3));
    for (std::size_t i = 0; i < vertices.size(); ++i)
        vertices[i] = positions_m.segment<3>(static_cast<Eigen::Index>(3 * i));
    return vertices;
}

}  // namespace flowvid::video
