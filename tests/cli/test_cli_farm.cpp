// Long work split into independent farm or cluster tasks (docs/farm.md), run
// here as separate processes the way an array job runs them: a cloth fit in
// three shards plus `flowvid merge` against the same fit on one machine
// (`--shards 3`), the merge's refusals, and synthesis in frame chunks against
// one whole render. Kept small: a static drape on an 8x8 mesh, a few
// evaluations, a 15-frame render of a tiny procedural clip.

#include "cli_fixtures.hpp"
#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/flow/frames.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fit_shard.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <unistd.h>

using namespace flowvid::testing;
namespace fs = std::filesystem;

namespace {

using flowvid::testing::mentions;

// ctest runs the tests of this file as parallel processes: one folder each.
std::string own_dir(const std::string& name) { return scratch_dir(name + "_" + std::to_string(::getpid())); }

std::string file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

const std::string kSilkStatic = "captures/cloth-silk-static-1";
const std::string kCottonStatic = "captures/cloth-cotton-static-1";

// The fit every farm test splits: as cheap as a fit gets (static drape, 6
// parameters with the angle maps, a design of 7 points, 8x8 mesh).
std::vector<std::string> fit_arguments(const std::string& out) {
    return {"fit", "cloth", "--capture", shared_path(kSilkStatic), "--out", out, "--evaluations", "16", "--resolution",
            "8x8", "--seed", "5", "--fit-to", "footage", "--json"};
}

std::vector<std::string> with(std::vector<std::string> arguments, std::initializer_list<std::string> more) {
    arguments.insert(arguments.end(), more);
    return arguments;
}

// A shard file written directly (for the merge's refusals, which come before
// any simulation): shard `index` of `count` of a fit on `capture`.
std::string made_shard(const std::string& path, const std::string& capture, int index, int count, double error) {
    flowvid::formats::FitShard shard;
    shard.kind = "cloth";
    shard.software = "flowvid test";
    const flowvid::formats::Capture c = flowvid::formats::read_capture(shared_path(capture));
    shard.captures.push_back({shared_path(capture), c.capture_json_sha256});
    shard.options = {{"resolution", "8x8"}, {"seed", 5}};
    shard.index = index;
    shard.count = count;
    shard.best = {{"bend_stiffness_N_m", 1e-6}, {"shear_stiffness_N_per_m", 2.0}};
    shard.best_error = error;
    shard.evaluations = 9;
    shard.status = "max_evaluations";
    flowvid::formats::write_fit_shard(path, shard);
    return path;
}

}  // namespace

TEST(CliFarm, HelpExplainsShardsAndMerge) {
    const CliResult merge = run_flowvid({"help", "merge"});
    EXPECT_EQ(merge.exit_code, 0);
    EXPECT_TRUE(mentions(merge.out, "Examples")) << merge.out;
    EXPECT_TRUE(mentions(merge.out, "--out")) << merge.out;
    EXPECT_TRUE(mentions(merge.out, "docs/farm.md")) << merge.out;
    const CliResult fit = run_flowvid({"fit", "cloth", "--help"});
    EXPECT_EQ(fit.exit_code, 0);
    EXPECT_TRUE(mentions(fit.out, "--shard ")) << fit.out;
    EXPECT_TRUE(mentions(fit.out, "--shards")) << fit.out;
    EXPECT_TRUE(mentions(fit.out, "Deterministic only without --budget-seconds")) << fit.out;
}

TEST(CliFarm, ThreeShardProcessesAndMergeEqualOneMachineBitForBit) {
    const std::string dir = own_dir("cli_farm_fit");
    // Both presets get this creation time (the reproducible-builds convention).
    ::setenv("SOURCE_DATE_EPOCH", "1795000000", 1);

    // Three tasks, as an array job runs them (here one after the other).
    nlohmann::json shard_summaries = nlohmann::json::array();
    for (int i = 1; i <= 3; ++i) {
        const std::string out = dir + "/shards/" + std::to_string(i) + ".json";
        const CliResult r = run_flowvid(with(fit_arguments(out), {"--shard", std::to_string(i) + "/3", "--threads", "1"}));
        ASSERT_EQ(r.exit_code, 0) << "shard " << i << ": " << r.err;
        shard_summaries.push_back(nlohmann::json::parse(r.out));
    }
    // The shards share one design of max(16 / 4, 6 + 1) = 7 points, every-third-point each.
    EXPECT_EQ(shard_summaries[0]["design_points"], 3);
    EXPECT_EQ(shard_summaries[1]["design_points"], 2);
    EXPECT_EQ(shard_summaries[2]["design_points"], 2);
    EXPECT_EQ(shard_summaries[0]["fingerprint_sha256"], shard_summaries[2]["fingerprint_sha256"]);

    // The merge, given the files in any order.
    const CliResult merged = run_flowvid({"merge", "--out", dir + "/split/silk.fabric.json", dir + "/shards/3.json",
                                          dir + "/shards/1.json", dir + "/shards/2.json", "--json"});
    ASSERT_EQ(merged.exit_code, 0) << merged.err;
    // One machine, the shards in one process (two threads: the result must not depend on it).
    const CliResult whole = run_flowvid(with(fit_arguments(dir + "/one/silk.fabric.json"), {"--shards", "3", "--threads", "2"}));
    ASSERT_EQ(whole.exit_code, 0) << whole.err;
    // The same with variability restarts around the winner (the preset's uncertainty).
    const CliResult merged_restarts =
        run_flowvid({"merge", "--out", dir + "/split/restarts.fabric.json", "--variability-runs", "2", "--variability-evaluations",
                     "4", dir + "/shards/1.json", dir + "/shards/2.json", dir + "/shards/3.json", "--name", "silk"});
    ASSERT_EQ(merged_restarts.exit_code, 0) << merged_restarts.err;
    const CliResult whole_restarts = run_flowvid(with(fit_arguments(dir + "/one/restarts.fabric.json"),
                                                      {"--shards", "3", "--variability-runs", "2", "--variability-evaluations",
                                                       "4", "--name", "silk"}));
    ASSERT_EQ(whole_restarts.exit_code, 0) << whole_restarts.err;
    ::unsetenv("SOURCE_DATE_EPOCH");
    EXPECT_EQ(file_bytes(dir + "/split/restarts.fabric.json"), file_bytes(dir + "/one/restarts.fabric.json"));
    EXPECT_TRUE(flowvid::formats::read_fabric_preset(dir + "/split/restarts.fabric.json")
                    .parameters.bend_stiffness_N_m.uncertainty.has_value());

    const std::string split_bytes = file_bytes(dir + "/split/silk.fabric.json");
    ASSERT_FALSE(split_bytes.empty());
    EXPECT_EQ(split_bytes, file_bytes(dir + "/one/silk.fabric.json")) << "a split fit must equal the one-machine fit";

    // The winner is the shard with the lowest error, and the preset is that
    // point simulated again: its final error is the shard's error.
    int winner = 0;
    for (int i = 1; i < 3; ++i)
        if (shard_summaries[i]["best_error"].get<double>() < shard_summaries[winner]["best_error"].get<double>()) winner = i;
    const nlohmann::json summary = nlohmann::json::parse(merged.out);
    EXPECT_EQ(summary["winner"]["shard"], std::to_string(winner + 1) + "/3");
    const flowvid::formats::FabricPreset preset = flowvid::formats::read_fabric_preset(dir + "/split/silk.fabric.json");
    ASSERT_EQ(preset.provenance.final_errors.size(), 1u);
    const double winner_error = shard_summaries[winner]["best_error"].get<double>();
    std::printf("[measured] shard errors %.6g %.6g %.6g, preset final error %.6g\n",
                shard_summaries[0]["best_error"].get<double>(), shard_summaries[1]["best_error"].get<double>(),
                shard_summaries[2]["best_error"].get<double>(), preset.provenance.final_errors[0].error);
    EXPECT_NEAR(preset.provenance.final_errors[0].error, winner_error, 1e-12 * winner_error);
    const flowvid::formats::FitShard best = flowvid::formats::read_fit_shard(dir + "/shards/" + std::to_string(winner + 1) + ".json");
    bool bend_found = false;
    for (const flowvid::formats::FitShardValue& v : best.best)
        if (v.name == "bend_stiffness_N_m") {
            bend_found = true;
            EXPECT_NEAR(preset.parameters.bend_stiffness_N_m.value, v.value, 1e-12 * v.value);
        }
    EXPECT_TRUE(bend_found) << "a static fit searches the bending stiffness";
    EXPECT_EQ(preset.provenance.created_utc, "2026-11-18T11:06:40Z");
    EXPECT_EQ(run_flowvid({"validate", dir + "/split/silk.fabric.json"}).exit_code, 0);
}

TEST(CliFarm, MergeRefusesMissingDuplicateAndForeignShardsNamingFileAndField) {
    const std::string dir = own_dir("cli_farm_merge");
    const std::string one = made_shard(dir + "/1.json", kSilkStatic, 1, 3, 5.0);
    const std::string two = made_shard(dir + "/2.json", kSilkStatic, 2, 3, 4.0);
    const std::string three = made_shard(dir + "/3.json", kSilkStatic, 3, 3, 6.0);
    const std::string again = made_shard(dir + "/1-again.json", kSilkStatic, 1, 3, 5.0);
    const std::string foreign = made_shard(dir + "/3-cotton.json", kCottonStatic, 3, 3, 1.0);
    const std::string out = dir + "/out.fabric.json";

    const CliResult missing = run_flowvid({"merge", "--out", out, one, three});
    EXPECT_EQ(missing.exit_code, 3);
    EXPECT_TRUE(mentions(missing.err, one + ": /shard/count")) << missing.err;
    EXPECT_TRUE(mentions(missing.err, "shard(s) 2 are missing")) << missing.err;

    const CliResult duplicate = run_flowvid({"merge", "--out", out, one, two, three, again});
    EXPECT_EQ(duplicate.exit_code, 3);
    EXPECT_TRUE(mentions(duplicate.err, again + ": /shard/index")) << duplicate.err;
    EXPECT_TRUE(mentions(duplicate.err, "also " + one)) << duplicate.err;

    const CliResult other = run_flowvid({"merge", "--out", out, one, two, foreign});
    EXPECT_EQ(other.exit_code, 3);
    EXPECT_TRUE(mentions(other.err, foreign + ": /request/captures/0/capture_json_sha256")) << other.err;
    EXPECT_TRUE(mentions(other.err, "shard(s) 3 are missing")) << other.err;
    EXPECT_FALSE(fs::exists(out)) << "a refused merge writes nothing";

    // A shard edited by hand no longer matches its fingerprint.
    std::string text = read_text(two);
    text.replace(text.find("\"8x8\""), 5, "\"9x9\"");
    write_text(dir + "/2-edited.json", text);
    const CliResult edited = run_flowvid({"merge", "--out", out, one, dir + "/2-edited.json", three});
    EXPECT_EQ(edited.exit_code, 3);
    EXPECT_TRUE(mentions(edited.err, dir + "/2-edited.json: /fingerprint_sha256")) << edited.err;

    const CliResult bad_split = run_flowvid(with(fit_arguments(dir + "/x.json"), {"--shard", "4/3"}));
    EXPECT_EQ(bad_split.exit_code, 2);
    EXPECT_TRUE(mentions(bad_split.err, "--shard 4/3")) << bad_split.err;
    const CliResult both = run_flowvid(with(fit_arguments(dir + "/x.json"), {"--shard", "1/3", "--shards", "3"}));
    EXPECT_EQ(both.exit_code, 2);
}


TEST(CliFarm, SynthChunksJoinAWholeRenderBitForBit) {
    const std::string dir = own_dir("cli_farm_synth");
    const std::string capture = tiny_flow_capture(dir + "/clip");
    const std::string bank = dir + "/clip.bank.exr";
    const CliResult tracked = run_flowvid({"track", "--capture", capture, "--out", bank});
    ASSERT_EQ(tracked.exit_code, 0) << tracked.err;

    fs::create_directories(dir + "/whole");
    fs::create_directories(dir + "/chunks");
    const CliResult whole = run_flowvid({"synth", "--bank", bank, "--frames", "1:15", "--out", dir + "/whole/%04d.png"});
    ASSERT_EQ(whole.exit_code, 0) << whole.err;
    // Three farm tasks, each its own frame range, into one folder.
    for (const char* range : {"1:5", "6:10", "11:15"}) {
        const CliResult chunk = run_flowvid({"synth", "--bank", bank, "--frames", range, "--out", dir + "/chunks/%04d.png"});
        ASSERT_EQ(chunk.exit_code, 0) << range << ": " << chunk.err;
    }
    EXPECT_NE(file_bytes(dir + "/whole/0001.png"), file_bytes(dir + "/whole/0015.png")) << "the texture should flow";
    int files = 0;
    for (const auto& entry : fs::directory_iterator(dir + "/chunks")) files += entry.is_regular_file() ? 1 : 0;
    EXPECT_EQ(files, 15) << "exactly frames 1..15, named by frame number";
    for (int f = 1; f <= 15; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "/%04d.png", f);
        const std::string a = file_bytes(dir + "/whole" + name), b = file_bytes(dir + "/chunks" + name);
        ASSERT_FALSE(a.empty()) << "frame " << f;
        EXPECT_EQ(a, b) << "frame " << f << " differs between the whole render and its chunk";
    }
}
