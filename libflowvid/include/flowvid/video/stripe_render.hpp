#pragma once
// The simulation side of the angle-map metric (thesis 2.4.3): a simulated
// swatch seen through the capture's camera while the capture's projector
// casts the same sine stripes on it, rendered with the deterministic
// software rasterizer (render/rasterizer.hpp): z-buffer, no GPU, bit-identical
// results on any thread.
//
// Per pixel covered by the mesh: the world position is interpolated with the
// perspective-correct barycentrics, projected into the projector, and
//   intensity = 0.5 + 0.5 sin(2 pi v_p / period_px)
// with v_p the projector row (pattern axis "rows") or column ("columns"),
// exactly as the captures were made (../shared/captures/README.md). No
// projector shadowing, as in the captures. Optional Lambertian shading by the
// projector's light; the angle map does not need it (it measures orientation).

#include "flowvid/formats/capture.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/video/image.hpp"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <vector>

namespace flowvid::video {

enum class StripeShading {
    none,        // the stripe pattern only, in [0, 1]
    lambertian,  // times (ambient + (1 - ambient) |n . l|), l towards the projector
};

struct StripeRenderSettings {
    StripeShading shading = StripeShading::none;
    double ambient = 0.3;           // lambertian only
    float background = 0.0f;        // image value where the mesh does not cover the pixel centre
    int supersampling = 1;          // of the silhouette coverage (1..8); attributes come from the pixel centre
    bool projector_coordinates = false;  // also output v_p per pixel (tests, figures)
};

struct StripeImage {
    ImageF image;                    // linear intensity
    metrics::Silhouette silhouette;  // coverage >= 0.5
    ImageF projector_coordinate;     // v_p (projector pixels) where covered, NaN elsewhere; only when asked
    render::PixelRect region;        // pixels the mesh may touch (its projected bounding box)
    float background_value = 0.0f;   // what `image` holds outside the mesh
};

class StripeRenderer {
public:
    // Throws std::invalid_argument when the camera has no size or the pattern
    // has no positive period or an unknown axis.
    StripeRenderer(formats::CameraModel camera, formats::Projector projector, StripeRenderSettings settings = {});

    // Renders the mesh (`#V` world positions in metres, triangles indexing
    // them) into `out`, reusing its buffers.
    void render(const std::vector<Eigen::Vector3d>& vertices_m, const std::vector<std::array<int, 3>>& triangles,
                StripeImage& out);
    StripeImage render(const std::vector<Eigen::Vector3d>& vertices_m, const std::vector<std::array<int, 3>>& triangles);

    // The projector coordinate v_p of a world point (NaN behind the projector)
    // and the pattern intensity there: what every covered pixel shows.
    double projector_coordinate(const Eigen::Vector3d& world_m) const;
    double stripe_intensity(const Eigen::Vector3d& world_m) const;

    const formats::CameraModel& camera() const { return m_camera; }
    const formats::Projector& projector() const { return m_projector; }
    const StripeRenderSettings& settings() const { return m_settings; }

private:
    formats::CameraModel m_camera;
    formats::Projector m_projector;
    StripeRenderSettings m_settings;
    bool m_rows = true;
    render::Framebuffer m_framebuffer;
    std::vector<Eigen::Vector3d> m_normals;
    std::vector<Eigen::Vector2d> m_pixels;
    std::vector<double> m_numerator;    // per vertex, see render()
    std::vector<double> m_denominator;
};

// Triangles of a rows x cols vertex grid (vertex r * cols + c, row 0 at v = 0,
// column 0 at u = 0, as truth/positions.exr), two per quad, front faces
// towards u x v.
std::vector<std::array<int, 3>> grid_triangles(int rows, int cols);

// The vertices of one stored frame (0-based) of a vertex animation (e.g. the
// truth/positions.exr of a capture, in tests) as a vertex list.
std::vector<Eigen::Vector3d> vertices_of_frame(const formats::VertexAnimation& animation, int frame);
// A 3*#V position vector (the cloth simulator's layout) as a vertex list.
std::vector<Eigen::Vector3d> vertices_from_vector(const Eigen::VectorXd& positions_m);

}  // namespace flowvid::video
