// flowvid.swatch_experiment and flowvid.swatch_frames (what `flowvid swatch`
// reads and writes, and the Blender add-on writes and reads): the examples
// read, validate and write back to the same bytes; round trips are equal;
// every bad field is refused naming the file, its JSON pointer and a fix; a
// refused write keeps the previous file.

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/swatch_experiment.hpp"
#include "flowvid/formats/swatch_frames.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::mentions;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string experiment_path() { return source_path("formats/examples/waving.swatch_experiment.json"); }
std::string frames_path() { return source_path("formats/examples/waving.swatch_frames.json"); }
nlohmann::json experiment_json() { return nlohmann::json::parse(read_text(experiment_path())); }
nlohmann::json frames_json() { return nlohmann::json::parse(read_text(frames_path())); }

// Writes `document`, reads it, and expects the file, the pointer `field` and a fix in the messages,
// from the reader and from `flowvid validate`'s validator alike.
template <class Read, class Validate>
void expect_refused(const std::string& path, const nlohmann::json& document, const std::string& field, Read read,
                    Validate validate) {
    write_text(path, document.dump(2));
    const std::string messages = validation_messages([&] { read(path); });
    EXPECT_TRUE(mentions(messages, path + ": " + field + ": ")) << field << "\n" << messages;
    EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    bool named = false;
    for (const Problem& problem : validate(path, Strictness::strict))
        named = named || (problem.field == field && !problem.fix.empty());
    EXPECT_TRUE(named) << "validator did not name " << field;
}

}  // namespace

TEST(SwatchExperimentFormat, ExampleLoadsValidatesAndIsRecognised) {
    std::vector<Problem> warnings;
    const SwatchExperimentFile e = read_swatch_experiment(experiment_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(e.name, "waving");
    EXPECT_EQ(e.frame_count, 6);
    ASSERT_EQ(e.pins.size(), 2u);
    for (const SwatchPinTrajectory& pin : e.pins) EXPECT_EQ(pin.positions_m.size(), 6u);
    EXPECT_FALSE(e.mass_kg.has_value());
    EXPECT_TRUE(validate_swatch_experiment_file(experiment_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(experiment_path()), FileKind::swatch_experiment);
    EXPECT_TRUE(validate_any_file(experiment_path()).empty());
    const nlohmann::json summary = summarize_any_file(experiment_path());
    EXPECT_EQ(summary["kind"], "swatch experiment");
    EXPECT_EQ(summary["frame_count"], 6);
}

TEST(SwatchExperimentFormat, RoundTripsAreEqual) {
    const std::string dir = scratch_dir("swatch_experiment_round_trip");
    const SwatchExperimentFile e = read_swatch_experiment(experiment_path());
    write_swatch_experiment(dir + "/waving.swatch_experiment.json", e);
    EXPECT_EQ(read_text(dir + "/waving.swatch_experiment.json"), read_text(experiment_path()));
    EXPECT_TRUE(read_swatch_experiment(dir + "/waving.swatch_experiment.json") == e);

    // The optional fields and awkward numbers survive too.
    SwatchExperimentFile other = e;
    other.name.clear();
    other.mass_kg = 0.0123456789012345;
    other.fps = 29.97;
    other.pins[1].positions_m[3] = {1.0 / 3.0, -2e-7, 1e5};
    other.pins[0].uv = {0.25, 0.0};
    write_swatch_experiment(dir + "/other.json", other);
    EXPECT_TRUE(read_swatch_experiment(dir + "/other.json") == other);
    EXPECT_FALSE(nlohmann::json::parse(read_text(dir + "/other.json")).contains("name"));
    Diagnostics diagnostics("in memory");
    EXPECT_TRUE(parse_swatch_experiment(swatch_experiment_to_json(other), diagnostics) == other);
    EXPECT_TRUE(diagnostics.problems().empty());
}

TEST(SwatchExperimentFormat, EveryBadFieldIsNamedWithPointerAndFix) {
    const std::string dir = scratch_dir("swatch_experiment_bad");
    const std::string path = dir + "/bad.swatch_experiment.json";
    const auto refused = [&](const nlohmann::json& document, const std::string& field) {
        expect_refused(path, document, field, [](const std::string& p) { read_swatch_experiment(p); },
                       validate_swatch_experiment_file);
    };
    nlohmann::json d = experiment_json();
    d["width_m"] = 0.0;  // not positive
    refused(d, "/width_m");
    d = experiment_json();
    d["height_m"] = -0.2;
    refused(d, "/height_m");
    d = experiment_json();
    d.erase("height_m");  // missing
    refused(d, "/height_m");
    d = experiment_json();
    d["fps"] = "thirty";  // wrong type
    refused(d, "/fps");
    d = experiment_json();
    d["fps"] = nullptr;  // NaN written by a careless writer
    refused(d, "/fps");
    d = experiment_json();
    d["frame_count"] = 0;
    refused(d, "/frame_count");
    d = experiment_json();
    d["frame_count"] = 2.5;
    refused(d, "/frame_count");
    d = experiment_json();
    d["mass_kg"] = 0.0;  // given, so positive
    refused(d, "/mass_kg");
    d = experiment_json();
    d["name"] = 7;
    refused(d, "/name");
    d = experiment_json();
    d["pins"] = nlohmann::json::array();  // nothing holds the swatch
    refused(d, "/pins");
    d = experiment_json();
    d["pins"][1] = "corner";
    refused(d, "/pins/1");
    d = experiment_json();
    d["pins"][0]["uv"] = {0.5, 1.2};  // outside the swatch
    refused(d, "/pins/0/uv/1");
    d = experiment_json();
    d["pins"][0]["uv"] = {0.5};
    refused(d, "/pins/0/uv");
    d = experiment_json();
    d["pins"][1]["positions_m"].erase(5);  // frame_count points each
    refused(d, "/pins/1/positions_m");
    d = experiment_json();
    d["pins"][1].erase("positions_m");
    refused(d, "/pins/1/positions_m");
    d = experiment_json();
    d["pins"][1]["positions_m"][2] = {0.1, 0.0};
    refused(d, "/pins/1/positions_m/2");
    d = experiment_json();
    d["pins"][1]["positions_m"][2][1] = nullptr;  // not finite
    refused(d, "/pins/1/positions_m/2/1");
    d = experiment_json();
    d["pins"][0]["weight"] = 1.0;  // unknown key: an error when validating strictly, a warning when reading
    write_text(path, d.dump(2));
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_swatch_experiment(path, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "/pins/0/weight");
    EXPECT_FALSE(validate_swatch_experiment_file(path, Strictness::strict).empty());
    d = experiment_json();
    d["version"] = "2.0";
    refused(d, "/version");
    d = experiment_json();
    d["format"] = "flowvid.swatch_frames";
    refused(d, "/format");
    d = experiment_json();
    d.erase("format");
    refused(d, "/format");
}

TEST(SwatchExperimentFormat, AFailedWriteKeepsThePreviousFile) {
    const std::string dir = scratch_dir("swatch_experiment_failed_write");
    const std::string path = dir + "/kept.swatch_experiment.json";
    SwatchExperimentFile e = read_swatch_experiment(experiment_path());
    write_swatch_experiment(path, e);
    const std::string before = read_text(path);
    e.pins[1].positions_m[4].z() = std::numeric_limits<double>::quiet_NaN();
    const std::string messages = validation_messages([&] { write_swatch_experiment(path, e); });
    EXPECT_TRUE(mentions(messages, path + ": /pins/1/positions_m/4/2")) << messages;
    EXPECT_EQ(read_text(path), before);
    e = read_swatch_experiment(experiment_path());
    e.pins[0].positions_m.pop_back();
    EXPECT_TRUE(mentions(validation_messages([&] { write_swatch_experiment(path, e); }), "/pins/0/positions_m"));
    EXPECT_EQ(read_text(path), before);
    validation_messages([&] { write_swatch_experiment(dir + "/never.json", e); });
    EXPECT_FALSE(std::filesystem::exists(dir + "/never.json"));  // and no file where there was none
}

TEST(SwatchFramesFormat, ExampleLoadsValidatesAndIsRecognised) {
    std::vector<Problem> warnings;
    const SwatchFramesFile f = read_swatch_frames(frames_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_TRUE(f.ok());
    EXPECT_EQ(f.rows, 6);
    EXPECT_EQ(f.cols, 6);
    ASSERT_EQ(f.frames_m.size(), 6u);
    for (const auto& frame : f.frames_m) EXPECT_EQ(frame.size(), 36u);
    ASSERT_EQ(f.pinned_vertices.size(), 2u);
    // The pins of the example experiment hold the top corners (row 5, columns 0 and 5) where it puts them.
    const SwatchExperimentFile e = read_swatch_experiment(experiment_path());
    EXPECT_EQ(f.pinned_vertices[0], 30);
    EXPECT_EQ(f.pinned_vertices[1], 35);
    for (std::size_t k = 0; k < 6; ++k)
        for (std::size_t p = 0; p < 2; ++p)
            EXPECT_LT((f.frames_m[k][static_cast<std::size_t>(f.pinned_vertices[p])] - e.pins[p].positions_m[k]).norm(), 1e-9);
    EXPECT_TRUE(validate_swatch_frames_file(frames_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(frames_path()), FileKind::swatch_frames);
    EXPECT_TRUE(validate_any_file(frames_path()).empty());
    EXPECT_EQ(summarize_any_file(frames_path())["kind"], "swatch frames");
}

TEST(SwatchFramesFormat, RoundTripsAreEqual) {
    const std::string dir = scratch_dir("swatch_frames_round_trip");
    const SwatchFramesFile f = read_swatch_frames(frames_path());
    write_swatch_frames(dir + "/waving.swatch_frames.json", f);
    EXPECT_EQ(read_text(dir + "/waving.swatch_frames.json"), read_text(frames_path()));
    EXPECT_TRUE(read_swatch_frames(dir + "/waving.swatch_frames.json") == f);

    // A run that blew up keeps its frames so far; a coordinate that was not finite comes back as NaN.
    SwatchFramesFile blown = f;
    blown.status = "blew_up";
    blown.reason = "non-finite state at t = 0.1 s";
    blown.equilibrium_converged = false;
    blown.frames_m.resize(3);
    blown.frames_m[2][7].y() = std::numeric_limits<double>::infinity();
    write_swatch_frames(dir + "/blown.swatch_frames.json", blown);
    const SwatchFramesFile back = read_swatch_frames(dir + "/blown.swatch_frames.json");
    EXPECT_EQ(back.status, "blew_up");
    EXPECT_EQ(back.reason, blown.reason);
    EXPECT_FALSE(back.equilibrium_converged);
    ASSERT_EQ(back.frames_m.size(), 3u);
    EXPECT_TRUE(std::isnan(back.frames_m[2][7].y()));
    SwatchFramesFile finite_back = back;
    finite_back.frames_m[2][7].y() = 0.0;
    blown.frames_m[2][7].y() = 0.0;
    EXPECT_TRUE(finite_back == blown);
    EXPECT_TRUE(validate_swatch_frames_file(dir + "/blown.swatch_frames.json", Strictness::strict).empty());
}

TEST(SwatchFramesFormat, EveryBadFieldIsNamedWithPointerAndFix) {
    const std::string dir = scratch_dir("swatch_frames_bad");
    const std::string path = dir + "/bad.swatch_frames.json";
    const auto refused = [&](const nlohmann::json& document, const std::string& field) {
        expect_refused(path, document, field, [](const std::string& p) { read_swatch_frames(p); },
                       validate_swatch_frames_file);
    };
    nlohmann::json d = frames_json();
    d["status"] = "fine";
    refused(d, "/status");
    d = frames_json();
    d.erase("reason");
    refused(d, "/reason");
    d = frames_json();
    d["equilibrium_converged"] = "yes";
    refused(d, "/equilibrium_converged");
    d = frames_json();
    d["wall_time_s"] = -1.0;
    refused(d, "/wall_time_s");
    d = frames_json();
    d["grid"] = {6};
    refused(d, "/grid");
    d = frames_json();
    d["grid"] = {6, 1};  // at least 2 x 2
    refused(d, "/grid/1");
    d = frames_json();
    d["grid"] = {6, 6.5};
    refused(d, "/grid/1");
    d = frames_json();
    d["pinned_vertices"][1] = 36;  // beyond the 6 x 6 grid
    refused(d, "/pinned_vertices/1");
    d = frames_json();
    d["pinned_vertices"][0] = 2.5;
    refused(d, "/pinned_vertices/0");
    d = frames_json();
    d["grid"] = {6, 1};  // without a valid grid an index is still bounded by the largest grid
    d["pinned_vertices"][0] = 4294967295.0;
    refused(d, "/pinned_vertices/0");
    d = frames_json();
    d["frames"][3].erase(35);  // rows x cols points per frame
    refused(d, "/frames/3");
    d = frames_json();
    d["frames"] = nlohmann::json::array();  // an ok run has frames
    refused(d, "/frames");
    d = frames_json();
    d["frames"][2][10] = {0.0, 1.0};
    refused(d, "/frames/2/10");
    d = frames_json();
    d["frames"][2][10][2] = nullptr;  // NaN in a run that ended ok
    refused(d, "/frames/2/10/2");
    d = frames_json();
    d["frames"][2][10][2] = "deep";
    refused(d, "/frames/2/10/2");
    d = frames_json();
    d["extra"] = 1;
    write_text(path, d.dump());
    EXPECT_FALSE(validate_swatch_frames_file(path, Strictness::strict).empty());
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_swatch_frames(path, &warnings));
    EXPECT_EQ(warnings.size(), 1u);
    d = frames_json();
    d["version"] = "0.9";
    refused(d, "/version");
    d = frames_json();
    d["format"] = "flowvid.swatch_experiment";
    refused(d, "/format");
}

TEST(SwatchFramesFormat, AFailedWriteKeepsThePreviousFile) {
    const std::string dir = scratch_dir("swatch_frames_failed_write");
    const std::string path = dir + "/kept.swatch_frames.json";
    SwatchFramesFile f = read_swatch_frames(frames_path());
    write_swatch_frames(path, f);
    const std::string before = read_text(path);
    f.frames_m[4][9].x() = std::numeric_limits<double>::quiet_NaN();  // an "ok" run must be finite
    const std::string messages = validation_messages([&] { write_swatch_frames(path, f); });
    EXPECT_TRUE(mentions(messages, path + ": /frames/4/9/0")) << messages;
    EXPECT_EQ(read_text(path), before);
    f = read_swatch_frames(frames_path());
    f.pinned_vertices.push_back(1000);
    EXPECT_TRUE(mentions(validation_messages([&] { write_swatch_frames(path, f); }), "/pinned_vertices/2"));
    EXPECT_EQ(read_text(path), before);
}
