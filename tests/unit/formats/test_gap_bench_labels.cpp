// flowvid.gap_bench_labels (a bench folder's labels.json): the example reads
// and writes back to the same bytes; every class of bad input is refused
// naming the file, the field and the fix; the writer refuses a NaN.

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/gap_bench_labels.hpp"
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

std::string example_path() { return source_path("formats/examples/gapbench.labels.json"); }
nlohmann::json example() { return nlohmann::json::parse(read_text(example_path())); }

using flowvid::testing::mentions;

}  // namespace

TEST(GapBenchLabels, ExampleLoadsAndValidates) {
    std::vector<Problem> warnings;
    const GapBenchLabels labels = read_gap_bench_labels(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(labels.seed, 5u);
    EXPECT_EQ(labels.footage_mesh, "24x24");
    EXPECT_EQ(labels.frames, 30);
    ASSERT_EQ(labels.cases.size(), 3u);
    const GapBenchLabel& cloth = labels.cases[0];
    EXPECT_EQ(cloth.id, "case-001");
    EXPECT_EQ(cloth.kind, "cloth");
    EXPECT_EQ(cloth.effect, "pin_lag");
    ASSERT_EQ(cloth.values.count("lag_s"), 1u);
    EXPECT_EQ(cloth.weakened, 0);
    ASSERT_TRUE(cloth.fabric.has_value());
    const GapBenchLabel& rigid = labels.cases[1];
    EXPECT_EQ(rigid.kind, "rigid");
    EXPECT_FALSE(rigid.fabric.has_value());
    EXPECT_FALSE(rigid.weakened.has_value());
    EXPECT_EQ(rigid.values.size(), 2u);
    EXPECT_TRUE(labels.cases[2].values.empty());
    EXPECT_TRUE(validate_gap_bench_labels_file(example_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(example_path()), FileKind::gap_bench_labels);
    EXPECT_EQ(summarize_any_file(example_path())["cases"], 3);
}

TEST(GapBenchLabels, RoundTripIsBitExact) {
    const std::string dir = scratch_dir("gap_labels_round_trip");
    const GapBenchLabels labels = read_gap_bench_labels(example_path());
    write_gap_bench_labels(dir + "/labels.json", labels);
    EXPECT_EQ(read_text(dir + "/labels.json"), read_text(example_path()));
    EXPECT_TRUE(read_gap_bench_labels(dir + "/labels.json") == labels);
    // A 64-bit seed survives.
    GapBenchLabels big = labels;
    big.seed = std::numeric_limits<std::uint64_t>::max();
    write_gap_bench_labels(dir + "/big.json", big);
    EXPECT_EQ(read_gap_bench_labels(dir + "/big.json").seed, std::numeric_limits<std::uint64_t>::max());
}

TEST(GapBenchLabels, EveryClassOfBadInputNamesFileFieldAndFix) {
    const std::string dir = scratch_dir("gap_labels_bad");
    const std::string path = dir + "/labels.json";
    const auto expect_refused = [&](const nlohmann::json& document, const std::string& field) {
        write_text(path, document.dump(2));
        const std::string messages = validation_messages([&] { read_gap_bench_labels(path); });
        EXPECT_TRUE(mentions(messages, path + ": " + field + ": ")) << field << "\n" << messages;
        EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    };
    nlohmann::json document = example();
    document["seed"] = "five";  // wrong type
    expect_refused(document, "/seed");
    document = example();
    document["cases"][1]["values"]["quadratic_per_m"] = "strong";
    expect_refused(document, "/cases/1/values/quadratic_per_m");

    document = example();
    document["cases"][0].erase("effect_to_noise");  // missing field
    expect_refused(document, "/cases/0/effect_to_noise");
    document = example();
    document["cases"][2].erase("fabric");  // a cloth case records its fabric
    expect_refused(document, "/cases/2/fabric");

    document = example();
    document["cases"][0]["weakened"] = 7;  // out of range
    expect_refused(document, "/cases/0/weakened");
    document = example();
    document["cases"][1]["effect_to_noise"] = -1.0;
    expect_refused(document, "/cases/1/effect_to_noise");
    document = example();
    document["strength"] = 0;
    expect_refused(document, "/strength");

    document = example();
    document["version"] = 2;  // wrong version
    expect_refused(document, "/version");
    document["version"] = "1.0";
    expect_refused(document, "/version");

    // Values that cannot be right.
    document = example();
    document["cases"][2]["case"] = "case-001";
    expect_refused(document, "/cases/2/case");
    document = example();
    document["cases"][0]["case"] = "../elsewhere";
    expect_refused(document, "/cases/0/case");
    document = example();
    document["cases"][2]["values"] = {{"lag_s", 0.1}};
    expect_refused(document, "/cases/2/values");
    document = example();
    document["cases"][0]["kind"] = "fluid";
    expect_refused(document, "/cases/0/kind");
    document = example();
    document["footage_mesh"] = "24 by 24";
    expect_refused(document, "/footage_mesh");
    document = example();
    document["cases"] = nlohmann::json::array();
    expect_refused(document, "/cases");
}

TEST(GapBenchLabels, WriterRefusesANaNAndLeavesNoFile) {
    const std::string dir = scratch_dir("gap_labels_nan");
    GapBenchLabels labels = read_gap_bench_labels(example_path());
    labels.cases[1].effect_to_noise = std::numeric_limits<double>::quiet_NaN();
    const std::string path = dir + "/labels.json";
    const std::string messages = validation_messages([&] { write_gap_bench_labels(path, labels); });
    EXPECT_TRUE(mentions(messages, path + ": /cases/1/effect_to_noise")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
}
