// flowvid fit rigid / predict rigid / rectify as a user meets them: help,
// bad input named by file and field, and a real fit checked against the truth.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/rigid/dynamics.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>

using namespace flowvid::testing;

namespace {

using flowvid::testing::mentions;
std::string major() { return shared_path("captures/rigid-toss-major"); }

Eigen::Vector3d vec3(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }
Eigen::Quaterniond quat(const nlohmann::json& j) {
    return Eigen::Quaterniond(j[0].get<double>(), j[1].get<double>(), j[2].get<double>(), j[3].get<double>());
}

}  // namespace

TEST(CliRigid, HelpNamesTheKindsOptionsAndExamples) {
    const CliResult fit = run_flowvid({"help", "fit"});
    EXPECT_EQ(fit.exit_code, 0);
    EXPECT_TRUE(mentions(fit.out, "rigid")) << fit.out;
    EXPECT_TRUE(mentions(fit.out, "Examples")) << fit.out;
    const CliResult rigid = run_flowvid({"fit", "rigid", "--help"});
    EXPECT_EQ(rigid.exit_code, 0);
    for (const char* part : {"--capture", "--out", "--frames", "--guess", "--optimizer", "Examples", "9.81"})
        EXPECT_TRUE(mentions(rigid.out, part)) << part << "\n" << rigid.out;
    const CliResult predict = run_flowvid({"predict", "rigid", "--help"});
    EXPECT_EQ(predict.exit_code, 0);
    EXPECT_TRUE(mentions(predict.out, "--fit")) << predict.out;
    const CliResult rectify = run_flowvid({"help", "rectify"});
    EXPECT_EQ(rectify.exit_code, 0);
    EXPECT_TRUE(mentions(rectify.out, "Examples")) << rectify.out;
    EXPECT_TRUE(mentions(run_flowvid({"--help"}).out, "rectify"));
}

TEST(CliRigid, BadInputIsNamedWithFileAndField) {
    const std::string dir = scratch_dir("cli_rigid_bad");
    // Usage errors: a missing option, a missing kind, a malformed or impossible frame range.
    EXPECT_EQ(run_flowvid({"fit", "rigid", "--capture", major()}).exit_code, 2);
    EXPECT_EQ(run_flowvid({"fit"}).exit_code, 2);
    EXPECT_EQ(run_flowvid({"fit", "rigid", "--capture", major(), "--out", dir + "/f.json", "--frames", "3-9"}).exit_code, 2);
    const CliResult outside = run_flowvid({"fit", "rigid", "--capture", major(), "--out", dir + "/f.json", "--frames", "30:50"});
    EXPECT_EQ(outside.exit_code, 2);
    EXPECT_TRUE(mentions(outside.err, "1:36")) << outside.err;

    // A missing capture folder is an I/O error naming it.
    const CliResult missing = run_flowvid({"fit", "rigid", "--capture", dir + "/nowhere", "--out", dir + "/f.json"});
    EXPECT_EQ(missing.exit_code, 4);
    EXPECT_TRUE(mentions(missing.err, dir + "/nowhere")) << missing.err;

    // A capture of the wrong kind: invalid input naming capture.json and /kind.
    const std::string cloth = shared_path("captures/cloth-cotton-static-1");
    const CliResult kind = run_flowvid({"fit", "rigid", "--capture", cloth, "--out", dir + "/f.json"});
    EXPECT_EQ(kind.exit_code, 3);
    EXPECT_TRUE(mentions(kind.err, cloth + "/capture.json: /kind")) << kind.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/f.json"));

    // An invalid guess and an invalid fit file: every field named.
    write_text(dir + "/guess.json", R"({"initial": {"orientation_cam_wxyz": [3, 0, 0, 0], "angular_velocity_cam": [1, 2]}})");
    const CliResult guess = run_flowvid({"fit", "rigid", "--capture", major(), "--out", dir + "/f.json", "--guess", dir + "/guess.json"});
    EXPECT_EQ(guess.exit_code, 3);
    EXPECT_TRUE(mentions(guess.err, dir + "/guess.json: /initial/orientation_cam_wxyz")) << guess.err;
    EXPECT_TRUE(mentions(guess.err, dir + "/guess.json: /initial/angular_velocity_cam")) << guess.err;
    write_text(dir + "/fit.json", R"({"format": "flowvid.rigid_fit", "version": "1.0", "fps": 30})");
    const CliResult fit = run_flowvid({"predict", "rigid", "--fit", dir + "/fit.json", "--capture", major(), "--out", dir + "/p"});
    EXPECT_EQ(fit.exit_code, 3);
    for (const char* field : {"/initial", "/gravity_cam", "/capture"})
        EXPECT_TRUE(mentions(fit.err, dir + "/fit.json: " + std::string(field))) << field << "\n" << fit.err;
    const CliResult wrong = run_flowvid({"predict", "rigid", "--fit", major() + "/capture.json", "--capture", major(), "--out", dir + "/p"});
    EXPECT_EQ(wrong.exit_code, 3);
    EXPECT_TRUE(mentions(wrong.err, major() + "/capture.json: /format")) << wrong.err;
}

TEST(CliRigid, FitsPredictsAndRectifiesARealToss) {
    const std::string dir = scratch_dir("cli_rigid_fit");
    const CliResult fit = run_flowvid({"-q", "fit", "rigid", "--capture", major(), "--out", dir + "/fit.json", "--frames", "1:12", "--json"});
    ASSERT_EQ(fit.exit_code, 0) << fit.err;
    const nlohmann::json summary = nlohmann::json::parse(fit.out);
    EXPECT_EQ(summary["frames"], "1:12");

    // Against the truth (evaluation only), at the capture's first frame.
    const nlohmann::json document = nlohmann::json::parse(read_text(dir + "/fit.json"));
    const nlohmann::json truth = nlohmann::json::parse(read_text(major() + "/truth/truth.json"));
    EXPECT_EQ(document["initial_frame"], 1);
    const double gravity_deg =
        std::acos(std::clamp(vec3(document["gravity_cam"]).normalized().dot(vec3(truth["gravity_cam"]).normalized()), -1.0, 1.0)) *
        180.0 / M_PI;
    EXPECT_LT(gravity_deg, 1.0);
    // Up to the T's symmetry: 180 degrees about its stem (body z).
    const std::vector<Eigen::Matrix3d> symmetries = {Eigen::Matrix3d::Identity(), Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()};
    const double orientation_deg = flowvid::rigid::orientation_distance_rad(quat(document["initial"]["orientation_cam_wxyz"]),
                                                                             quat(truth["initial"]["orientation_cam_wxyz"]), symmetries) *
                                   180.0 / M_PI;
    EXPECT_LT(orientation_deg, 5.0);
    const Eigen::Vector3d w = vec3(document["initial"]["angular_velocity_cam"]);
    const Eigen::Vector3d w_true = vec3(truth["initial"]["angular_velocity_cam"]);
    EXPECT_LT((w - w_true).norm() / w_true.norm(), 0.05);
    EXPECT_LT((vec3(document["initial"]["com_cam"]) - vec3(truth["initial"]["com_cam"])).norm(), 0.02);
    EXPECT_EQ(document["frames"].size(), 12u);
    EXPECT_LT(document["error"]["mean_edge_rms_px"].get<double>(), 0.5);

    // Predict the next frames from the 12 fitted ones.
    const CliResult predict = run_flowvid(
        {"-q", "predict", "rigid", "--fit", dir + "/fit.json", "--capture", major(), "--out", dir + "/predicted", "--frames", "13:20", "--json"});
    ASSERT_EQ(predict.exit_code, 0) << predict.err;
    const nlohmann::json predicted = nlohmann::json::parse(predict.out);
    EXPECT_GT(predicted["iou_mean"].get<double>(), 0.85);
    EXPECT_EQ(predicted["per_frame"].size(), 8u);
    EXPECT_TRUE(std::filesystem::exists(dir + "/predicted/000013.png"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/predicted/000020.png"));

    // Rectify two frames: a valid capture comes out.
    const CliResult rectify = run_flowvid({"-q", "rectify", "--fit", dir + "/fit.json", "--capture", major(), "--out", dir + "/straight", "--frames", "1:2"});
    ASSERT_EQ(rectify.exit_code, 0) << rectify.err;
    EXPECT_TRUE(std::filesystem::exists(dir + "/straight/frames/000002.png"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/straight/masks/000001.png"));
    const CliResult valid = run_flowvid({"validate", dir + "/straight"});
    EXPECT_EQ(valid.exit_code, 0) << valid.err;
    const nlohmann::json description = nlohmann::json::parse(read_text(dir + "/straight/rectify.json"));
    EXPECT_LT(std::abs(description["roll_deg"].get<double>()), 1.0);  // this camera was upright
}
