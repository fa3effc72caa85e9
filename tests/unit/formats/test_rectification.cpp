// flowvid.rectification (rectify.json written by `flowvid rectify`): the
// example reads and writes back to the same bytes; every class of bad input
// is refused naming the file, the field and the fix.

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/rectification.hpp"
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

std::string example_path() { return source_path("formats/examples/straight.rectify.json"); }
nlohmann::json example() { return nlohmann::json::parse(read_text(example_path())); }

using flowvid::testing::mentions;

}  // namespace

TEST(Rectification, ExampleLoadsAndValidates) {
    std::vector<Problem> warnings;
    const RectificationFile r = read_rectification(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(r.fit, "toss.rigid_fit.json");
    EXPECT_LT(std::abs(r.roll_deg), 1.0);
    EXPECT_NEAR(r.homography_output_from_input(2, 2), 1.0, 1e-12);
    EXPECT_TRUE(validate_rectification_file(example_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(example_path()), FileKind::rectification);
    EXPECT_EQ(summarize_any_file(example_path())["kind"], "rectification");
}

TEST(Rectification, RoundTripIsBitExact) {
    const std::string dir = scratch_dir("rectification_round_trip");
    const RectificationFile r = read_rectification(example_path());
    write_rectification(dir + "/rectify.json", r);
    EXPECT_EQ(read_text(dir + "/rectify.json"), read_text(example_path()));
    EXPECT_TRUE(read_rectification(dir + "/rectify.json") == r);
}

TEST(Rectification, EveryClassOfBadInputNamesFileFieldAndFix) {
    const std::string dir = scratch_dir("rectification_bad");
    const std::string path = dir + "/rectify.json";
    const auto expect_refused = [&](const nlohmann::json& document, const std::string& field) {
        write_text(path, document.dump(2));
        const std::string messages = validation_messages([&] { read_rectification(path); });
        EXPECT_TRUE(mentions(messages, path + ": " + field + ": ")) << field << "\n" << messages;
        EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    };
    nlohmann::json document = example();
    document["roll_deg"] = "small";  // wrong type
    expect_refused(document, "/roll_deg");
    document = example();
    document["homography_output_from_input"][1] = {1.0, 2.0};
    expect_refused(document, "/homography_output_from_input/1");

    document = example();
    document.erase("fit");  // missing field
    expect_refused(document, "/fit");

    document = example();
    document["roll_deg"] = 400.0;  // out of range
    expect_refused(document, "/roll_deg");
    document = example();
    document["tilt_deg_not_corrected"] = -95.0;
    expect_refused(document, "/tilt_deg_not_corrected");
    document = example();
    document["homography_output_from_input"] = {{1, 2, 0}, {2, 4, 0}, {0, 0, 1}};  // singular
    expect_refused(document, "/homography_output_from_input");

    document = example();
    document["version"] = "2.0";  // wrong version
    expect_refused(document, "/version");
    document = example();
    document["format"] = "flowvid.rigid_fit";
    expect_refused(document, "/format");
}

TEST(Rectification, WriterRefusesANaNAndLeavesNoFile) {
    const std::string dir = scratch_dir("rectification_nan");
    RectificationFile r = read_rectification(example_path());
    r.homography_output_from_input(0, 1) = std::numeric_limits<double>::quiet_NaN();
    const std::string path = dir + "/rectify.json";
    const std::string messages = validation_messages([&] { write_rectification(path, r); });
    EXPECT_TRUE(mentions(messages, path + ": /homography_output_from_input/0/1")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
}
