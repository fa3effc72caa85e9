#include "flowvid/rigid/silhouette_residuals.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace flowvid::rigid {

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
}

// Distance used for observed outline points when the model shows no outline.
constexpr double kMissingDistancePx = 100.0;
constexpr double kNearM = 1e-3;

}  // namespace

Pose Pose::perturbed(const Eigen::Matrix<double, 6, 1>& d) const {
    Pose p = *this;
    p.com_m += d.head<3>();
    const Eigen::Vector3d w = d.tail<3>();
    const double angle = w.norm();
    if (angle > 0.0) p.rotation = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * rotation;
    return p;
}

FrameObservation make_frame_observation(metrics::Silhouette mask, int frame, double time_s) {
    FrameObservation o;
    o.frame = frame;
    o.time_s = time_s;
    o.mask = std::move(mask);
    const metrics::Silhouette& m = o.mask;
    double sx = 0.0, sy = 0.0;
    long long n = 0;
    int x0 = m.width, y0 = m.height, x1 = -1, y1 = -1;
    for (int y = 0; y < m.height; ++y)
        for (int x = 0; x < m.width; ++x) {
            if (!m.at(x, y)) continue;
            sx += x;
            sy += y;
            ++n;
            x0 = std::min(x0, x);
            y0 = std::min(y0, y);
            x1 = std::max(x1, x);
            y1 = std::max(y1, y);
            // Outline points half-way to each background 4-neighbour inside the image.
            const int nx[4] = {x - 1, x + 1, x, x};
            const int ny[4] = {y, y, y - 1, y + 1};
            for (int k = 0; k < 4; ++k)
                if (nx[k] >= 0 && ny[k] >= 0 && nx[k] < m.width && ny[k] < m.height && !m.at(nx[k], ny[k]))
                    o.edge_points_px.emplace_back(0.5 * (x + nx[k]), 0.5 * (y + ny[k]));
        }
    o.area_px = static_cast<double>(n);
    if (n > 0) {
        o.centroid_px = {sx / n, sy / n};
        o.bounds = {x0, y0, x1 + 1, y1 + 1};
    }
    o.signed_distance = metrics::signed_distance_field(o.mask);
    return o;
}

SilhouetteModel::SilhouetteModel(const RigidBody& body, const formats::CameraModel& camera)
    : m_body(body), m_camera(camera), m_distorted(camera.has_distortion()) {
    // Weld coincident vertices so that the edge topology is found even when a
    // file splits vertices per face (flat shading).
    std::map<std::array<double, 3>, int> index_of;
    std::vector<int> remap(body.mesh.vertices_m.size());
    for (std::size_t i = 0; i < body.mesh.vertices_m.size(); ++i) {
        const Eigen::Vector3d& v = body.mesh.vertices_m[i];
        const std::array<double, 3> key{v.x(), v.y(), v.z()};
        auto [it, inserted] = index_of.emplace(key, static_cast<int>(m_vertices.size()));
        if (inserted) m_vertices.push_back(v - body.center_of_mass_m);
        remap[i] = it->second;
    }
    std::map<std::pair<int, int>, std::size_t> edge_of;
    for (const std::array<int, 3>& t : body.mesh.triangles) {
        const std::array<int, 3> w{remap[static_cast<std::size_t>(t[0])], remap[static_cast<std::size_t>(t[1])],
                                   remap[static_cast<std::size_t>(t[2])]};
        if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;
        const int face = static_cast<int>(m_triangles.size());
        m_triangles.push_back(w);
        for (int k = 0; k < 3; ++k) {
            const int a = w[static_cast<std::size_t>(k)], b = w[static_cast<std::size_t>((k + 1) % 3)];
            const int c = w[static_cast<std::size_t>((k + 2) % 3)];
            const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
            auto [it, inserted] = edge_of.emplace(key, m_edges.size());
            if (inserted) {
                MeshEdge e;
                e.a = key.first;
                e.b = key.second;
                m_edges.push_back(e);
            }
            m_edges[it->second].faces.push_back(face);
            m_edges[it->second].opposite.push_back(c);
        }
    }
    m_closed = !m_edges.empty() && std::all_of(m_edges.begin(), m_edges.end(), [](const MeshEdge& e) { return e.faces.size() == 2; });
}

Eigen::Vector2d SilhouetteModel::project(const Eigen::Vector3d& p) const {
    if (!(p.z() > 0.0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
    if (m_distorted) return m_camera.project_camera_point(p);
    const Eigen::Matrix3d& K = m_camera.K;
    const double x = p.x() / p.z(), y = p.y() / p.z();
    return {K(0, 0) * x + K(0, 1) * y + K(0, 2), K(1, 1) * y + K(1, 2)};
}

Eigen::Matrix<double, 2, 3> SilhouetteModel::projection_jacobian(const Eigen::Vector3d& p) const {
    Eigen::Matrix<double, 2, 3> J;
    if (!m_distorted) {
        const Eigen::Matrix3d& K = m_camera.K;
        const double iz = 1.0 / p.z();
        const double x = p.x() * iz, y = p.y() * iz;
        J << K(0, 0) * iz, K(0, 1) * iz, -(K(0, 0) * x + K(0, 1) * y) * iz, 0.0, K(1, 1) * iz, -K(1, 1) * y * iz;
        return J;
    }
    const double h = 1e-6 * std::max(std::abs(p.z()), 1e-3);
    for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d a = p, b = p;
        a[k] += h;
        b[k] -= h;
        J.col(k) = (m_camera.project_camera_point(a) - m_camera.project_camera_point(b)) / (2.0 * h);
    }
    return J;
}

void SilhouetteModel::transform(const Pose& pose, Scratch& s) const {
    s.camera_points.resize(m_vertices.size());
    for (std::size_t i = 0; i < m_vertices.size(); ++i) s.camera_points[i] = pose.rotation * m_vertices[i] + pose.com_m;
    s.pixels.resize(m_vertices.size());
    for (std::size_t i = 0; i < m_vertices.size(); ++i) s.pixels[i] = project(s.camera_points[i]);
}

render::PixelRect SilhouetteModel::projected_bounds(const Pose& pose, Scratch& s) const {
    transform(pose, s);
    const render::PixelRect image = render::PixelRect::image(m_camera.width, m_camera.height);
    if (s.pixels.empty()) return {};
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d hi = -lo;
    for (std::size_t i = 0; i < s.pixels.size(); ++i) {
        if (!(s.camera_points[i].z() > kNearM) || !s.pixels[i].allFinite()) return image;
        lo = lo.cwiseMin(s.pixels[i]);
        hi = hi.cwiseMax(s.pixels[i]);
    }
    return render::PixelRect::around(lo, hi).expanded(2).intersected(image);
}

void SilhouetteModel::rasterize_region(const render::PixelRect& region, Scratch& s) const {
    render::RasterSettings settings;
    settings.region = region;
    settings.attributes = false;
    // Every line of sight through a closed surface crosses a face turned
    // towards the camera: those alone give the same coverage, at half the cost.
    settings.cull_back_faces = m_closed;
    settings.near_m = kNearM;
    render::rasterize(render::MeshView{&s.camera_points, &m_triangles}, render::VertexSpace::camera, m_camera, settings,
                      s.framebuffer);
}

void SilhouetteModel::contour(const Pose& pose, Scratch& s, double piece_length_px) const {
    s.pieces.clear();
    const render::PixelRect region = projected_bounds(pose, s);  // also transforms
    if (region.empty()) return;
    rasterize_region(region, s);

    s.facing.resize(m_triangles.size());
    for (std::size_t f = 0; f < m_triangles.size(); ++f) {
        const Eigen::Vector3d& P0 = s.camera_points[static_cast<std::size_t>(m_triangles[f][0])];
        const Eigen::Vector3d& P1 = s.camera_points[static_cast<std::size_t>(m_triangles[f][1])];
        const Eigen::Vector3d& P2 = s.camera_points[static_cast<std::size_t>(m_triangles[f][2])];
        s.facing[f] = (P1 - P0).cross(P2 - P0).dot(P0) < 0.0 ? 1 : -1;
    }
    const double width = m_camera.width, height = m_camera.height;
    for (const MeshEdge& e : m_edges) {
        int front = -1;
        bool has_back = false;
        for (std::size_t k = 0; k < e.faces.size(); ++k) {
            if (s.facing[static_cast<std::size_t>(e.faces[k])] > 0) {
                if (front < 0) front = static_cast<int>(k);
            } else {
                has_back = true;
            }
        }
        // A contour edge: front on one side, back on the other; a border edge of an open mesh always.
        const bool border = e.faces.size() == 1;
        if (!border && (front < 0 || !has_back)) continue;
        const int inner = front >= 0 ? front : 0;
        const Eigen::Vector3d& Pa = s.camera_points[static_cast<std::size_t>(e.a)];
        const Eigen::Vector3d& Pb = s.camera_points[static_cast<std::size_t>(e.b)];
        if (!(Pa.z() > kNearM && Pb.z() > kNearM)) continue;
        const Eigen::Vector2d ua = s.pixels[static_cast<std::size_t>(e.a)], ub = s.pixels[static_cast<std::size_t>(e.b)];
        const double length = (ub - ua).norm();
        if (!(length > 1e-9)) continue;
        const Eigen::Vector2d direction = (ub - ua) / length;
        Eigen::Vector2d outward(-direction.y(), direction.x());
        const Eigen::Vector2d uo = s.pixels[static_cast<std::size_t>(e.opposite[static_cast<std::size_t>(inner)])];
        if (outward.dot(uo - ua) > 0.0) outward = -outward;

        const int count = std::max(1, static_cast<int>(std::ceil(length / piece_length_px)));
        const Eigen::Vector3d& Va = m_vertices[static_cast<std::size_t>(e.a)];
        const Eigen::Vector3d& Vb = m_vertices[static_cast<std::size_t>(e.b)];
        Eigen::Vector2d previous = ua;
        for (int k = 0; k < count; ++k) {
            const double s_b = static_cast<double>(k + 1) / count, s_m = (k + 0.5) / count;
            const Eigen::Vector2d next = k + 1 == count ? ub : project(Pa + s_b * (Pb - Pa));
            const Eigen::Vector2d mid = project(Pa + s_m * (Pb - Pa));
            const Eigen::Vector2d piece_a = previous;
            previous = next;
            if (!(mid.x() >= -0.5 && mid.y() >= -0.5 && mid.x() <= width - 0.5 && mid.y() <= height - 0.5)) continue;
            // Hidden when the body itself covers the outer side.
            const Eigen::Vector2d probe = mid + 0.8 * outward;
            const int px = static_cast<int>(std::lround(probe.x())), py = static_cast<int>(std::lround(probe.y()));
            if (s.framebuffer.covered(px, py)) continue;
            ContourPiece piece;
            const double s_a = static_cast<double>(k) / count;
            piece.body_a = Va + s_a * (Vb - Va);
            piece.body_b = Va + s_b * (Vb - Va);
            piece.pixel_a = piece_a;
            piece.pixel_b = next;
            piece.mid_pixel = mid;
            piece.outward = outward;
            piece.length_px = (next - piece_a).norm();
            piece.corner_distance_px = std::min(s_m, 1.0 - s_m) * length;
            piece.edge_s_a = s_a;
            piece.edge_s_b = s_b;
            piece.edge_length_px = length;
            s.pieces.push_back(piece);
        }
    }
}

FrameCost SilhouetteModel::edge_cost(const Pose& pose, const FrameObservation& observed, Scratch& s,
                                     PoseNormalEquations* normal) const {
    FrameCost cost;
    contour(pose, s);
    cost.contour_pieces = static_cast<int>(s.pieces.size());
    cost.visible = !s.pieces.empty();
    if (normal) *normal = PoseNormalEquations{};

    auto pose_rows = [&](const Eigen::Vector3d& body_point, Eigen::Matrix<double, 2, 6>& J) {
        const Eigen::Vector3d rotated = pose.rotation * body_point;
        const Eigen::Vector3d P = rotated + pose.com_m;
        const Eigen::Matrix<double, 2, 3> Jp = projection_jacobian(P);
        J.leftCols<3>() = Jp;
        J.rightCols<3>() = -Jp * skew(rotated);
    };
    auto accumulate = [&](const Eigen::Matrix<double, 1, 6>& row, double residual) {
        normal->JtJ.noalias() += row.transpose() * row;
        normal->Jtr.noalias() += row.transpose() * residual;
    };

    auto corner_weight = [&](double distance_px) {
        if (m_corner_radius_px <= 0.0 || distance_px >= m_corner_radius_px) return 1.0;
        const double u = distance_px / m_corner_radius_px;
        return u * u;
    };
    // Model -> data.
    double total_length = 0.0;
    for (const ContourPiece& p : s.pieces) total_length += p.length_px * corner_weight(p.corner_distance_px);
    if (total_length > 0.0) {
        double sum = 0.0;
        for (const ContourPiece& p : s.pieces) {
            Eigen::Vector2d gradient;
            const double phi = observed.signed_distance.sample(p.mid_pixel, &gradient);
            const double weight = p.length_px * corner_weight(p.corner_distance_px) / total_length;
            sum += weight * phi * phi;
            if (normal && weight > 0.0) {
                const double a = std::sqrt(0.5 * weight);
                Eigen::Matrix<double, 2, 6> J;
                pose_rows(0.5 * (p.body_a + p.body_b), J);
                accumulate(a * gradient.transpose() * J, a * phi);
            }
        }
        cost.model_to_data_px2 = sum;
    }

    // Data -> model.
    const std::size_t n = observed.edge_points_px.size();
    if (n > 0 && s.pieces.empty()) {
        cost.data_to_model_px2 = kMissingDistancePx * kMissingDistancePx;
    } else if (n > 0) {
        struct Nearest {
            std::size_t piece = 0;
            double t = 0.0;
            double d2 = 0.0;
            double weight = 1.0;
        };
        thread_local std::vector<Nearest> nearest;
        nearest.assign(n, Nearest{});
        double total_weight = 0.0;
        s.segments.resize(s.pieces.size());
        for (std::size_t i = 0; i < s.pieces.size(); ++i) s.segments[i] = {s.pieces[i].pixel_a, s.pieces[i].pixel_b};
        s.piece_grid.build(s.segments);
        for (std::size_t k = 0; k < n; ++k) {
            Nearest& best = nearest[k];
            const NearestSegment hit = s.piece_grid.nearest(observed.edge_points_px[k]);
            best = {hit.index, hit.t, hit.distance2_px2, 1.0};
            const ContourPiece& p = s.pieces[best.piece];
            const double along = p.edge_s_a + best.t * (p.edge_s_b - p.edge_s_a);
            best.weight = corner_weight(std::min(along, 1.0 - along) * p.edge_length_px);
            total_weight += best.weight;
        }
        if (!(total_weight > 0.0)) {
            for (Nearest& k : nearest) k.weight = 1.0;
            total_weight = static_cast<double>(n);
        }
        double sum = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            const Nearest& best = nearest[k];
            sum += best.weight * best.d2;
            if (normal && best.weight > 0.0) {
                const Eigen::Vector2d& o = observed.edge_points_px[k];
                const ContourPiece& p = s.pieces[best.piece];
                const Eigen::Vector2d c = p.pixel_a + best.t * (p.pixel_b - p.pixel_a);
                const double d = std::sqrt(best.d2);
                const double a = std::sqrt(0.5 * best.weight / total_weight);
                const Eigen::Vector2d direction = d > 1e-9 ? Eigen::Vector2d((o - c) / d) : Eigen::Vector2d(-p.outward);
                Eigen::Matrix<double, 2, 6> J;
                pose_rows(p.body_a + best.t * (p.body_b - p.body_a), J);
                accumulate(-a * direction.transpose() * J, a * d);
            }
        }
        cost.data_to_model_px2 = sum / total_weight;
    }
    cost.cost_px2 = 0.5 * (cost.model_to_data_px2 + cost.data_to_model_px2);
    return cost;
}

SilhouetteOverlap SilhouetteModel::overlap(const Pose& pose, const FrameObservation& observed, Scratch& s) const {
    const render::PixelRect image = render::PixelRect::image(m_camera.width, m_camera.height);
    const render::PixelRect region = projected_bounds(pose, s).united(observed.bounds).intersected(image);
    SilhouetteOverlap result;
    if (region.empty()) return result;
    rasterize_region(region, s);
    for (int y = region.y0; y < region.y1; ++y)
        for (int x = region.x0; x < region.x1; ++x) {
            const bool model = s.framebuffer.coverage[s.framebuffer.index_of(x, y)] >= 0.5f;
            const bool data = observed.mask.at(x, y);
            result.xor_px += model != data;
            result.intersection_px += model && data;
            result.union_px += model || data;
        }
    return result;
}

SilhouetteModel::Moments SilhouetteModel::moments(const Pose& pose, Scratch& s) const {
    Moments m;
    const render::PixelRect region = projected_bounds(pose, s);
    if (region.empty()) return m;
    rasterize_region(region, s);
    double sx = 0.0, sy = 0.0;
    for (int y = region.y0; y < region.y1; ++y)
        for (int x = region.x0; x < region.x1; ++x)
            if (s.framebuffer.coverage[s.framebuffer.index_of(x, y)] >= 0.5f) {
                m.area_px += 1.0;
                sx += x;
                sy += y;
            }
    if (m.area_px > 0.0) m.centroid_px = {sx / m.area_px, sy / m.area_px};
    return m;
}

metrics::Silhouette SilhouetteModel::render(const Pose& pose, Scratch& s) const {
    const render::PixelRect region = projected_bounds(pose, s);
    metrics::Silhouette out(m_camera.width, m_camera.height);
    if (region.empty()) return out;
    rasterize_region(region, s);
    for (int y = region.y0; y < region.y1; ++y)
        for (int x = region.x0; x < region.x1; ++x) out.set(x, y, s.framebuffer.coverage[s.framebuffer.index_of(x, y)] >= 0.5f);
    return out;
}

}  // namespace flowvid::rigid
