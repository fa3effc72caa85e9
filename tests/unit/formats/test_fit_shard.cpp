// flowvid.fit_shard: the partial result of one farm task of a split fit, and
// the check that a set of them is one complete split.

#include "flowvid/formats/fit_shard.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string example_path() { return source_path("formats/examples/cloth.fit_shard.json"); }

using flowvid::testing::mentions;

FitShard shard(int index, int count, double error, const std::string& sha = std::string(64, 'a')) {
    FitShard s;
    s.kind = "cloth";
    s.software = "flowvid test";
    s.captures = {{"captures/a", sha}};
    s.options = {{"seed", 3}, {"resolution", "8x8"}, {"half-life-frames", 10.0}};
    s.index = index;
    s.count = count;
    s.best = {{"bend_stiffness_N_m", 1.25e-6}, {"shear_stiffness_N_per_m", 40.0}};
    s.best_error = error;
    s.evaluations = 12;
    s.status = "max_evaluations";
    return s;
}

std::string write_json(const std::string& dir, const nlohmann::json& document, const std::string& name) {
    const std::string path = dir + "/" + name;
    write_text(path, document.dump(2));
    return path;
}

}  // namespace

TEST(FitShard, ExampleOfVersion1_0Loads) {
    std::vector<Problem> warnings;
    const FitShard s = read_fit_shard(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(s.kind, "cloth");
    EXPECT_EQ(s.count, 3);
    ASSERT_EQ(s.captures.size(), 1u);
    EXPECT_EQ(s.captures[0].capture_json_sha256.size(), 64u);
    ASSERT_EQ(s.best.size(), 6u);
    EXPECT_EQ(s.best[0].name, "stretch_stiffness_N_per_m");
    EXPECT_TRUE(std::isfinite(s.best_error));
    EXPECT_TRUE(validate_fit_shard_file(example_path(), Strictness::strict).empty());
}

TEST(FitShard, RoundTripIsBitExactAndTheFileIsMachineIndependent) {
    const std::string dir = scratch_dir("fit_shard_round_trip");
    FitShard s = shard(2, 3, 0.0);
    std::mt19937_64 random(7);
    std::uniform_real_distribution<double> exponent(-9.0, 4.0);
    for (FitShardValue& v : s.best) v.value = std::pow(10.0, exponent(random));
    s.best_error = std::pow(10.0, exponent(random));
    s.options["seed"] = std::numeric_limits<std::uint64_t>::max();  // a 64-bit seed survives
    write_fit_shard(dir + "/s.json", s);
    const FitShard back = read_fit_shard(dir + "/s.json");
    EXPECT_TRUE(back == s);
    EXPECT_EQ(fit_shard_fingerprint(back), fit_shard_fingerprint(s));
    // Writing what was read gives the same bytes.
    write_fit_shard(dir + "/again.json", back);
    EXPECT_EQ(read_text(dir + "/s.json"), read_text(dir + "/again.json"));
}

TEST(FitShard, FingerprintChangesWithEveryPartOfTheRequestOnly) {
    const FitShard a = shard(1, 3, 1.0);
    FitShard b = shard(2, 3, 5.0);  // another shard of the same fit
    EXPECT_EQ(fit_shard_fingerprint(a), fit_shard_fingerprint(b));
    b.captures[0].capture_json_sha256 = std::string(64, 'b');
    EXPECT_NE(fit_shard_fingerprint(a), fit_shard_fingerprint(b));
    FitShard c = shard(1, 3, 1.0);
    c.options["resolution"] = "9x9";
    EXPECT_NE(fit_shard_fingerprint(a), fit_shard_fingerprint(c));
    FitShard d = shard(1, 3, 1.0);
    d.software = "flowvid other";
    EXPECT_NE(fit_shard_fingerprint(a), fit_shard_fingerprint(d));
    // The same capture reached by another path (another mount, another working folder).
    FitShard e = shard(3, 3, 1.0);
    e.captures[0].path = "/mnt/farm/captures/a";
    EXPECT_EQ(fit_shard_fingerprint(a), fit_shard_fingerprint(e));
    EXPECT_EQ(fit_shard_fingerprint(a).size(), 64u);
}

TEST(FitShard, ReaderReportsEveryProblemWithFileAndField) {
    const std::string dir = scratch_dir("fit_shard_bad");
    nlohmann::json document = fit_shard_to_json(shard(1, 3, 1.0));
    document["shard"]["index"] = 4;                                  // beyond count
    document["request"]["captures"][0]["capture_json_sha256"] = "XYZ";  // not hex
    document["result"]["parameters"][1]["name"] = "bend_stiffness_N_m";  // twice
    document["result"]["error"] = nullptr;                              // a NaN written by a careless tool
    document["request"]["options"]["nested"] = {{"a", 1}};              // not flat
    const std::string path = write_json(dir, document, "bad.json");
    const std::string messages = validation_messages([&] { read_fit_shard(path); });
    EXPECT_TRUE(mentions(messages, path + ": /shard/index")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /request/captures/0/capture_json_sha256")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /result/parameters/1/name")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /result/error")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /request/options/nested")) << messages;
    EXPECT_EQ(validate_fit_shard_file(path, Strictness::strict).size(), 5u) << messages;
}

TEST(FitShard, AnEditedRequestNoLongerMatchesItsFingerprint) {
    const std::string dir = scratch_dir("fit_shard_edited");
    nlohmann::json document = fit_shard_to_json(shard(1, 3, 1.0));
    document["request"]["options"]["seed"] = 4;
    const std::string path = write_json(dir, document, "edited.json");
    const std::string messages = validation_messages([&] { read_fit_shard(path); });
    EXPECT_TRUE(mentions(messages, path + ": /fingerprint_sha256")) << messages;
}

TEST(FitShard, VersionsAndUnknownKeys) {
    const std::string dir = scratch_dir("fit_shard_versions");
    nlohmann::json newer = fit_shard_to_json(shard(1, 1, 1.0));
    newer["version"] = "1.3";
    newer["added_later"] = true;
    std::vector<Problem> warnings;
    read_fit_shard(write_json(dir, newer, "newer.json"), &warnings);
    EXPECT_EQ(warnings.size(), 2u);  // newer minor, unknown key
    EXPECT_EQ(validate_fit_shard_file(dir + "/newer.json", Strictness::strict).size(), 2u);  // unknown key is an error there
    nlohmann::json major = fit_shard_to_json(shard(1, 1, 1.0));
    major["version"] = "2.0";
    const std::string path = write_json(dir, major, "major.json");
    EXPECT_TRUE(mentions(validation_messages([&] { read_fit_shard(path); }), path + ": /version"));
}

TEST(FitShard, WriterRefusesNonFiniteValuesAndLeavesTheOldFile) {
    const std::string dir = scratch_dir("fit_shard_nan");
    write_fit_shard(dir + "/s.json", shard(1, 1, 1.0));
    const std::string before = read_text(dir + "/s.json");
    FitShard bad = shard(1, 1, 1.0);
    bad.best[1].value = std::numeric_limits<double>::quiet_NaN();
    const std::string messages = validation_messages([&] { write_fit_shard(dir + "/s.json", bad); });
    EXPECT_TRUE(mentions(messages, "/result/parameters/1/value")) << messages;
    EXPECT_EQ(read_text(dir + "/s.json"), before);
}

TEST(FitShard, SetCheckPicksTheLowestErrorAndBreaksTiesByIndex) {
    // Given out of order: the winner does not depend on the order of the files.
    const std::vector<FitShardFile> files = {
        {"c.json", shard(3, 3, 2.0)}, {"a.json", shard(1, 3, 3.0)}, {"b.json", shard(2, 3, 2.0)}};
    EXPECT_EQ(check_fit_shard_set(files), 2u);  // b.json: shard 2 ties shard 3 at 2.0 and has the lower index
    const std::vector<FitShardFile> clear = {{"a.json", shard(1, 2, 0.5)}, {"b.json", shard(2, 2, 2.0)}};
    EXPECT_EQ(check_fit_shard_set(clear), 0u);
}

TEST(FitShard, SetCheckNamesMissingDuplicateAndForeignShards) {
    const std::string missing = validation_messages([] {
        check_fit_shard_set({{"a.json", shard(1, 4, 1.0)}, {"c.json", shard(3, 4, 1.0)}});
    });
    EXPECT_TRUE(mentions(missing, "a.json: /shard/count")) << missing;
    EXPECT_TRUE(mentions(missing, "shard(s) 2, 4 are missing")) << missing;

    const std::string duplicate = validation_messages([] {
        check_fit_shard_set({{"a.json", shard(1, 2, 1.0)}, {"b.json", shard(2, 2, 1.0)}, {"a2.json", shard(1, 2, 1.0)}});
    });
    EXPECT_TRUE(mentions(duplicate, "a2.json: /shard/index")) << duplicate;
    EXPECT_TRUE(mentions(duplicate, "also a.json")) << duplicate;

    const std::string foreign = validation_messages([] {
        check_fit_shard_set({{"a.json", shard(1, 2, 1.0)}, {"x.json", shard(2, 2, 1.0, std::string(64, 'f'))}});
    });
    EXPECT_TRUE(mentions(foreign, "x.json: /request/captures/0/capture_json_sha256")) << foreign;
    EXPECT_TRUE(mentions(foreign, "shard(s) 2 are missing")) << foreign;

    const std::string split = validation_messages([] {
        check_fit_shard_set({{"a.json", shard(1, 2, 1.0)}, {"b.json", shard(2, 3, 1.0)}});
    });
    EXPECT_TRUE(mentions(split, "b.json: /shard/count")) << split;
}
