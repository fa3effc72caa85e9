// The edge-distance residuals: outline geometry, gradient against finite
// differences, and single-frame pose recovery from synthetic masks.

#include "flowvid/rigid/optimize.hpp"
#include "flowvid/rigid/silhouette_residuals.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace flowvid;
using namespace flowvid::rigid;

namespace {

formats::CameraModel camera() {
    formats::CameraModel c;
    c.width = 480;
    c.height = 360;
    c.K << 640.0, 0.0, 239.5, 0.0, 640.0, 179.5, 0.0, 0.0, 1.0;
    return c;
}

// A T made of two boxes like the captures' body (metres, stem along z).
RigidBody t_body() {
    RigidBody body;
    auto box = [&](Eigen::Vector3d lo, Eigen::Vector3d hi) {
        const int base = static_cast<int>(body.mesh.vertices_m.size());
        for (int i = 0; i < 8; ++i)
            body.mesh.vertices_m.emplace_back((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(), (i & 4) ? hi.z() : lo.z());
        const std::array<std::array<int, 3>, 12> faces = {{{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                                            {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}}};
        for (const auto& f : faces) body.mesh.triangles.push_back({base + f[0], base + f[1], base + f[2]});
    };
    box({-0.03, -0.03, 0.0}, {0.03, 0.03, 0.24});
    box({-0.15, -0.03, 0.24}, {0.15, 0.03, 0.30});
    body.center_of_mass_m = {0.0, 0.0, 0.2033};
    body.inertia_kg_m2 = Eigen::Vector3d(0.0079, 0.0118, 0.0045).asDiagonal();
    return body;
}

Pose pose_a() {
    return Pose{(Eigen::AngleAxisd(0.9, Eigen::Vector3d(0.2, 1.0, 0.4).normalized()) *
                 Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()))
                    .toRotationMatrix(),
                Eigen::Vector3d(0.12, -0.08, 2.6)};
}

// A mask like the captures': coverage of 5 x 5 samples thresholded at 0.5.
FrameObservation observe(const SilhouetteModel& model, const Pose& pose) {
    std::vector<Eigen::Vector3d> vertices;
    for (const Eigen::Vector3d& v : model.body().mesh.vertices_m)
        vertices.push_back(pose.rotation * (v - model.body().center_of_mass_m) + pose.com_m);
    render::RasterSettings settings;
    settings.supersampling = 5;
    const render::Framebuffer fb =
        render::rasterize(vertices, model.body().mesh.triangles, render::VertexSpace::camera, model.camera(), settings);
    metrics::Silhouette mask(model.camera().width, model.camera().height);
    mask.pixels = fb.silhouette(0.5f);
    return make_frame_observation(std::move(mask), 1, 0.0);
}

}  // namespace

TEST(SilhouetteResiduals, VisibleOutlineHasThePerimeterOfTheSilhouette) {
    const RigidBody body = t_body();
    const SilhouetteModel model(body, camera());
    SilhouetteModel::Scratch scratch;
    const Pose pose = pose_a();
    model.contour(pose, scratch);
    double length = 0.0;
    for (const ContourPiece& p : scratch.pieces) length += p.length_px;
    // The outline of the rendered mask, counted along pixel edges, over-estimates
    // a slanted outline by up to 4/pi; the geometric outline lies in between.
    const FrameObservation observed = observe(model, pose);
    const double staircase = static_cast<double>(observed.edge_points_px.size());
    EXPECT_GT(length, staircase * M_PI / 4.0 * 0.95);
    EXPECT_LT(length, staircase * 1.02);
    // Every piece lies on the observed outline (within the half pixel of quantisation).
    for (const ContourPiece& p : scratch.pieces) EXPECT_LT(std::abs(observed.signed_distance.sample(p.mid_pixel)), 0.75);
}

TEST(SilhouetteResiduals, GradientMatchesFiniteDifferences) {
    const RigidBody body = t_body();
    SilhouetteModel model(body, camera());
    model.set_corner_radius(0.0);
    SilhouetteModel::Scratch scratch;
    const FrameObservation observed = observe(model, pose_a());
    Eigen::Matrix<double, 6, 1> offset;
    offset << 0.004, -0.003, 0.02, 0.03, -0.02, 0.04;
    const Pose pose = pose_a().perturbed(offset);
    PoseNormalEquations normal;
    const double cost = model.edge_cost(pose, observed, scratch, &normal).cost_px2;
    EXPECT_GT(cost, 0.5);  // a few tenths of a pixel off on average
    // E = sum r^2, so dE/dpose = 2 J^T r. The cost is piecewise smooth (pieces
    // appear and disappear), so compare with moderately small steps.
    for (int k = 0; k < 6; ++k) {
        const double h = 2e-5;
        Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
        d[k] = h;
        const double fd = (model.edge_cost(pose.perturbed(d), observed, scratch).cost_px2 -
                           model.edge_cost(pose.perturbed(-d), observed, scratch).cost_px2) /
                          (2 * h);
        EXPECT_NEAR(2.0 * normal.Jtr[k], fd, 0.03 * std::abs(fd) + 1e-3 * normal.Jtr.norm()) << "component " << k;
    }
}

TEST(SilhouetteResiduals, PoseFitRecoversAPerturbedPose) {
    const RigidBody body = t_body();
    const SilhouetteModel model(body, camera());
    SilhouetteModel::Scratch scratch;
    const Pose truth = pose_a();
    const FrameObservation observed = observe(model, truth);
    Eigen::Matrix<double, 6, 1> offset;
    offset << 0.01, -0.008, 0.05, 0.08, -0.06, 0.1;  // about 7 degrees and 5 px
    const PoseFit fit = fit_pose(model, observed, truth.perturbed(offset), scratch, 40);
    const double angle = Eigen::AngleAxisd(fit.pose.rotation * truth.rotation.transpose()).angle();
    EXPECT_LT(angle * 180.0 / M_PI, 0.3);
    // Lateral position to a tenth of a pixel (2.6 m away, 640 px focal length).
    EXPECT_LT((fit.pose.com_m - truth.com_m).head<2>().norm() * 640.0 / 2.6, 0.1);
    EXPECT_LT(std::abs(fit.pose.com_m.z() - truth.com_m.z()), 0.005);
    EXPECT_LT(fit.cost_px2, 0.1);
    // The XOR count at the fitted pose is a few boundary pixels at most.
    EXPECT_LT(model.overlap(fit.pose, observed, scratch).xor_px, 12);
}

TEST(SilhouetteResiduals, AnEmptyViewCostsMoreThanAnyOverlap) {
    const RigidBody body = t_body();
    const SilhouetteModel model(body, camera());
    SilhouetteModel::Scratch scratch;
    const FrameObservation observed = observe(model, pose_a());
    Pose away = pose_a();
    away.com_m.z() = -3.0;  // behind the camera
    const FrameCost missing = model.edge_cost(away, observed, scratch);
    EXPECT_FALSE(missing.visible);
    Pose off = pose_a();
    off.com_m.x() += 0.3;  // about 70 px beside the observation
    EXPECT_GT(missing.cost_px2, model.edge_cost(off, observed, scratch).cost_px2);
}
