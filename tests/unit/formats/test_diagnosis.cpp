// flowvid.diagnosis (diagnosis.json): the example reads and writes back to the
// same bytes; every class of bad input is refused naming the file, the field
// and the fix; `flowvid validate`'s entry point recognises it.

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

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

std::string example_path() { return source_path("formats/examples/toss.diagnosis.json"); }
nlohmann::json example() { return nlohmann::json::parse(read_text(example_path())); }

using flowvid::testing::mentions;

std::string write_json(const std::string& dir, const nlohmann::json& document, const std::string& name = "diagnosis.json") {
    const std::string path = dir + "/" + name;
    write_text(path, document.dump(2));
    return path;
}

// The messages of reading `document`, written to a file; expects a refusal.
std::string refusal(const std::string& dir, const nlohmann::json& document) {
    const std::string path = write_json(dir, document);
    return validation_messages([&] { read_diagnosis(path); });
}

}  // namespace

TEST(Diagnosis, ExampleLoadsAndValidates) {
    std::vector<Problem> warnings;
    const Diagnosis d = read_diagnosis(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(d.kind, "rigid");
    ASSERT_EQ(d.trials.size(), 1u);
    EXPECT_TRUE(d.gap.detected);
    EXPECT_EQ(d.gap.held_out_frames, 16);
    ASSERT_TRUE(d.gap.ratio.has_value());
    EXPECT_GT(*d.gap.ratio, d.gap.threshold);
    EXPECT_EQ(d.verdict.status, "named");
    EXPECT_EQ(d.verdict.effects, std::vector<std::string>{"air_drag"});
    ASSERT_TRUE(d.verdict.gap_closed.has_value());
    EXPECT_NEAR(*d.verdict.gap_closed, 1.0, 1e-3);
    EXPECT_GT(d.evaluations, 0);
    EXPECT_TRUE(validate_diagnosis_file(example_path(), Strictness::strict).empty());
}

TEST(Diagnosis, WritingWhatWasReadGivesTheSameBytes) {
    const std::string dir = scratch_dir("diagnosis_round_trip");
    const Diagnosis d = read_diagnosis(example_path());
    write_diagnosis(dir + "/diagnosis.json", d.document);
    EXPECT_EQ(read_text(dir + "/diagnosis.json"), read_text(example_path()));
}

TEST(Diagnosis, MeasuredNumbersMayBeNullButNotMistyped) {
    const std::string dir = scratch_dir("diagnosis_null");
    nlohmann::json document = example();
    // NaN and infinity are written as null (JSON has neither): a reader accepts them there.
    document["gap"]["ratio"] = nullptr;
    document["frames"][0]["driver"] = std::numeric_limits<double>::quiet_NaN();
    document["candidates"][1]["delta_bic"] = std::numeric_limits<double>::infinity();
    write_diagnosis(dir + "/diagnosis.json", document);
    const Diagnosis d = read_diagnosis(dir + "/diagnosis.json");
    EXPECT_FALSE(d.gap.ratio.has_value());
    EXPECT_TRUE(d.document["frames"][0]["driver"].is_null());
    EXPECT_TRUE(d.document["candidates"][1]["delta_bic"].is_null());
}

TEST(Diagnosis, EveryClassOfBadInputNamesFileFieldAndFix) {
    const std::string dir = scratch_dir("diagnosis_bad");
    const std::string path = dir + "/diagnosis.json";
    const auto expect_refused = [&](const nlohmann::json& document, const std::string& field) {
        const std::string messages = refusal(dir, document);
        EXPECT_TRUE(mentions(messages, path + ": " + field + ": ")) << field << "\n" << messages;
        EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    };
    nlohmann::json document = example();
    document["verdict"]["effects"] = "air_drag";  // wrong type
    expect_refused(document, "/verdict/effects");

    document = example();
    document["gap"].erase("detected");  // missing field
    expect_refused(document, "/gap/detected");

    document = example();
    document["candidates"][0]["bootstrap_stability"] = 1.5;  // out of range
    expect_refused(document, "/candidates/0/bootstrap_stability");
    document = example();
    document["frames"][3]["trial"] = 1;  // there is one trial
    expect_refused(document, "/frames/3/trial");

    document = example();
    document["version"] = 2;  // wrong version
    const std::string newer = refusal(dir, document);
    EXPECT_TRUE(mentions(newer, path + ": /version: version 2 is not supported")) << newer;
    EXPECT_TRUE(mentions(newer, "upgrade flowvid")) << newer;
    document["version"] = "1.0";  // the version is an integer
    expect_refused(document, "/version");
    document = example();
    document["format"] = "flowvid.fabric";
    expect_refused(document, "/format");

    // What does not hold together.
    document = example();
    document["verdict"]["status"] = "no_gap";
    expect_refused(document, "/verdict/status");
    document = example();
    document["verdict"]["effects"] = nlohmann::json::array();
    expect_refused(document, "/verdict/effects");
    document = example();
    document["maps"][0]["values"].erase(0);
    expect_refused(document, "/maps/0/values");
    document = example();
    document["verdict"]["status"] = "named?";
    expect_refused(document, "/verdict/status");

    // Every problem at once, not only the first.
    document = example();
    document["kind"] = 3;
    document["seconds"] = -1;
    document["spectrum"]["floor_power"].erase(0);
    const std::string messages = refusal(dir, document);
    for (const char* field : {"/kind", "/seconds", "/spectrum/floor_power"})
        EXPECT_TRUE(mentions(messages, path + ": " + field)) << field << "\n" << messages;

    // Not JSON at all: line and column.
    write_text(path, "{\"format\": \"flowvid.diagnosis\",\n  \"version\": 1,,}");
    EXPECT_TRUE(mentions(validation_messages([&] { read_diagnosis(path); }), path + ": line 2, column")) << path;
    EXPECT_THROW(read_diagnosis(dir + "/missing.json"), IoError);
}

TEST(Diagnosis, UnknownKeysWarnWhenReadAndFailValidation) {
    const std::string dir = scratch_dir("diagnosis_unknown");
    nlohmann::json document = example();
    document["verdict"]["colour"] = "red";
    const std::string path = write_json(dir, document);
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_diagnosis(path, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "/verdict/colour");
    const std::vector<Problem> problems = validate_diagnosis_file(path, Strictness::strict);
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_EQ(problems[0].severity, Problem::Severity::error);
}

TEST(Diagnosis, WriterRefusesAnInvalidDocumentAndLeavesNoFile) {
    const std::string dir = scratch_dir("diagnosis_write_bad");
    nlohmann::json document = example();
    document["gap"]["held_out_frames"] = -3;
    const std::string path = dir + "/diagnosis.json";
    const std::string messages = validation_messages([&] { write_diagnosis(path, document); });
    EXPECT_TRUE(mentions(messages, path + ": /gap/held_out_frames")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(Diagnosis, AnyFileRecognisesItByContentAndByName) {
    const std::string dir = scratch_dir("diagnosis_any_file");
    // Keys are sorted, so "format" comes after the candidates, far beyond the first 4 KiB.
    const std::string renamed = dir + "/case.json";
    write_text(renamed, read_text(example_path()));
    EXPECT_EQ(detect_file_kind(renamed), FileKind::diagnosis);
    EXPECT_TRUE(validate_any_file(renamed).empty());
    EXPECT_EQ(summarize_any_file(renamed)["kind"], "gap diagnosis");
    EXPECT_EQ(summarize_any_file(renamed)["verdict"], "named");
    // A file too broken to declare its format is judged by its name.
    write_text(dir + "/diagnosis.json", "{\"verdict\": 1}");
    const std::vector<Problem> problems = validate_any_file(dir + "/diagnosis.json");
    ASSERT_FALSE(problems.empty());
    EXPECT_EQ(problems[0].file, dir + "/diagnosis.json");
    EXPECT_EQ(problems[0].field, "/format");
}
