// flowvid bench gap and flowvid diagnose as a user runs them: sealed cases
// carry no label, are valid captures and are the same bytes for the same
// seed; the rigid cases are diagnosed and scored against their hidden labels.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>

using namespace flowvid::testing;
namespace fs = std::filesystem;

namespace {

bool have_shared() { return fs::exists(shared_path("captures/rigid-toss-major/capture.json")); }

std::string read(const fs::path& p) { return flowvid::formats::read_text_file(p.string()); }

}  // namespace

TEST(CliGap, ClothCasesAreSealedValidAndDeterministic) {
    if (!have_shared()) GTEST_SKIP() << "needs ../shared/captures";
    const std::string a = scratch_dir("cli_gap_cloth_a"), b = scratch_dir("cli_gap_cloth_b");
    for (const std::string& out : {a, b}) {
        const CliResult r = run_flowvid({"--progress", "none", "bench", "gap", "--cases", "2", "--seed", "3", "--frame-count", "6",
                                         "--effects", "pin_lag", "--out", out, "--scene",
                                         shared_path("captures/cloth-cotton-waving-1"), "--fabric",
                                         test_data("cloth/cotton.fabric.json"), "--threads", "2"});
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    const nlohmann::json labels = nlohmann::json::parse(read(fs::path(a) / "labels.json"));
    ASSERT_EQ(labels.at("cases").size(), 2u);
    for (const nlohmann::json& label : labels.at("cases")) {
        const fs::path folder = fs::path(a) / "cases" / label.at("case").get<std::string>();
        // A valid capture with a base preset, and nothing in it names the effect.
        const flowvid::formats::Capture capture = flowvid::formats::read_capture(folder.string());
        EXPECT_EQ(capture.frames.count, 6);
        EXPECT_TRUE(fs::exists(folder / "base.fabric.json"));
        const std::string json = read(folder / "capture.json");
        EXPECT_EQ(json.find(label.at("effect").get<std::string>()), std::string::npos);
        EXPECT_EQ(json.find("lag"), std::string::npos);
        // Same seed, same bytes: capture.json and every frame.
        const fs::path twin = fs::path(b) / "cases" / label.at("case").get<std::string>();
        EXPECT_EQ(json, read(twin / "capture.json"));
        for (int k = 1; k <= 6; ++k) {
            char name[32];
            std::snprintf(name, sizeof name, "frames/%06d.png", k);
            EXPECT_EQ(read(folder / name), read(twin / name)) << name;
        }
    }
    // Each label measures what the diagnoser will face: the effect's size in floor units.
    for (const nlohmann::json& label : labels.at("cases")) EXPECT_GT(label.at("effect_to_noise").get<double>(), 0.0);
}

TEST(CliGap, RigidCasesAreDiagnosedAndScoredAgainstTheirHiddenLabels) {
    if (!have_shared()) GTEST_SKIP() << "needs ../shared/captures";
    const std::string out = scratch_dir("cli_gap_rigid");
    CliResult r = run_flowvid({"--progress", "none", "bench", "gap", "--cases", "2", "--seed", "6", "--effects", "air_drag",
                               "--out", out, "--scene", shared_path("captures/cloth-cotton-waving-1"), "--fabric",
                               test_data("cloth/cotton.fabric.json"), "--rigid-scene",
                               shared_path("captures/rigid-toss-major"), "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_flowvid({"--progress", "none", "bench", "gap", "--diagnose", out, "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // The scorer's numbers are the diagnoses' against the labels, recounted here.
    const nlohmann::json labels = nlohmann::json::parse(read(fs::path(out) / "labels.json"));
    const nlohmann::json score = nlohmann::json::parse(read(fs::path(out) / "score.json"));
    int correct = 0, cases = 0;
    for (const nlohmann::json& label : labels.at("cases")) {
        const fs::path report = fs::path(out) / "results" / label.at("case").get<std::string>();
        ASSERT_TRUE(fs::exists(report / "report.html"));
        const nlohmann::json d = nlohmann::json::parse(read(report / "diagnosis.json"));
        EXPECT_EQ(d.at("kind"), "rigid");
        const auto named = d.at("verdict").at("effects").get<std::vector<std::string>>();
        ++cases;
        correct += !named.empty() && named.front() == label.at("effect") ? 1 : 0;
    }
    EXPECT_EQ(score.at("per_effect").at("air_drag").at("cases").get<int>(), cases);
    EXPECT_EQ(score.at("per_effect").at("air_drag").at("correct").get<int>(), correct);
    // Drag strong enough to see (labels' effect-to-noise >= 4) is a structural
    // gap, and the drag is named: here one case at 49x and one at 141x noise,
    // strong enough to bend the toss's parabola (the fit's start must model it).
    int strong = 0;
    for (const nlohmann::json& label : labels.at("cases")) {
        if (label.at("effect_to_noise").get<double>() < 4.0) continue;
        ++strong;
        const nlohmann::json d = nlohmann::json::parse(
            read(fs::path(out) / "results" / label.at("case").get<std::string>() / "diagnosis.json"));
        EXPECT_TRUE(d.at("gap").at("detected").get<bool>()) << label.dump();
        const auto named = d.at("verdict").at("effects").get<std::vector<std::string>>();
        EXPECT_TRUE(!named.empty() && named.front() == "air_drag") << label.dump() << "\n" << d.at("verdict").dump();
    }
    EXPECT_EQ(strong, 2);
    // The oracle: the true drag in the diagnoser's own model. Where the
    // diagnosis named the drag, its fitted drag closes as much of the gap as
    // the true one does (RK4 at 1/240 s against the footage's 1/960 s: the
    // integrations agree far better than the drag is strong).
    r = run_flowvid({"--progress", "none", "bench", "gap", "--score", out, "--oracle", "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json oracle = nlohmann::json::parse(read(fs::path(out) / "score.json")).at("oracle_gap_closed_strong");
    EXPECT_EQ(static_cast<int>(oracle.size()), strong);
    int compared = 0;
    for (const auto& [id, closed] : oracle.items()) {
        ASSERT_TRUE(closed.is_number()) << id;
        const nlohmann::json d = nlohmann::json::parse(read(fs::path(out) / "results" / id / "diagnosis.json"));
        const nlohmann::json& named_closed = d.at("verdict").at("gap_closed");
        if (!named_closed.is_number()) continue;
        ++compared;
        EXPECT_NEAR(closed.get<double>(), named_closed.get<double>(), 0.05) << id;
    }
    EXPECT_EQ(compared, strong);
}

TEST(CliGap, DiagnoseRefusesACaptureWithoutAPreset) {
    if (!have_shared()) GTEST_SKIP() << "needs ../shared/captures";
    const CliResult r = run_flowvid({"diagnose", "--capture", shared_path("captures/cloth-cotton-waving-1"), "--out",
                                     scratch_dir("cli_gap_refuse")});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("--preset"), std::string::npos) << r.err;
}

// --score reads labels.json and each results/*/diagnosis.json through their
// format readers: a malformed file is invalid input (exit 3) named by file,
// field and fix, before any work; valid files score as before.
namespace {

std::string bench_folder(const std::string& name) {
    const std::string dir = scratch_dir(name);
    fs::create_directories(fs::path(dir) / "results" / "case-002");
    fs::copy_file(source_path("formats/examples/gapbench.labels.json"), fs::path(dir) / "labels.json");
    fs::copy_file(source_path("formats/examples/toss.diagnosis.json"), fs::path(dir) / "results" / "case-002" / "diagnosis.json");
    return dir;
}

void write_json(const fs::path& path, const nlohmann::json& document) { write_text(path.string(), document.dump(2)); }

}  // namespace

TEST(CliGap, ScoreOfValidLabelsAndDiagnoses) {
    const std::string dir = bench_folder("cli_gap_score_valid");
    const CliResult r = run_flowvid({"bench", "gap", "--score", dir});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("top-1 accuracy per effect"), std::string::npos) << r.out;
    const nlohmann::json score = nlohmann::json::parse(read(fs::path(dir) / "score.json"));
    EXPECT_EQ(score.at("cases_scored"), 1);
    EXPECT_EQ(score.at("missing"), 2);
    EXPECT_EQ(score.at("per_effect").at("air_drag").at("correct"), 1);
    EXPECT_NEAR(score.at("median_gap_closed_strong").get<double>(), 1.0, 1e-3);
}

TEST(CliGap, ScoreRefusesAMalformedDiagnosisNamingFileAndField) {
    const std::string dir = bench_folder("cli_gap_score_bad_diagnosis");
    const fs::path path = fs::path(dir) / "results" / "case-002" / "diagnosis.json";
    nlohmann::json d = nlohmann::json::parse(read(path));
    d["verdict"]["effects"] = "air_drag";  // a string where a list belongs
    d["gap"].erase("detected");
    write_json(path, d);
    // A second malformed one: every problem is listed, not only the first file's.
    fs::create_directories(fs::path(dir) / "results" / "case-001");
    const fs::path other = fs::path(dir) / "results" / "case-001" / "diagnosis.json";
    write_text(other.string(), "{\"format\": \"flowvid.diagnosis\", \"version\": 1,");
    const CliResult r = run_flowvid({"bench", "gap", "--score", dir});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(path.string() + ": /verdict/effects: expected an array"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(path.string() + ": /gap/detected: missing"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(other.string() + ": line 1"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("(fix: "), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("json.exception"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(fs::path(dir) / "score.json"));
}

TEST(CliGap, ScoreRefusesMalformedLabelsNamingFileAndField) {
    const std::string dir = bench_folder("cli_gap_score_bad_labels");
    const fs::path path = fs::path(dir) / "labels.json";
    nlohmann::json labels = nlohmann::json::parse(read(path));
    labels["cases"][0]["effect_to_noise"] = "high";
    write_json(path, labels);
    CliResult r = run_flowvid({"bench", "gap", "--score", dir});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(path.string() + ": /cases/0/effect_to_noise"), std::string::npos) << r.err;
    // Well-formed, but not an effect of the catalogue.
    labels = nlohmann::json::parse(read(source_path("formats/examples/gapbench.labels.json")));
    labels["cases"][1]["effect"] = "air_dragg";
    labels["cases"][0]["values"]["lag_ms"] = 3.0;
    write_json(path, labels);
    r = run_flowvid({"bench", "gap", "--score", dir});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(path.string() + ": /cases/1/effect: \"air_dragg\" is not an effect"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(path.string() + ": /cases/0/values/lag_ms: not a parameter of pin_lag"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(fs::path(dir) / "score.json"));
}

TEST(CliGap, ValidateAndInfoKnowTheBenchFiles) {
    const std::string dir = bench_folder("cli_gap_validate");
    const std::string labels = (fs::path(dir) / "labels.json").string();
    const std::string diagnosis = (fs::path(dir) / "results" / "case-002" / "diagnosis.json").string();
    const CliResult valid = run_flowvid({"validate", labels, diagnosis});
    EXPECT_EQ(valid.exit_code, 0) << valid.err;
    EXPECT_NE(valid.out.find(labels + ": valid"), std::string::npos) << valid.out;
    const CliResult info = run_flowvid({"info", "--json", diagnosis});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    const nlohmann::json summary = nlohmann::json::parse(info.out);
    EXPECT_EQ(summary.at("kind"), "gap diagnosis");
    EXPECT_EQ(summary.at("verdict"), "named");
    write_text(diagnosis, "{\"format\": \"flowvid.diagnosis\", \"version\": 7}");
    const CliResult invalid = run_flowvid({"validate", diagnosis});
    EXPECT_EQ(invalid.exit_code, 3);
    EXPECT_NE(invalid.err.find(diagnosis + ": /version"), std::string::npos) << invalid.err;
}
