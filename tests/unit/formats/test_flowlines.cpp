// Flow-line set JSON files (*.flowlines.json): the kept example, bit-exact
// round trips, key interpolation, and every kind of bad input named by file
// and JSON pointer.

#include "flowvid/formats/flowlines.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

namespace flowvid::formats {
namespace {

using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::test_data;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

std::string example_path() { return source_path("formats/examples/waterfall.flowlines.json"); }

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool same_bits(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (!same_bits(a[i].x(), b[i].x()) || !same_bits(a[i].y(), b[i].y())) return false;
    return true;
}

// A set whose coordinates are hard to write: binary fractions that need 17
// digits, a negative zero, tiny and huge magnitudes.
FlowLineSet awkward_set() {
    FlowLineSet set;
    set.width = 640;
    set.height = 360;
    set.description = "awkward \"quoted\" text / with a slash and ünïcödé";
    FlowLine in1{"in-1", {{0.1, 1.0 / 3.0}, {-0.0, 2.0 / 3.0}, {123.456789012345678, 359.99999999999994}}, {}, ""};
    FlowLine in2{"in/2~x", {{std::nextafter(100.0, 200.0), 1e-300}, {600.5, 7e-7}, {639.0, 359.0}}, {}, ""};
    FlowLine out1{"out-1", {{10.0, 20.0}, {30.25, 40.125}}, {}, "in-1"};
    FlowLine out2{"out-2", {}, {}, "in/2~x"};
    out2.keys = {{1, {{1.0, 2.0}, {3.0, 4.0}}}, {7, {{1.5, 2.0 / 7.0}, {-3.0, 4e-5}}}, {40, {{0, 0}, {9, 9}}}};
    set.inputs = {in1, in2};
    set.outputs = {out1, out2};
    return set;
}

bool has_line_with(const std::string& messages, const std::string& a, const std::string& b,
                   const std::string& c = "") {
    std::size_t start = 0;
    while (start < messages.size()) {
        std::size_t end = messages.find('\n', start);
        if (end == std::string::npos) end = messages.size();
        const std::string line = messages.substr(start, end - start);
        if (line.find(a) != std::string::npos && line.find(b) != std::string::npos &&
            line.find(c) != std::string::npos)
            return true;
        start = end + 1;
    }
    return false;
}

// Reads `document` written to a scratch file and returns the messages.
std::string messages_for(const nlohmann::json& document, const std::string& name) {
    const std::string path = scratch_dir("flowlines_" + name) + "/" + name + ".flowlines.json";
    write_text(path, document.dump(2));
    return validation_messages([&] { read_flowline_set(path); });
}

nlohmann::json minimal_document() {
    return nlohmann::json::parse(R"({
      "format": "flowvid.flowlines", "version": "1.0",
      "image": {"width": 64, "height": 48, "pixel_convention": "opencv"},
      "inputs": [{"id": "in-1", "points": [[10, 0], [12, 47]]}],
      "outputs": [{"id": "out-1", "from": "in-1", "points": [[20, 0], [30, 47]]}]
    })");
}

TEST(FlowLinesJson, ExampleLoadsWithoutWarnings) {
    std::vector<Problem> warnings;
    const FlowLineSet set = read_flowline_set(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(set.width, 640);
    EXPECT_EQ(set.height, 360);
    ASSERT_EQ(set.inputs.size(), 7u);
    ASSERT_EQ(set.outputs.size(), 10u);
    EXPECT_EQ(set.inputs[6].id, "in-7");
    EXPECT_EQ(set.inputs[2].points.back(), Eigen::Vector2d(370, 355));
    EXPECT_EQ(set.outputs[6].id, "out-8");
    EXPECT_EQ(set.outputs[6].from, "in-3");
    const FlowLine& gust = set.outputs[9];
    EXPECT_EQ(gust.id, "out-7");
    ASSERT_TRUE(gust.is_time_varying());
    ASSERT_EQ(gust.keys.size(), 3u);
    EXPECT_EQ(gust.keys[1].frame, 25);
    EXPECT_EQ(gust.keys[1].points[3], Eigen::Vector2d(489.125, 158));
}

TEST(FlowLinesJson, ExampleRewritesToTheSameBytes) {
    const std::string original = read_text(example_path());
    const FlowLineSet set = read_flowline_set(example_path());
    EXPECT_EQ(flowline_set_to_text(set), original);
    const std::string path = scratch_dir("flowlines_rewrite") + "/waterfall.flowlines.json";
    write_flowline_set(path, set);
    EXPECT_EQ(read_text(path), original);
}

TEST(FlowLinesJson, WrittenTextIsTheDocumentOfToJson) {
    const FlowLineSet set = awkward_set();
    EXPECT_EQ(nlohmann::json::parse(flowline_set_to_text(set)), flowline_set_to_json(set));
}

TEST(FlowLinesJson, FileRoundTripIsBitExact) {
    const FlowLineSet set = awkward_set();
    const std::string path = scratch_dir("flowlines_roundtrip") + "/awkward.flowlines.json";
    write_flowline_set(path, set);
    const FlowLineSet back = read_flowline_set(path);
    EXPECT_EQ(back.width, set.width);
    EXPECT_EQ(back.height, set.height);
    EXPECT_EQ(back.description, set.description);
    ASSERT_EQ(back.inputs.size(), set.inputs.size());
    ASSERT_EQ(back.outputs.size(), set.outputs.size());
    for (std::size_t i = 0; i < set.inputs.size(); ++i) {
        EXPECT_EQ(back.inputs[i].id, set.inputs[i].id);
        EXPECT_TRUE(same_bits(back.inputs[i].points, set.inputs[i].points)) << set.inputs[i].id;
    }
    for (std::size_t i = 0; i < set.outputs.size(); ++i) {
        EXPECT_EQ(back.outputs[i].from, set.outputs[i].from);
        EXPECT_TRUE(same_bits(back.outputs[i].points, set.outputs[i].points));
        ASSERT_EQ(back.outputs[i].keys.size(), set.outputs[i].keys.size());
        for (std::size_t k = 0; k < set.outputs[i].keys.size(); ++k) {
            EXPECT_EQ(back.outputs[i].keys[k].frame, set.outputs[i].keys[k].frame);
            EXPECT_TRUE(same_bits(back.outputs[i].keys[k].points, set.outputs[i].keys[k].points));
        }
    }
    EXPECT_TRUE(std::signbit(back.inputs[0].points[1].x()));  // -0.0 kept
    // And the file itself is stable: writing what was read gives the same bytes.
    EXPECT_EQ(flowline_set_to_text(back), read_text(path));
}

TEST(FlowLinesHelpers, PointsAtFrameInterpolatesAndClamps) {
    FlowLine line{"out", {}, {}, "in"};
    line.keys = {{10, {{0, 0}, {10, 0}}}, {20, {{10, 20}, {30, 0}}}, {30, {{10, 20}, {30, 40}}}};
    EXPECT_EQ(points_at_frame(line, -5)[1], Eigen::Vector2d(10, 0));    // before the first key
    EXPECT_EQ(points_at_frame(line, 10)[1], Eigen::Vector2d(10, 0));
    EXPECT_EQ(points_at_frame(line, 20)[0], Eigen::Vector2d(10, 20));   // exactly on a key
    EXPECT_EQ(points_at_frame(line, 99)[1], Eigen::Vector2d(30, 40));   // after the last key
    const std::vector<Eigen::Vector2d> quarter = points_at_frame(line, 12.5);
    EXPECT_NEAR(quarter[0].x(), 2.5, 1e-12);
    EXPECT_NEAR(quarter[0].y(), 5.0, 1e-12);
    EXPECT_NEAR(quarter[1].x(), 15.0, 1e-12);
    const std::vector<Eigen::Vector2d> later = points_at_frame(line, 26);
    EXPECT_NEAR(later[1].y(), 24.0, 1e-12);
    EXPECT_NEAR(later[0].x(), 10.0, 1e-12);

    FlowLine fixed{"in", {{1, 2}, {3, 4}}, {}, ""};
    EXPECT_EQ(points_at_frame(fixed, 1234.5), fixed.points);

    FlowLine empty{"bad", {}, {}, ""};
    EXPECT_THROW(points_at_frame(empty, 0), std::invalid_argument);
    EXPECT_THROW(points_at_frame(line, std::nan("")), std::invalid_argument);
    line.keys[2].points.pop_back();
    EXPECT_THROW(points_at_frame(line, 12), std::invalid_argument);
}

TEST(FlowLinesHelpers, ArcLength) {
    const std::vector<Eigen::Vector2d> points = {{0, 0}, {3, 4}, {3, 4}, {3, 10}};
    EXPECT_DOUBLE_EQ(polyline_length(points), 11.0);
    const std::vector<double> s = cumulative_arc_lengths(points);
    ASSERT_EQ(s.size(), 4u);
    EXPECT_DOUBLE_EQ(s[1], 5.0);
    EXPECT_DOUBLE_EQ(s[2], 5.0);
    EXPECT_DOUBLE_EQ(s[3], 11.0);
    EXPECT_EQ(point_at_arc_length(points, -1.0), Eigen::Vector2d(0, 0));
    EXPECT_TRUE(point_at_arc_length(points, 2.5).isApprox(Eigen::Vector2d(1.5, 2.0)));
    EXPECT_TRUE(point_at_arc_length(points, 8.0).isApprox(Eigen::Vector2d(3, 7)));
    EXPECT_EQ(point_at_arc_length(points, 50.0), Eigen::Vector2d(3, 10));
    EXPECT_EQ(polyline_length({{1, 1}}), 0.0);
}

TEST(FlowLinesJson, SummaryCountsLinesAndKeys) {
    const nlohmann::json summary = summarize_flowline_set(read_flowline_set(example_path()));
    EXPECT_EQ(summary["format"], "flowvid.flowlines");
    EXPECT_EQ(summary["input_count"], 7);
    EXPECT_EQ(summary["output_count"], 10);
    EXPECT_EQ(summary["time_varying_outputs"], 1);
    EXPECT_EQ(summary["outputs"][9]["frames"], nlohmann::json({1, 50}));
    // in-7: (600,40) (570,80) (530,120) (500,150): 50 + sqrt(1600 + 1600) + sqrt(900 + 900)
    EXPECT_NEAR(summary["inputs"][6]["length_px"].get<double>(), 50.0 + std::sqrt(3200.0) + std::sqrt(1800.0), 1e-9);
}

TEST(FlowLinesJson, MalformedJsonNamesFileAndPosition) {
    const std::string path = test_data("formats/flowlines/malformed.flowlines.json");
    const std::string messages = validation_messages([&] { read_flowline_set(path); });
    EXPECT_TRUE(has_line_with(messages, path, "line 6, column", "malformed JSON")) << messages;
}

TEST(FlowLinesJson, OtherFormatIsRefused) {
    nlohmann::json document = minimal_document();
    document["format"] = "flowvid.fabric";
    const std::string messages = messages_for(document, "wrong_format");
    EXPECT_TRUE(has_line_with(messages, "wrong_format.flowlines.json", "/format", "flowvid.fabric")) << messages;
}

TEST(FlowLinesJson, MajorVersion2IsRefused) {
    const std::string path = test_data("formats/flowlines/version_2.flowlines.json");
    const std::string messages = validation_messages([&] { read_flowline_set(path); });
    EXPECT_TRUE(has_line_with(messages, path, "/version", "2.0 is not supported")) << messages;
}

TEST(FlowLinesJson, NewerMinorVersionLoadsWithWarnings) {
    const std::string path = test_data("formats/flowlines/version_1_9.flowlines.json");
    std::vector<Problem> warnings;
    const FlowLineSet set = read_flowline_set(path, &warnings);
    EXPECT_EQ(set.inputs[0].points[1], Eigen::Vector2d(12, 47.5));
    std::string text;
    for (const Problem& p : warnings) text += p.to_string() + "\n";
    EXPECT_TRUE(has_line_with(text, path, "/version", "newer")) << text;
    EXPECT_TRUE(has_line_with(text, path, "/inputs/0/width_px", "unknown key")) << text;
    // `flowvid validate` is strict: the unknown key is an error there.
    bool strict_error = false;
    for (const Problem& p : validate_flowline_set_file(path, Strictness::strict))
        strict_error = strict_error || (p.severity == Problem::Severity::error && p.field == "/inputs/0/width_px");
    EXPECT_TRUE(strict_error);
}

TEST(FlowLinesJson, EveryLineProblemIsReportedAtOnce) {
    const std::string path = test_data("formats/flowlines/bad_lines.flowlines.json");
    const std::vector<Problem> problems = validate_flowline_set_file(path, Strictness::lenient);
    std::string errors, warnings;
    for (const Problem& p : problems) (p.severity == Problem::Severity::error ? errors : warnings) += p.to_string() + "\n";
    EXPECT_TRUE(has_line_with(errors, path, "/inputs/0/points/1/0", "null")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/inputs/1/points", "at least 2 points")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/inputs/2/id", "already used by /inputs/0/id")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/inputs/3/points", "zero-length")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/outputs/0/from", "in-9")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/outputs/1/keys/1/frame", "does not come after")) << errors;
    EXPECT_TRUE(has_line_with(errors, path, "/outputs/1/keys/1/points", "same number of points")) << errors;
    EXPECT_TRUE(has_line_with(warnings, path, "/outputs/2/points/1", "far outside")) << warnings;
    // The reader throws with the same errors.
    const std::string messages = validation_messages([&] { read_flowline_set(path); });
    EXPECT_TRUE(has_line_with(messages, path, "/inputs/2/id"));
    EXPECT_TRUE(has_line_with(messages, path, "/outputs/0/from"));
}

TEST(FlowLinesJson, StructuralMistakesNameTheField) {
    struct Case {
        const char* name;
        std::function<void(nlohmann::json&)> mutate;
        const char* field;
        const char* words;
    };
    const std::vector<Case> cases = {
        {"no_image", [](nlohmann::json& d) { d.erase("image"); }, "/image", "missing"},
        {"convention", [](nlohmann::json& d) { d["image"]["pixel_convention"] = "opengl"; }, "/image/pixel_convention",
         "opengl"},
        {"zero_width", [](nlohmann::json& d) { d["image"]["width"] = 0; }, "/image/width", "out of range"},
        {"no_inputs", [](nlohmann::json& d) { d["inputs"] = nlohmann::json::array(); }, "/inputs", "no input"},
        {"input_keys",
         [](nlohmann::json& d) {
             d["inputs"][0].erase("points");
             d["inputs"][0]["keys"] = {{{"frame", 1}, {"points", {{0, 0}, {1, 1}}}}};
         },
         "/inputs/0/keys", "cannot vary"},
        {"input_from", [](nlohmann::json& d) { d["inputs"][0]["from"] = "in-1"; }, "/inputs/0/from", "input line"},
        {"points_and_keys",
         [](nlohmann::json& d) { d["outputs"][0]["keys"] = {{{"frame", 1}, {"points", {{0, 0}, {1, 1}}}}}; },
         "/outputs/0", "both"},
        {"empty_id", [](nlohmann::json& d) { d["outputs"][0]["id"] = ""; }, "/outputs/0/id", "empty id"},
        {"space_id", [](nlohmann::json& d) { d["outputs"][0]["id"] = "out 1"; }, "/outputs/0/id", "spaces"},
        {"no_from", [](nlohmann::json& d) { d["outputs"][0].erase("from"); }, "/outputs/0/from", "in-1"},
        {"from_output", [](nlohmann::json& d) { d["outputs"][0]["from"] = "out-1"; }, "/outputs/0/from",
         "an output line"},
        {"point_of_three", [](nlohmann::json& d) { d["inputs"][0]["points"][1] = {1, 2, 3}; }, "/inputs/0/points/1",
         "[x, y]"},
        {"string_coordinate", [](nlohmann::json& d) { d["inputs"][0]["points"][0][1] = "7"; },
         "/inputs/0/points/0/1", "string"},
        {"key_frame_float",
         [](nlohmann::json& d) {
             d["outputs"][0].erase("points");
             d["outputs"][0]["keys"] = {{{"frame", 1.5}, {"points", {{0, 0}, {1, 1}}}}};
         },
         "/outputs/0/keys/0/frame", "integer"},
        {"empty_keys",
         [](nlohmann::json& d) {
             d["outputs"][0].erase("points");
             d["outputs"][0]["keys"] = nlohmann::json::array();
         },
         "/outputs/0/keys", "no keys"},
    };
    for (const Case& c : cases) {
        nlohmann::json document = minimal_document();
        c.mutate(document);
        const std::string messages = messages_for(document, c.name);
        EXPECT_TRUE(has_line_with(messages, std::string(c.name) + ".flowlines.json", std::string(c.field) + ":", c.words))
            << c.name << ":\n"
            << messages;
    }
}

TEST(FlowLinesJson, WriterRefusesNaNAndKeepsThePreviousFile) {
    const std::string dir = scratch_dir("flowlines_atomic");
    const std::string path = dir + "/set.flowlines.json";
    write_flowline_set(path, awkward_set());
    const std::string before = read_text(path);

    FlowLineSet bad = awkward_set();
    bad.inputs[0].points[1].y() = std::numeric_limits<double>::quiet_NaN();
    const std::string messages = validation_messages([&] { write_flowline_set(path, bad); });
    EXPECT_TRUE(has_line_with(messages, path, "/inputs/0/points/1", "not finite")) << messages;
    EXPECT_EQ(read_text(path), before);

    FlowLineSet duplicate = awkward_set();
    duplicate.outputs[1].id = "in-1";
    EXPECT_TRUE(has_line_with(validation_messages([&] { write_flowline_set(path, duplicate); }), path,
                              "/outputs/1/id", "already used"));
    EXPECT_EQ(read_text(path), before);

    // A write that fails half-way (here: the folder is gone) throws IoError.
    EXPECT_THROW(write_flowline_set(dir + "/missing/set.flowlines.json", awkward_set()), IoError);
    // No temporary files are left beside the kept file.
    std::size_t files = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) files += entry.is_regular_file();
    EXPECT_EQ(files, 1u);
}

TEST(FlowLinesJson, ValidateFileNeverThrows) {
    const std::vector<Problem> missing = validate_flowline_set_file("/nonexistent/x.flowlines.json", Strictness::strict);
    ASSERT_EQ(missing.size(), 1u);
    EXPECT_EQ(missing[0].file, "/nonexistent/x.flowlines.json");
    EXPECT_TRUE(validate_flowline_set_file(example_path(), Strictness::strict).empty());
    // .svg files are checked with the SVG import rules.
    const std::string svg = test_data("formats/flowlines/unsupported.svg");
    const std::vector<Problem> problems = validate_flowline_set_file(svg, Strictness::strict);
    ASSERT_FALSE(problems.empty());
    EXPECT_EQ(problems[0].file, svg);
}


TEST(FlowLinesJson, TimeOffsetsRoundTripAndAreRefusedOnInputs) {
    const std::string dir = scratch_dir("flowlines_time_offset");
    FlowLineSet set = awkward_set();
    set.outputs[0].time_offset_frames = 7;
    write_flowline_set(dir + "/set.flowlines.json", set);
    EXPECT_NE(read_text(dir + "/set.flowlines.json").find("\"time_offset_frames\": 7"), std::string::npos);
    EXPECT_EQ(read_flowline_set(dir + "/set.flowlines.json"), set);
    FlowLineSet bad = awkward_set();
    bad.inputs[0].time_offset_frames = 3;
    const std::string messages = validation_messages([&] { write_flowline_set(dir + "/bad.flowlines.json", bad); });
    EXPECT_TRUE(has_line_with(messages, dir + "/bad.flowlines.json", "/inputs/0/time_offset_frames", "time offset")) << messages;
}

}  // namespace
}  // namespace flowvid::formats
