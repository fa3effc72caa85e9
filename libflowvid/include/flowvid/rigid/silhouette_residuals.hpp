#pragma once
// Comparing a posed rigid body with an observed silhouette (thesis 2.3.3).
//
// Two measures:
//  * XOR (eq. 2.5): mismatched pixels between the rasterized silhouette and
//    the mask; piecewise constant in the pose, used for scoring starts and
//    by the thesis's optimizer.
//  * Edge distance (eq. 2.6), made continuous for least squares. The model's
//    outline is taken from the mesh geometry, not from pixels: the contour
//    generator (mesh edges between a front- and a back-facing triangle) is
//    projected and cut into pieces about one pixel long; pieces whose outer
//    side is covered by the body's own rasterized silhouette are hidden and
//    dropped. Then
//      model -> data: each visible piece's midpoint samples the mask's signed
//                     distance field (bilinear), weighted by the piece length;
//      data -> model: each observed edge point (half-way between an object
//                     pixel and a 4-neighbour background pixel) to the nearest
//                     visible piece (point to segment).
//    The frame cost E_k (px^2) is the mean of the two mean squared distances,
//    so E_k = 1 means the outlines are one pixel apart on average. Residuals
//    and their derivatives with respect to the pose are analytic (chain rule
//    through the projection), which is what Levenberg-Marquardt uses.

#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/rigid/dynamics.hpp"
#include "flowvid/rigid/nearest_segment.hpp"

#include <Eigen/Core>

#include <vector>

namespace flowvid::rigid {

// Where the body is in one frame: rotation camera_from_body and its COM in
// camera coordinates (m).
struct Pose {
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    Eigen::Vector3d com_m = Eigen::Vector3d::Zero();

    static Pose of(const RigidState& state) { return {state.rotation(), state.com_m}; }
    // Left perturbation: COM + d[0..2], rotation exp(d[3..5]) R.
    Pose perturbed(const Eigen::Matrix<double, 6, 1>& d) const;
};

// One observed frame, preprocessed once.
struct FrameObservation {
    int frame = 0;
    double time_s = 0.0;  // relative to the fit's reference frame
    metrics::Silhouette mask;
    metrics::DistanceField signed_distance;         // of the mask, px (negative inside)
    std::vector<Eigen::Vector2d> edge_points_px;    // sub-pixel outline points
    render::PixelRect bounds;                       // of the object pixels (empty when none)
    double area_px = 0.0;
    Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();
};
FrameObservation make_frame_observation(metrics::Silhouette mask, int frame, double time_s);

// A piece of the projected visible outline.
struct ContourPiece {
    Eigen::Vector3d body_a = Eigen::Vector3d::Zero();  // end points on the mesh edge, body frame relative to the COM
    Eigen::Vector3d body_b = Eigen::Vector3d::Zero();
    Eigen::Vector2d pixel_a = Eigen::Vector2d::Zero();  // their projections
    Eigen::Vector2d pixel_b = Eigen::Vector2d::Zero();
    Eigen::Vector2d mid_pixel = Eigen::Vector2d::Zero();  // projection of the 3D midpoint
    Eigen::Vector2d outward = Eigen::Vector2d::Zero();    // unit image normal pointing out of the silhouette
    double length_px = 0.0;
    // Distance (px) along the edge from the midpoint to the nearer end of the
    // mesh edge: a silhouette corner, where a mask made by thresholding pixel
    // coverage is rounded off and the sharp model does not fit it.
    double corner_distance_px = 0.0;
    double edge_s_a = 0.0;  // where the piece lies on its mesh edge (0..1)
    double edge_s_b = 0.0;
    double edge_length_px = 0.0;  // projected length of the whole mesh edge
};

struct FrameCost {
    double cost_px2 = 0.0;           // E_k = (model_to_data + data_to_model) / 2
    double model_to_data_px2 = 0.0;  // length-weighted mean of squared signed distances
    double data_to_model_px2 = 0.0;  // mean squared distance of observed edge points
    int contour_pieces = 0;          // visible pieces
    bool visible = false;            // some of the outline is in the image
};

// Gauss-Newton terms of one frame in pose coordinates (see Pose::perturbed).
struct PoseNormalEquations {
    Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> Jtr = Eigen::Matrix<double, 6, 1>::Zero();
};

struct SilhouetteOverlap {
    long long xor_px = 0;  // eq. 2.5
    long long intersection_px = 0;
    long long union_px = 0;
    double iou() const { return union_px == 0 ? 1.0 : static_cast<double>(intersection_px) / static_cast<double>(union_px); }
};

class SilhouetteModel {
public:
    // Reusable per-thread buffers: pass one Scratch per thread.
    struct Scratch {
        render::Framebuffer framebuffer;
        std::vector<Eigen::Vector3d> camera_points;
        std::vector<Eigen::Vector2d> pixels;
        std::vector<signed char> facing;
        std::vector<ContourPiece> pieces;
        std::vector<Segment2> segments;  // the pieces in pixels, for the nearest-piece search
        NearestSegmentGrid piece_grid;
    };

    SilhouetteModel(const RigidBody& body, const formats::CameraModel& camera);

    const formats::CameraModel& camera() const { return m_camera; }
    const RigidBody& body() const { return m_body; }

    // The visible outline pieces at `pose` (into scratch.pieces).
    void contour(const Pose& pose, Scratch& scratch, double piece_length_px = 1.0) const;
    // Outline within this distance (px) of a silhouette corner counts less
    // (weight (d / radius)^2): thresholded coverage rounds corners off. 0 = off.
    void set_corner_radius(double radius_px) { m_corner_radius_px = radius_px; }
    double corner_radius() const { return m_corner_radius_px; }
    // E_k and, when `normal` is given, its Gauss-Newton terms (residuals are
    // scaled so that E_k = sum of squared residuals).
    FrameCost edge_cost(const Pose& pose, const FrameObservation& observed, Scratch& scratch,
                        PoseNormalEquations* normal = nullptr) const;
    // Rasterized silhouette compared with the mask (pixel centres sampled).
    SilhouetteOverlap overlap(const Pose& pose, const FrameObservation& observed, Scratch& scratch) const;
    // Area (px) and centroid of the rasterized silhouette.
    struct Moments {
        double area_px = 0.0;
        Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();
    };
    Moments moments(const Pose& pose, Scratch& scratch) const;
    // The silhouette at `pose` over the whole image.
    metrics::Silhouette render(const Pose& pose, Scratch& scratch) const;
    // Pixel bounds of the projected vertices (empty when any is behind the camera).
    render::PixelRect projected_bounds(const Pose& pose, Scratch& scratch) const;
    // Projection of the COM (NaN when behind the camera).
    Eigen::Vector2d project(const Eigen::Vector3d& camera_point_m) const;
    // d pixel / d camera point (2 x 3), analytic without distortion.
    Eigen::Matrix<double, 2, 3> projection_jacobian(const Eigen::Vector3d& camera_point_m) const;

private:
    struct MeshEdge {
        int a = 0, b = 0;               // welded vertex indices
        std::vector<int> faces;         // adjacent triangles
        std::vector<int> opposite;      // their third vertices
    };
    void transform(const Pose& pose, Scratch& scratch) const;
    void rasterize_region(const render::PixelRect& region, Scratch& scratch) const;

    RigidBody m_body;
    formats::CameraModel m_camera;
    std::vector<Eigen::Vector3d> m_vertices;      // welded, relative to the COM
    std::vector<std::array<int, 3>> m_triangles;  // into m_vertices
    std::vector<MeshEdge> m_edges;
    bool m_distorted = false;
    bool m_closed = false;  // every edge between two faces: coverage from front faces alone
    double m_corner_radius_px = 1.5;
};

}  // namespace flowvid::rigid
