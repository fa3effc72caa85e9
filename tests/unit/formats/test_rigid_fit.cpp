// flowvid.rigid_fit (fit.json written by `flowvid fit rigid`) as a file
// format: the example reads and writes back to the same bytes, older files
// without the optional keys read, every class of bad input is refused naming
// the file, the field and the fix, and guesses take what they give.
// (tests/unit/rigid/test_fit_file.cpp checks the fit <-> file conversion.)

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/rigid_fit.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string example_path() { return source_path("formats/examples/toss.rigid_fit.json"); }
nlohmann::json example() { return nlohmann::json::parse(read_text(example_path())); }

using flowvid::testing::mentions;

}  // namespace

TEST(RigidFitFormat, ExampleLoadsAndValidates) {
    std::vector<Problem> warnings;
    const RigidFit fit = read_rigid_fit(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(fit.capture, "../shared/captures/rigid-toss-major");
    EXPECT_EQ(fit.capture_json_sha256.size(), 64u);
    EXPECT_EQ(fit.initial_frame, 1);
    EXPECT_EQ(fit.first_fitted_frame, 1);
    EXPECT_EQ(fit.last_fitted_frame, 12);
    EXPECT_EQ(fit.frames.size(), 12u);
    EXPECT_NEAR(fit.gravity_cam.norm(), 9.81, 1e-9);
    EXPECT_NEAR(fit.initial.orientation_cam.norm(), 1.0, 1e-9);
    ASSERT_TRUE(fit.error.has_value());
    EXPECT_EQ(fit.error->status, "converged");
    EXPECT_EQ(fit.symmetries_body.size(), 2u);
    EXPECT_TRUE(fit.details.is_object());
    EXPECT_TRUE(validate_rigid_fit_file(example_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(example_path()), FileKind::rigid_fit);
    EXPECT_EQ(summarize_any_file(example_path())["kind"], "rigid fit");
}

TEST(RigidFitFormat, RoundTripIsBitExact) {
    const std::string dir = scratch_dir("rigid_fit_format_round_trip");
    const RigidFit fit = read_rigid_fit(example_path());
    write_rigid_fit(dir + "/fit.json", fit);
    EXPECT_EQ(read_text(dir + "/fit.json"), read_text(example_path()));
}

TEST(RigidFitFormat, OptionalKeysMayBeAbsent) {
    const std::string dir = scratch_dir("rigid_fit_format_minimal");
    nlohmann::json document = example();
    for (const char* key : {"conventions", "capture_json_sha256", "gravity_magnitude_m_per_s2", "gravity_angles_deg", "optimizer",
                            "error", "frames", "symmetries_body", "timing_s", "details"})
        document.erase(key);
    document["initial"].erase("origin_velocity_cam");
    document["initial"].erase("angular_velocity_body");
    write_text(dir + "/fit.json", document.dump(2));
    const RigidFit fit = read_rigid_fit(dir + "/fit.json");
    EXPECT_EQ(fit.gravity_magnitude_m_per_s2, kRigidFitDefaultGravity_m_per_s2);
    EXPECT_FALSE(fit.error.has_value());
    EXPECT_TRUE(fit.frames.empty());
    EXPECT_TRUE(validate_rigid_fit_file(dir + "/fit.json", Strictness::strict).empty());
}

TEST(RigidFitFormat, EveryClassOfBadInputNamesFileFieldAndFix) {
    const std::string dir = scratch_dir("rigid_fit_format_bad");
    const std::string path = dir + "/fit.json";
    const auto expect_refused = [&](const nlohmann::json& document, const std::string& field) {
        write_text(path, document.dump(2));
        const std::string messages = validation_messages([&] { read_rigid_fit(path); });
        EXPECT_TRUE(mentions(messages, path + ": " + field + ": ")) << field << "\n" << messages;
        EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    };
    nlohmann::json document = example();
    document["initial"]["com_velocity_cam"] = "fast";  // wrong type
    expect_refused(document, "/initial/com_velocity_cam");
    document = example();
    document["frames"][2]["xor_px"] = 1.5;
    expect_refused(document, "/frames/2/xor_px");

    document = example();
    document.erase("gravity_cam");  // missing field
    expect_refused(document, "/gravity_cam");
    document = example();
    document["frames"][0].erase("frame");
    expect_refused(document, "/frames/0/frame");

    document = example();
    document["fps"] = -30;  // out of range
    expect_refused(document, "/fps");
    document = example();
    document["frames"][4]["iou"] = 1.2;
    expect_refused(document, "/frames/4/iou");
    document = example();
    document["fit_frames"] = {9, 4};
    expect_refused(document, "/fit_frames");
    document = example();
    document["fit_frames"] = {1, 4.5};
    expect_refused(document, "/fit_frames/1");
    document = example();
    document["initial"]["orientation_cam_wxyz"] = {0.9, 0.0, 0.0, 0.0};
    expect_refused(document, "/initial/orientation_cam_wxyz");
    document = example();
    document["gravity_cam"] = {0, 0, 0};
    expect_refused(document, "/gravity_cam");
    document = example();
    document["symmetries_body"][1] = {{2, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    expect_refused(document, "/symmetries_body/1");

    document = example();
    document["version"] = "2.0";  // wrong version
    expect_refused(document, "/version");
    document["version"] = 1;
    expect_refused(document, "/version");
}

TEST(RigidFitFormat, WriterNamesNonFiniteValuesAndLeavesNoFile) {
    const std::string dir = scratch_dir("rigid_fit_format_nan");
    RigidFit fit = read_rigid_fit(example_path());
    fit.initial.angular_velocity_cam.y() = std::numeric_limits<double>::infinity();
    fit.frames[1].edge_rms_px = std::numeric_limits<double>::quiet_NaN();
    const std::string path = dir + "/fit.json";
    std::string messages = validation_messages([&] { write_rigid_fit(path, fit); });
    EXPECT_TRUE(mentions(messages, path + ": /initial/angular_velocity_cam: not finite")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
    fit.initial.angular_velocity_cam.y() = 0.0;
    messages = validation_messages([&] { write_rigid_fit(path, fit); });
    EXPECT_TRUE(mentions(messages, path + ": /frames/1/edge_rms_px")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(RigidFitFormat, GuessesTakeWhatTheyGive) {
    const std::string dir = scratch_dir("rigid_fit_format_guess");
    // A fit file is a complete guess.
    const RigidFitGuess full = read_rigid_fit_guess(example_path());
    EXPECT_TRUE(full.position_cam && full.orientation_cam && full.com_velocity_cam && full.angular_velocity_cam && full.gravity_cam);
    EXPECT_EQ(full.initial_frame, 1);
    write_text(dir + "/spin.json", R"({"initial": {"angular_velocity_cam": [0, 0, 12]}, "initial_frame": 3})");
    const RigidFitGuess spin = read_rigid_fit_guess(dir + "/spin.json");
    EXPECT_FALSE(spin.orientation_cam.has_value());
    EXPECT_EQ(spin.initial_frame, 3);
    EXPECT_DOUBLE_EQ(spin.angular_velocity_cam->z(), 12.0);
    // A file declaring another format is not a guess.
    const std::string capture = dir + "/other.json";
    write_text(capture, R"({"format": "flowvid.capture", "version": "1.0", "gravity_cam": [0, 9.81, 0]})");
    EXPECT_TRUE(mentions(validation_messages([&] { read_rigid_fit_guess(capture); }), capture + ": /format"));
    write_text(dir + "/empty.json", R"({"comment": "nothing here"})");
    EXPECT_TRUE(mentions(validation_messages([&] { read_rigid_fit_guess(dir + "/empty.json"); }), dir + "/empty.json: /initial"));
}
