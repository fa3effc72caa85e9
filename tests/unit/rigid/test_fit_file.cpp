// fit.json (flowvid.rigid_fit 1.0): round trip, the truth.json keys, every
// problem of a bad file reported with file and field, guess files.

#include "flowvid/rigid/fit_file.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <limits>

using namespace flowvid;
using namespace flowvid::rigid;
using flowvid::testing::scratch_dir;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

using flowvid::testing::mentions;

struct Example {
    formats::Capture capture;
    RigidBody body;
    FitResult fit;
};

// A fit of frames 4-9 with made-up but plausible numbers.
Example example() {
    Example e;
    e.capture = formats::read_capture(flowvid::testing::shared_path("captures/rigid-toss-major"));
    e.body = RigidBody::from_capture(*e.capture.rigid);
    e.fit.fps = 30.0;
    e.fit.reference_frame = 4;
    e.fit.parameters.com_m = {-0.4, 0.5, 4.4};
    e.fit.parameters.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
    e.fit.parameters.com_velocity_m_per_s = {0.7, -4.7, -0.6};
    e.fit.parameters.angular_velocity_rad_per_s = {-4.1, -2.7, 12.0};
    e.fit.parameters.gravity = GravityAngles{0.059, 0.01};
    for (int f = 4; f <= 9; ++f) e.fit.frames.push_back({f, 0.25, 3, 0.99});
    e.fit.final_cost_px2 = 6 * 0.0625;
    return e;
}

}  // namespace

TEST(RigidFitFile, RoundTripHoldsTheStateAtTheCapturesFirstFrame) {
    const Example e = example();
    const RigidFitRecord record = make_rigid_fit_record(e.fit, e.body, e.capture, "toss");
    EXPECT_EQ(record.initial_frame, 1);
    EXPECT_EQ(record.first_fitted_frame, 4);
    EXPECT_EQ(record.last_fitted_frame, 9);
    const std::string path = scratch_dir("rigid_fit_file") + "/fit.json";
    write_rigid_fit(path, record, e.body);
    const RigidFitRecord back = read_rigid_fit(path);
    EXPECT_LT((back.initial.com_m - record.initial.com_m).norm(), 1e-12);
    EXPECT_LT(back.initial.orientation.angularDistance(record.initial.orientation), 1e-12);
    EXPECT_LT((back.initial.angular_velocity_rad_per_s - record.initial.angular_velocity_rad_per_s).norm(), 1e-12);
    EXPECT_NEAR(back.initial.gravity.tilt_rad, 0.059, 1e-12);
    EXPECT_EQ(back.frames.size(), 6u);
    // Predicting from the record gives the fitted state back at frame 4.
    const RigidState at4 = back.as_fit_result().state_at_frame(e.body, 4);
    EXPECT_LT((at4.com_m - e.fit.parameters.com_m).norm(), 1e-8);
    EXPECT_LT(at4.orientation.angularDistance(e.fit.parameters.orientation), 1e-7);

    // The keys and meaning of truth/truth.json.
    const nlohmann::json document = nlohmann::json::parse(flowvid::testing::read_text(path));
    EXPECT_EQ(document["format"], "flowvid.rigid_fit");
    EXPECT_EQ(document["version"], "1.0");
    for (const char* key : {"position_cam", "com_cam", "orientation_cam_wxyz", "com_velocity_cam", "angular_velocity_cam"})
        EXPECT_TRUE(document["initial"].contains(key)) << key;
    const Eigen::Vector3d position(document["initial"]["position_cam"][0], document["initial"]["position_cam"][1],
                                   document["initial"]["position_cam"][2]);
    EXPECT_LT((position - record.initial.initial_state().origin_m(e.body)).norm(), 1e-12);
    EXPECT_EQ(document["gravity_cam"].size(), 3u);
    EXPECT_NEAR(std::hypot(document["gravity_cam"][0].get<double>(), document["gravity_cam"][1].get<double>(),
                           document["gravity_cam"][2].get<double>()),
                9.81, 1e-12);
    EXPECT_EQ(document["frames"].size(), 6u);
    EXPECT_TRUE(document["error"].contains("final_cost_px2"));
    EXPECT_EQ(document["symmetries_body"].size(), 2u);
    EXPECT_TRUE(validate_rigid_fit_file(path, formats::Strictness::strict).empty());
}

TEST(RigidFitFile, ReportsEveryProblemWithFileAndField) {
    const Example e = example();
    const std::string dir = scratch_dir("rigid_fit_file_bad");
    const std::string good = dir + "/good.json";
    write_rigid_fit(good, make_rigid_fit_record(e.fit, e.body, e.capture, "toss"), e.body);
    nlohmann::json document = nlohmann::json::parse(flowvid::testing::read_text(good));
    document["initial"].erase("com_cam");
    document["initial"]["orientation_cam_wxyz"] = {0.9, 0.0, 0.0, 0.0};
    document["fps"] = -30;
    document["gravity_cam"] = {0, 0, 0};
    document["fit_frames"] = {9, 4};
    const std::string bad = dir + "/bad.json";
    write_text(bad, document.dump());
    const std::string messages = validation_messages([&] { read_rigid_fit(bad); });
    for (const char* field : {"/initial/com_cam", "/initial/orientation_cam_wxyz", "/fps", "/gravity_cam", "/fit_frames"})
        EXPECT_TRUE(mentions(messages, bad + ": " + field)) << field << "\n" << messages;

    document = nlohmann::json::parse(flowvid::testing::read_text(good));
    document["version"] = "2.0";
    write_text(bad, document.dump());
    EXPECT_TRUE(mentions(validation_messages([&] { read_rigid_fit(bad); }), bad + ": /version"));

    // Unknown keys: errors under validate, accepted (with a warning) by the reader.
    document = nlohmann::json::parse(flowvid::testing::read_text(good));
    document["colour"] = "red";
    write_text(bad, document.dump());
    EXPECT_NO_THROW(read_rigid_fit(bad));
    const std::vector<Problem> problems = validate_rigid_fit_file(bad, formats::Strictness::strict);
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_EQ(problems[0].field, "/colour");
    EXPECT_THROW(read_rigid_fit(dir + "/missing.json"), IoError);
}

TEST(RigidFitFile, WriterRefusesNonFiniteResultsAndLeavesNoFile) {
    Example e = example();
    RigidFitRecord record = make_rigid_fit_record(e.fit, e.body, e.capture, "toss");
    record.initial.com_m.x() = std::numeric_limits<double>::quiet_NaN();
    const std::string path = scratch_dir("rigid_fit_file_nan") + "/fit.json";
    const std::string messages = validation_messages([&] { write_rigid_fit(path, record, e.body); });
    EXPECT_TRUE(mentions(messages, path + ": /initial/com_cam")) << messages;
    EXPECT_FALSE(std::ifstream(path).good());
}

TEST(RigidFitFile, GuessFilesTakeWhatTheyGive) {
    // A capture's truth.json works as a guess (complete, at frame 1).
    const GuessFile truth = read_guess_file(flowvid::testing::shared_path("captures/rigid-toss-major/truth/truth.json"));
    EXPECT_TRUE(truth.guess.complete());
    EXPECT_TRUE(truth.guess.gravity_m_per_s2.has_value());
    EXPECT_FALSE(truth.initial_frame.has_value());

    const std::string dir = scratch_dir("rigid_guess");
    write_text(dir + "/spin.json", R"({"initial": {"angular_velocity_cam": [0, 0, 12]}, "initial_frame": 3})");
    const GuessFile spin = read_guess_file(dir + "/spin.json");
    EXPECT_FALSE(spin.guess.complete());
    EXPECT_EQ(*spin.initial_frame, 3);
    EXPECT_FALSE(spin.guess.orientation.has_value());
    EXPECT_DOUBLE_EQ(spin.guess.angular_velocity_rad_per_s->z(), 12.0);

    write_text(dir + "/empty.json", R"({"comment": "nothing here"})");
    EXPECT_TRUE(mentions(validation_messages([&] { read_guess_file(dir + "/empty.json"); }), dir + "/empty.json: /initial"));
    write_text(dir + "/bad.json", R"({"initial": {"orientation_cam_wxyz": [2, 0, 0], "com_velocity_cam": "fast"}})");
    const std::string messages = validation_messages([&] { read_guess_file(dir + "/bad.json"); });
    EXPECT_TRUE(mentions(messages, dir + "/bad.json: /initial/orientation_cam_wxyz")) << messages;
    EXPECT_TRUE(mentions(messages, dir + "/bad.json: /initial/com_velocity_cam")) << messages;
}
