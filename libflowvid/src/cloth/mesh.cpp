#include "flowvid/cloth/mesh.hpp"

#include "flowvid/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

namespace flowvid::cloth {

namespace {

double signed_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    return 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y()));
}

}  // namespace

std::vector<BendingStencil> bending_stencils(const ClothMesh& mesh) {
    const int n = mesh.vertex_count();
    // edge (lo, hi) -> triangles and their opposite vertices
    std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> edges;
    for (int t = 0; t < mesh.triangle_count(); ++t) {
        const auto& tri = mesh.triangles[static_cast<size_t>(t)];
        for (int k = 0; k < 3; ++k) {
            const int a = tri[static_cast<size_t>(k)];
            if (a < 0 || a >= n)
                throw Error("<mesh>", "triangles[" + std::to_string(t) + "]",
                            "vertex index " + std::to_string(a) + " is out of range (the mesh has " +
                                std::to_string(n) + " vertices)",
                            "use indices 0.." + std::to_string(n - 1));
        }
        for (int k = 0; k < 3; ++k) {
            const int a = tri[static_cast<size_t>(k)], b = tri[static_cast<size_t>((k + 1) % 3)];
            const int opposite = tri[static_cast<size_t>((k + 2) % 3)];
            edges[{std::min(a, b), std::max(a, b)}].push_back({t, opposite});
        }
    }
    std::vector<BendingStencil> stencils;
    stencils.reserve(edges.size());
    for (const auto& [edge, faces] : edges) {
        if (faces.size() > 2)
            throw Error("<mesh>", "triangles[" + std::to_string(faces[2].first) + "]",
                        "edge " + std::to_string(edge.first) + "-" + std::to_string(edge.second) + " has " +
                            std::to_string(faces.size()) + " triangles; cloth must be a manifold surface",
                        "split the mesh so that every edge has at most two triangles");
        if (faces.size() != 2) continue;
        BendingStencil s;
        s.vertices = {edge.first, edge.second, faces[0].second, faces[1].second};
        const Eigen::Vector2d& u0 = mesh.material_uv_m[static_cast<size_t>(edge.first)];
        const Eigen::Vector2d& u1 = mesh.material_uv_m[static_cast<size_t>(edge.second)];
        s.rest_edge_length_m = (u1 - u0).norm();
        s.rest_area_sum_m2 =
            std::abs(signed_area(u0, u1, mesh.material_uv_m[static_cast<size_t>(faces[0].second)])) +
            std::abs(signed_area(u0, u1, mesh.material_uv_m[static_cast<size_t>(faces[1].second)]));
        stencils.push_back(s);
    }
    return stencils;
}

ClothMesh make_swatch_mesh(double width_m, double height_m, int rows, int cols) {
    if (!(width_m > 0.0) || !(height_m > 0.0) || rows < 2 || cols < 2)
        throw Error("<swatch>", rows < 2 || cols < 2 ? "grid" : "size",
                    "a swatch needs a positive size and at least 2 x 2 vertices",
                    "give width_m, height_m > 0 and rows, cols >= 2");
    ClothMesh mesh;
    mesh.material_uv_m.reserve(static_cast<size_t>(rows) * static_cast<size_t>(cols));
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c)
            mesh.material_uv_m.emplace_back(width_m * c / (cols - 1), height_m * r / (rows - 1));
    for (int r = 0; r + 1 < rows; ++r) {
        for (int c = 0; c + 1 < cols; ++c) {
            const int v00 = r * cols + c, v01 = r * cols + c + 1;
            const int v10 = (r + 1) * cols + c, v11 = (r + 1) * cols + c + 1;
            // Counter-clockwise in uv, so u x v is the front normal.
            if ((r + c) % 2 == 0) {  // diagonal (0,0)-(1,1)
                mesh.triangles.push_back({v00, v01, v11});
                mesh.triangles.push_back({v00, v11, v10});
            } else {  // diagonal (1,0)-(0,1)
                mesh.triangles.push_back({v00, v01, v10});
                mesh.triangles.push_back({v01, v11, v10});
            }
        }
    }
    return mesh;
}

UvSampler::UvSampler(const ClothMesh& mesh, int rows, int cols) : m_rows(rows), m_cols(cols) {
    if (rows < 2 || cols < 2 || mesh.triangle_count() == 0)
        throw Error("<grid>", "grid", "a uv grid needs at least 2 x 2 samples and a mesh with triangles",
                    "use e.g. --grid 24x24");
    Eigen::Vector2d lo = mesh.material_uv_m.front(), hi = lo;
    for (const Eigen::Vector2d& uv : mesh.material_uv_m) {
        lo = lo.cwiseMin(uv);
        hi = hi.cwiseMax(uv);
    }
    const Eigen::Vector2d size = (hi - lo).cwiseMax(Eigen::Vector2d::Constant(1e-300));
    const double eps = 1e-9;
    m_samples.resize(static_cast<size_t>(rows) * static_cast<size_t>(cols));
    for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
            const Eigen::Vector2d p(lo.x() + size.x() * c / (cols - 1), lo.y() + size.y() * r / (rows - 1));
            double best_outside = std::numeric_limits<double>::infinity();
            Sample best{};
            for (const auto& tri : mesh.triangles) {
                const Eigen::Vector2d& a = mesh.material_uv_m[static_cast<size_t>(tri[0])];
                const Eigen::Vector2d& b = mesh.material_uv_m[static_cast<size_t>(tri[1])];
                const Eigen::Vector2d& cc = mesh.material_uv_m[static_cast<size_t>(tri[2])];
                const double area = signed_area(a, b, cc);
                if (area == 0.0) continue;
                double w[3] = {signed_area(p, b, cc) / area, signed_area(a, p, cc) / area,
                               signed_area(a, b, p) / area};
                const double outside = std::max({-w[0], -w[1], -w[2], 0.0});
                if (outside < best_outside) {
                    // Clamp to the triangle so that points just outside stay on the surface.
                    for (double& x : w) x = std::max(x, 0.0);
                    const double sum = w[0] + w[1] + w[2];
                    best = Sample{tri, {w[0] / sum, w[1] / sum, w[2] / sum}};
                    best_outside = outside;
                    if (outside <= eps) break;  // inside this triangle
                }
            }
            m_samples[static_cast<size_t>(r * cols + c)] = best;
        }
    }
}

Eigen::MatrixX3d UvSampler::sample(const Eigen::VectorXd& positions) const {
    Eigen::MatrixX3d out(static_cast<Eigen::Index>(m_samples.size()), 3);
    for (size_t i = 0; i < m_samples.size(); ++i) {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k)
            p += m_samples[i].weights[static_cast<size_t>(k)] *
                 positions.segment<3>(3 * m_samples[i].vertices[static_cast<size_t>(k)]);
        out.row(static_cast<Eigen::Index>(i)) = p.transpose();
    }
    return out;
}

}  // namespace flowvid::cloth
