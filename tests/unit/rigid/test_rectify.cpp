// Roll correction (thesis fig. 2.8): a toss filmed by a rolled camera is
// fitted, and warping its masks by the fitted roll gives the masks the
// upright camera would have seen.

#include "flowvid/rigid/fit.hpp"
#include "flowvid/rigid/rectify.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

using namespace flowvid;
using namespace flowvid::rigid;

namespace {

Eigen::Vector3d vec3(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

metrics::Silhouette render_mask(const RigidBody& body, const formats::CameraModel& camera, const RigidState& state) {
    std::vector<Eigen::Vector3d> vertices;
    for (const Eigen::Vector3d& v : body.mesh.vertices_m) vertices.push_back(state.to_camera(body, v));
    render::RasterSettings settings;
    settings.supersampling = 5;
    const render::Framebuffer fb = render::rasterize(vertices, body.mesh.triangles, render::VertexSpace::camera, camera, settings);
    metrics::Silhouette mask(camera.width, camera.height);
    mask.pixels = fb.silhouette(0.5f);
    return mask;
}

}  // namespace

TEST(Rectify, TheWarpTurnsGravityStraightDown) {
    formats::CameraModel camera;
    camera.width = 480;
    camera.height = 360;
    camera.K << 600.0, 0.0, 250.0, 0.0, 640.0, 170.0, 0.0, 0.0, 1.0;  // fx != fy: a homography, not a rotation
    const GravityAngles gravity{0.1, 0.35};
    const Rectification r = roll_rectification(camera, gravity);
    const Eigen::Vector3d g = r.rotation * gravity.direction();
    EXPECT_NEAR(g.x(), 0.0, 1e-12);
    EXPECT_GT(g.y(), 0.9);
    EXPECT_NEAR(g.z(), std::sin(0.1), 1e-12);  // tilt is kept
    // The pixel warp is the image of the rotated camera.
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 3.0), Eigen::Vector3d(-1.0, 0.7, 5.0)})
        EXPECT_LT((r.apply(camera.project_camera_point(p)) - camera.project_camera_point(r.rotation * p)).norm(), 1e-9);
    // The principal point stays put.
    EXPECT_LT((r.apply({250.0, 170.0}) - Eigen::Vector2d(250.0, 170.0)).norm(), 1e-9);
}

TEST(Rectify, RolledTossIsFittedAndStraightened) {
    const formats::Capture capture = formats::read_capture(flowvid::testing::shared_path("captures/rigid-toss-major"));
    const RigidBody body = RigidBody::from_capture(*capture.rigid);
    const formats::CameraModel& camera = *capture.camera;
    const nlohmann::json truth =
        nlohmann::json::parse(flowvid::testing::read_text(flowvid::testing::shared_path("captures/rigid-toss-major/truth/truth.json")));
    FlightParameters upright;
    upright.com_m = vec3(truth["initial"]["com_cam"]);
    const nlohmann::json& q = truth["initial"]["orientation_cam_wxyz"];
    upright.orientation = Eigen::Quaterniond(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(), q[3].get<double>());
    upright.com_velocity_m_per_s = vec3(truth["initial"]["com_velocity_cam"]);
    upright.angular_velocity_rad_per_s = vec3(truth["initial"]["angular_velocity_cam"]);
    upright.gravity = GravityAngles::from_vector(vec3(truth["gravity_cam"]));

    // The same throw seen by the camera rolled 12 degrees about its axis
    // (rotating about the COM's line of sight keeps the body in view).
    const Eigen::Matrix3d roll = Eigen::AngleAxisd(12.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    FlightParameters rolled = upright;
    rolled.com_m = roll * upright.com_m;
    rolled.orientation = Eigen::Quaterniond(roll) * upright.orientation;
    rolled.com_velocity_m_per_s = roll * upright.com_velocity_m_per_s;
    rolled.angular_velocity_rad_per_s = roll * upright.angular_velocity_rad_per_s;
    rolled.gravity = GravityAngles::from_vector(roll * upright.gravity.direction());
    EXPECT_NEAR(rolled.gravity.roll_rad * 180.0 / M_PI, -12.0, 0.2);

    std::vector<double> times;
    for (int i = 0; i < 12; ++i) times.push_back(i / capture.fps);
    const Trajectory seen = simulate(body, rolled, times);
    const Trajectory straight = simulate(body, upright, times);
    std::vector<FrameObservation> frames;
    for (std::size_t i = 0; i < times.size(); ++i)
        frames.push_back(make_frame_observation(render_mask(body, camera, seen.states[i]), static_cast<int>(i) + 1, times[i]));
    const FitResult fit = fit_rigid(body, camera, capture.fps, frames, FitSettings{});
    EXPECT_NEAR(fit.parameters.gravity.roll_rad * 180.0 / M_PI, -12.0, 0.5);

    // Warping the rolled masks by the fitted roll gives the upright camera's masks.
    const Rectification rectification = roll_rectification(camera, fit.parameters.gravity);
    for (std::size_t i : {std::size_t{0}, std::size_t{6}, std::size_t{11}}) {
        const formats::Image warped = rectify_image(metrics::silhouette_to_image(frames[i].mask), rectification, true);
        const metrics::Silhouette expected = render_mask(body, camera, straight.states[i]);
        EXPECT_GT(metrics::silhouette_iou(metrics::silhouette_from_image(warped), expected), 0.85) << "frame " << i + 1;
    }
}

TEST(Rectify, WritesPngs) {
    formats::Image image;
    image.width = 4;
    image.height = 3;
    image.channels = 3;
    for (int i = 0; i < 36; ++i) image.pixels.push_back(static_cast<float>(i % 7) / 6.0f);
    const std::string path = flowvid::testing::scratch_dir("rigid_png") + "/image.png";
    write_png(path, image);
    const formats::Image back = formats::load_image(path, 3);
    ASSERT_EQ(back.width, 4);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) EXPECT_NEAR(back.pixels[i], image.pixels[i], 0.5 / 255.0 + 1e-6);
    EXPECT_THROW(write_png("/nonexistent-folder/x.png", image), IoError);
}
