#include "flowvid/render/rasterizer.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace flowvid::render {

PixelRect PixelRect::intersected(const PixelRect& other) const {
    PixelRect r{std::max(x0, other.x0), std::max(y0, other.y0), std::min(x1, other.x1), std::min(y1, other.y1)};
    if (r.x1 < r.x0) r.x1 = r.x0;
    if (r.y1 < r.y0) r.y1 = r.y0;
    return r;
}

PixelRect PixelRect::united(const PixelRect& other) const {
    if (empty()) return other;
    if (other.empty()) return *this;
    return {std::min(x0, other.x0), std::min(y0, other.y0), std::max(x1, other.x1), std::max(y1, other.y1)};
}

PixelRect PixelRect::expanded(int margin_px) const {
    if (empty()) return *this;
    return {x0 - margin_px, y0 - margin_px, x1 + margin_px, y1 + margin_px};
}

PixelRect PixelRect::around(const Eigen::Vector2d& min, const Eigen::Vector2d& max) {
    if (!(min.allFinite() && max.allFinite()) || min.x() > max.x() || min.y() > max.y()) return {};
    // Clamp before converting so that far-away points cannot overflow int.
    auto to_int = [](double v) { return static_cast<int>(std::clamp(v, -1e8, 1e8)); };
    return {to_int(std::ceil(min.x())), to_int(std::ceil(min.y())), to_int(std::floor(max.x())) + 1,
            to_int(std::floor(max.y())) + 1};
}

double Framebuffer::covered_area_px() const {
    double sum = 0.0;
    for (float c : coverage) sum += c;
    return sum;
}

std::vector<std::uint8_t> Framebuffer::silhouette(float threshold) const {
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(image_width) * static_cast<std::size_t>(image_height), 0);
    for (int y = region.y0; y < region.y1; ++y)
        for (int x = region.x0; x < region.x1; ++x)
            if (coverage[index_of(x, y)] >= threshold)
                mask[static_cast<std::size_t>(y) * static_cast<std::size_t>(image_width) + static_cast<std::size_t>(x)] = 1;
    return mask;
}

void project_camera_points(const formats::CameraModel& camera, const std::vector<Eigen::Vector3d>& points,
                           std::vector<Eigen::Vector2d>& pixels) {
    pixels.resize(points.size());
    if (camera.has_distortion()) {
        for (std::size_t i = 0; i < points.size(); ++i) pixels[i] = camera.project_camera_point(points[i]);
        return;
    }
    const double fx = camera.K(0, 0), s = camera.K(0, 1), cx = camera.K(0, 2), fy = camera.K(1, 1), cy = camera.K(1, 2);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d& p = points[i];
        if (!(p.z() > 0.0)) {
            pixels[i] = {nan, nan};
            continue;
        }
        const double x = p.x() / p.z(), y = p.y() / p.z();
        pixels[i] = {fx * x + s * y + cx, fy * y + cy};
    }
}

namespace {

struct ClipVertex {
    Eigen::Vector3d camera;  // camera-space position
    Eigen::Vector3d bary;    // weights of the original triangle's vertices
};

// An edge function evaluated the same way, bit for bit, by both triangles that
// share the edge: the end points are put in a canonical order and the sign is
// applied afterwards, so the two values are exact negatives (watertightness).
struct Edge {
    double px, py, dx, dy, sign;
    bool owns_ties;  // the top-left rule: which of the two triangles takes samples exactly on the edge

    Edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        const bool swap = b.x() < a.x() || (b.x() == a.x() && b.y() < a.y());
        const Eigen::Vector2d& p = swap ? b : a;
        const Eigen::Vector2d& q = swap ? a : b;
        px = p.x();
        py = p.y();
        dx = q.x() - p.x();
        dy = q.y() - p.y();
        sign = swap ? -1.0 : 1.0;
        // Direction a -> b as the positively oriented triangle walks it; the
        // rule depends only on this direction and is antisymmetric in it.
        const double ux = b.x() - a.x(), uy = b.y() - a.y();
        owns_ties = uy > 0.0 || (uy == 0.0 && ux < 0.0);
    }
    double operator()(double sx, double sy) const { return sign * (dx * (sy - py) - dy * (sx - px)); }
    bool inside(double e) const { return e > 0.0 || (e == 0.0 && owns_ties); }
};

struct Rasterizer {
    const RasterSettings& settings;
    Framebuffer& fb;
    std::vector<std::uint64_t>& sample_bits;  // per pixel, s > 1 only

    void triangle(const Eigen::Vector2d* p, const double* z, const Eigen::Vector3d* bary, std::int32_t id) {
        int ia = 0, ib = 1, ic = 2;
        double area2 = (p[1].x() - p[0].x()) * (p[2].y() - p[0].y()) - (p[1].y() - p[0].y()) * (p[2].x() - p[0].x());
        if (!std::isfinite(area2) || area2 == 0.0) return;
        if (area2 < 0.0) {
            std::swap(ib, ic);
            area2 = -area2;
        }
        const Eigen::Vector2d &a = p[ia], &b = p[ib], &c = p[ic];
        const Edge e_a(b, c), e_b(c, a), e_c(a, b);  // e_a is zero on edge bc: the weight of vertex a

        const int s = settings.supersampling;
        const double min_x = std::min({a.x(), b.x(), c.x()}), max_x = std::max({a.x(), b.x(), c.x()});
        const double min_y = std::min({a.y(), b.y(), c.y()}), max_y = std::max({a.y(), b.y(), c.y()});
        const PixelRect box = PixelRect::around({min_x - 0.5, min_y - 0.5}, {max_x + 0.5, max_y + 0.5})
                                  .intersected(fb.region);
        if (box.empty()) return;

        const double inv_z[3] = {1.0 / z[ia], 1.0 / z[ib], 1.0 / z[ic]};
        const Eigen::Vector3d* bv[3] = {&bary[ia], &bary[ib], &bary[ic]};
        const double step = 1.0 / s;
        const double start = -0.5 + 0.5 * step;

        for (int y = box.y0; y < box.y1; ++y) {
            for (int x = box.x0; x < box.x1; ++x) {
                const std::size_t i = fb.index_of(x, y);
                const double ea = e_a(x, y), eb = e_b(x, y), ec = e_c(x, y);
                const bool centre_in = e_a.inside(ea) && e_b.inside(eb) && e_c.inside(ec);
                if (centre_in) {
                    if (s == 1) fb.coverage[i] = 1.0f;
                    if (settings.attributes) {
                        // Perspective-correct weights: screen weights divided by depth.
                        const double w0 = ea / area2 * inv_z[0], w1 = eb / area2 * inv_z[1], w2 = ec / area2 * inv_z[2];
                        const double sum = w0 + w1 + w2;
                        const double depth = 1.0 / sum;
                        if (depth < static_cast<double>(fb.depth_m[i])) {
                            fb.depth_m[i] = static_cast<float>(depth);
                            fb.triangle[i] = id;
                            const Eigen::Vector3d w = (w0 * *bv[0] + w1 * *bv[1] + w2 * *bv[2]) / sum;
                            fb.barycentric[i] = {static_cast<float>(w[0]), static_cast<float>(w[1]),
                                                 static_cast<float>(w[2])};
                        }
                    }
                }
                if (s > 1) {
                    std::uint64_t bits = 0;
                    int bit = 0;
                    for (int sy = 0; sy < s; ++sy) {
                        const double yy = y + start + sy * step;
                        for (int sx = 0; sx < s; ++sx, ++bit) {
                            const double xx = x + start + sx * step;
                            if (e_a.inside(e_a(xx, yy)) && e_b.inside(e_b(xx, yy)) && e_c.inside(e_c(xx, yy)))
                                bits |= std::uint64_t{1} << bit;
                        }
                    }
                    sample_bits[i] |= bits;
                }
            }
        }
    }
};

}  // namespace

void rasterize(const MeshView& mesh, VertexSpace space, const formats::CameraModel& camera,
               const RasterSettings& settings, Framebuffer& out) {
    if (camera.width <= 0 || camera.height <= 0) throw std::invalid_argument("rasterize: the camera has no image size");
    if (settings.supersampling < 1 || settings.supersampling > 8)
        throw std::invalid_argument("rasterize: supersampling must be 1..8");
    if (!mesh.vertices_m || !mesh.triangles) throw std::invalid_argument("rasterize: the mesh view is empty");
    const std::vector<Eigen::Vector3d>& vertices = *mesh.vertices_m;
    const std::vector<std::array<int, 3>>& triangles = *mesh.triangles;
    const int vertex_count = static_cast<int>(vertices.size());
    for (const std::array<int, 3>& t : triangles)
        for (int v : t)
            if (v < 0 || v >= vertex_count) throw std::invalid_argument("rasterize: a triangle index is out of range");

    out.image_width = camera.width;
    out.image_height = camera.height;
    const PixelRect image = PixelRect::image(camera.width, camera.height);
    out.region = settings.region ? settings.region->intersected(image) : image;
    const std::size_t n = static_cast<std::size_t>(out.region.width()) * static_cast<std::size_t>(out.region.height());
    out.coverage.assign(n, 0.0f);
    if (settings.attributes) {
        out.depth_m.assign(n, std::numeric_limits<float>::infinity());
        out.triangle.assign(n, -1);
        out.barycentric.assign(n, {0.0f, 0.0f, 0.0f});
    } else {
        out.depth_m.clear();
        out.triangle.clear();
        out.barycentric.clear();
    }
    if (n == 0) return;

    thread_local std::vector<Eigen::Vector3d> cam;
    thread_local std::vector<Eigen::Vector2d> pix;
    thread_local std::vector<std::uint64_t> sample_bits;
    cam.resize(vertices.size());
    if (space == VertexSpace::world) {
        const Eigen::Matrix3d R = camera.camera_from_world.topLeftCorner<3, 3>();
        const Eigen::Vector3d t = camera.camera_from_world.topRightCorner<3, 1>();
        for (std::size_t i = 0; i < vertices.size(); ++i) cam[i] = R * vertices[i] + t;
    } else {
        for (std::size_t i = 0; i < vertices.size(); ++i) cam[i] = vertices[i];
    }
    project_camera_points(camera, cam, pix);
    if (settings.supersampling > 1) sample_bits.assign(n, 0);

    Rasterizer raster{settings, out, sample_bits};
    const double near = settings.near_m;
    const Eigen::Vector3d unit[3] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};

    for (std::size_t t = 0; t < triangles.size(); ++t) {
        const std::array<int, 3>& tri = triangles[t];
        const Eigen::Vector3d& P0 = cam[static_cast<std::size_t>(tri[0])];
        const Eigen::Vector3d& P1 = cam[static_cast<std::size_t>(tri[1])];
        const Eigen::Vector3d& P2 = cam[static_cast<std::size_t>(tri[2])];
        if (settings.cull_back_faces && (P1 - P0).cross(P2 - P0).dot(P0) >= 0.0) continue;
        const bool in0 = P0.z() >= near, in1 = P1.z() >= near, in2 = P2.z() >= near;
        const auto id = static_cast<std::int32_t>(t);
        if (in0 && in1 && in2) {
            const Eigen::Vector2d p[3] = {pix[static_cast<std::size_t>(tri[0])], pix[static_cast<std::size_t>(tri[1])],
                                          pix[static_cast<std::size_t>(tri[2])]};
            if (!(p[0].allFinite() && p[1].allFinite() && p[2].allFinite())) continue;
            const double z[3] = {P0.z(), P1.z(), P2.z()};
            raster.triangle(p, z, unit, id);
            continue;
        }
        if (!in0 && !in1 && !in2) continue;
        // Clip against z = near (one plane of Sutherland-Hodgman), then fan.
        const ClipVertex input[3] = {{P0, unit[0]}, {P1, unit[1]}, {P2, unit[2]}};
        ClipVertex poly[4];
        int count = 0;
        for (int k = 0; k < 3; ++k) {
            const ClipVertex& a = input[k];
            const ClipVertex& b = input[(k + 1) % 3];
            const bool a_in = a.camera.z() >= near, b_in = b.camera.z() >= near;
            if (a_in) poly[count++] = a;
            if (a_in != b_in) {
                const double s = (near - a.camera.z()) / (b.camera.z() - a.camera.z());
                poly[count++] = {a.camera + s * (b.camera - a.camera), a.bary + s * (b.bary - a.bary)};
            }
        }
        Eigen::Vector2d p[4];
        double z[4];
        Eigen::Vector3d bary[4];
        bool finite = true;
        for (int k = 0; k < count; ++k) {
            p[k] = camera.project_camera_point(poly[k].camera);
            z[k] = poly[k].camera.z();
            bary[k] = poly[k].bary;
            finite = finite && p[k].allFinite();
        }
        if (!finite) continue;
        for (int k = 1; k + 1 < count; ++k) {
            const Eigen::Vector2d pp[3] = {p[0], p[k], p[k + 1]};
            const double zz[3] = {z[0], z[k], z[k + 1]};
            const Eigen::Vector3d bb[3] = {bary[0], bary[k], bary[k + 1]};
            raster.triangle(pp, zz, bb, id);
        }
    }

    if (settings.supersampling > 1) {
        const float scale = 1.0f / static_cast<float>(settings.supersampling * settings.supersampling);
        for (std::size_t i = 0; i < n; ++i)
            out.coverage[i] = static_cast<float>(std::popcount(sample_bits[i])) * scale;
    }
}

Framebuffer rasterize(const std::vector<Eigen::Vector3d>& vertices_m, const std::vector<std::array<int, 3>>& triangles,
                      VertexSpace space, const formats::CameraModel& camera, const RasterSettings& settings) {
    Framebuffer out;
    rasterize(MeshView{&vertices_m, &triangles}, space, camera, settings, out);
    return out;
}

}  // namespace flowvid::render
