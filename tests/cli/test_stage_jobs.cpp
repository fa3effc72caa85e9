// Stages side by side: flowvid demo runs its stages as processes, at most
// --jobs at once, each after the stage whose output it uses. Here the jobs
// are shell one-liners that log when they start and end, so the order is
// read from their own clocks, not from a timer in the test.

#include "cli_runner.hpp"
#include "stage_jobs.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>

namespace fs = std::filesystem;
using namespace flowvid::cli;
using namespace flowvid::testing;

namespace {

// A job that writes its start and end times (ns since the epoch) to
// DIR/NAME.times around a sleep, then exits with `exit_code`.
StageJob timed_job(const fs::path& dir, const std::string& name, std::vector<std::string> after = {},
                   int exit_code = 0) {
    const std::string times = (dir / (name + ".times")).string();
    StageJob job;
    job.name = name;
    job.argv = {"/bin/sh", "-c",
                "date +%s%N > " + shell_quote(times) + "; sleep 0.3; echo out-" + name + "; echo err-" + name +
                    " >&2; date +%s%N >> " + shell_quote(times) + "; exit " + std::to_string(exit_code)};
    job.after = std::move(after);
    job.stdout_file = dir / (name + ".txt");
    job.stderr_file = dir / (name + ".log");
    return job;
}

struct Span {
    long long start_ns = 0;
    long long end_ns = 0;
};

Span span_of(const fs::path& dir, const std::string& name) {
    std::ifstream in(dir / (name + ".times"));
    Span s;
    in >> s.start_ns >> s.end_ns;
    return s;
}

}  // namespace

TEST(StageJobs, IndependentJobsOverlapAndAFollowerStartsAfterItsPredecessorEnds) {
    const fs::path dir = scratch_dir("stage_jobs_overlap");
    const std::vector<StageJob> jobs = {timed_job(dir, "fabric"), timed_job(dir, "garment", {"fabric"}),
                                        timed_job(dir, "video")};
    std::vector<std::string> started, ended;
    StageJobEvents events;
    events.started = [&](const StageJob& j) { started.push_back(j.name); };
    events.ended = [&](const StageJob& j, const StageJobEnd&) { ended.push_back(j.name); };
    const std::vector<StageJobEnd> ends = run_stage_jobs(jobs, 2, events);

    ASSERT_EQ(ends.size(), 3u);
    for (const StageJobEnd& end : ends) {
        EXPECT_EQ(end.exit_code, 0);
        EXPECT_GE(end.seconds, 0.29);
    }
    const Span fabric = span_of(dir, "fabric"), garment = span_of(dir, "garment"), video = span_of(dir, "video");
    // The garment waits for the fabric; the video, ready, takes the free slot.
    EXPECT_EQ(started, (std::vector<std::string>{"fabric", "video", "garment"}));
    EXPECT_LT(video.start_ns, fabric.end_ns) << "independent jobs did not run side by side";
    EXPECT_GE(garment.start_ns, fabric.end_ns) << "the garment started before the fabric it uses had ended";
    EXPECT_EQ(ended.size(), 3u);
    // Each job's stdout and stderr went to its own files.
    EXPECT_EQ(read_text((dir / "garment.txt").string()), "out-garment\n");
    EXPECT_EQ(read_text((dir / "garment.log").string()), "err-garment\n");
}

TEST(StageJobs, OneAtATimeRunsThemInListOrderWithoutOverlap) {
    const fs::path dir = scratch_dir("stage_jobs_serial");
    const std::vector<StageJob> jobs = {timed_job(dir, "a"), timed_job(dir, "b"), timed_job(dir, "c")};
    run_stage_jobs(jobs, 1);
    const Span a = span_of(dir, "a"), b = span_of(dir, "b"), c = span_of(dir, "c");
    EXPECT_GE(b.start_ns, a.end_ns);
    EXPECT_GE(c.start_ns, b.end_ns);
}

TEST(StageJobs, AFailedJobReportsItsCodeAndStillLetsItsFollowerRun) {
    const fs::path dir = scratch_dir("stage_jobs_failure");
    StageJob missing = timed_job(dir, "missing");
    missing.argv = {"/nonexistent/flowvid-no-such-program"};
    const std::vector<StageJob> jobs = {timed_job(dir, "fabric", {}, 3), timed_job(dir, "garment", {"fabric"}), missing};
    const std::vector<StageJobEnd> ends = run_stage_jobs(jobs, 2);
    EXPECT_EQ(ends[0].exit_code, 3);
    EXPECT_EQ(ends[1].exit_code, 0);  // the demo's garment falls back to the bundled preset
    EXPECT_EQ(ends[2].exit_code, 127);
    EXPECT_GE(span_of(dir, "garment").start_ns, span_of(dir, "fabric").end_ns);
}

TEST(StageJobs, AnUnknownPredecessorOrACycleIsRefusedBeforeAnythingRuns) {
    const fs::path dir = scratch_dir("stage_jobs_refused");
    const auto message = [&](const std::vector<StageJob>& jobs) {
        try {
            run_stage_jobs(jobs, 2);
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string("(not refused)");
    };
    EXPECT_EQ(message({timed_job(dir, "garment", {"fabrc"})}),
              "job 'garment' waits for 'fabrc', which is not among the jobs");
    EXPECT_TRUE(mentions(message({timed_job(dir, "a", {"b"}), timed_job(dir, "b", {"a"})}), "waits for itself"));
    EXPECT_FALSE(fs::exists(dir / "a.times")) << "a job ran although the order was refused";
}

TEST(StageJobs, AFollowerReturnsWholeLinesOnlyAndEachOnce) {
    const fs::path file = fs::path(scratch_dir("stage_jobs_follow")) / "messages.log";
    FileFollower follower(file);
    EXPECT_TRUE(follower.new_lines().empty()) << "a file not yet written has no lines";
    std::ofstream out(file);
    out << "first\nsec" << std::flush;
    EXPECT_EQ(follower.new_lines(), std::vector<std::string>{"first"});
    out << "ond\n\nthird\n" << std::flush;
    EXPECT_EQ(follower.new_lines(), (std::vector<std::string>{"second", "", "third"}));
    EXPECT_TRUE(follower.new_lines().empty());
}

// The demo's own use: two stages side by side, one of which fails at once
// (its bundled data is missing). Both print their block; the failure is
// named with its messages' file, the index is written, the exit code says so.
TEST(StageJobs, TheDemoRunsItsStagesSideBySideAndNamesTheOneThatFailed) {
    const fs::path root = scratch_dir("stage_jobs_demo");
    const fs::path data = root / "data_without_footage";
    fs::create_directories(data / "formats");
    fs::copy(source_path("formats/examples"), data / "formats" / "examples", fs::copy_options::recursive);
    const fs::path out = root / "out";
    const CliResult result = run_flowvid({"--progress", "none", "demo", "--jobs", "2", "--only", "formats", "--only",
                                          "diagnosis", "--data", data.string(), "--out", out.string()});
    EXPECT_NE(result.exit_code, 0);
    EXPECT_TRUE(mentions(result.out, "== formats: validate")) << result.out;
    EXPECT_TRUE(mentions(result.out, "flow lines JSON -> SVG -> JSON: identical")) << result.out;
    EXPECT_TRUE(mentions(result.out, "formats done in")) << result.out;
    EXPECT_TRUE(mentions(result.out, "== diagnosis: diagnose")) << result.out;
    EXPECT_TRUE(mentions(result.out, "diagnosis FAILED in")) << result.out;
    EXPECT_TRUE(mentions(result.out, (out / "logs" / "diagnosis.log").string())) << result.out;
    // The failing stage's message, marked with its name, as it came.
    EXPECT_TRUE(mentions(result.err, "[diagnosis] ")) << result.err;
    EXPECT_TRUE(mentions(result.err, "cotton-waving-effect: no such file")) << result.err;
    EXPECT_TRUE(fs::exists(out / "index.html"));
    EXPECT_TRUE(fs::exists(out / "formats" / "summaries.json"));
    EXPECT_EQ(read_text((out / "logs" / "formats.txt").string()).find("== formats"), std::string::npos)
        << "a stage in its own process prints its output only; the demo prints the header";
}
