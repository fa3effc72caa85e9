// flowvid demo's index.html: every output a stage left is linked, with its
// key figures and a thumbnail, and the page renders in headless Chromium.
// The stages themselves take minutes; here their outputs are stand-ins
// written by the test, so the page is checked against known figures.

#include "cli_fixtures.hpp"
#include "cli_runner.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

namespace fs = std::filesystem;
using namespace flowvid::testing;

namespace {

void write_json(const fs::path& path, const nlohmann::json& value) {
    fs::create_directories(path.parent_path());
    std::ofstream(path) << value.dump(2);
}

// A frame of one colour the screenshot can look for (BGR).
const cv::Vec3b kThumbnailBgr(40, 160, 230);

void write_frame(const fs::path& path) {
    fs::create_directories(path.parent_path());
    ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(240, 320, CV_8UC3, cv::Scalar(kThumbnailBgr[0], kThumbnailBgr[1], kThumbnailBgr[2]))));
}

}  // namespace

TEST(CliDemo, IndexLinksEveryOutputWithItsFiguresAndRendersInChromium) {
    const fs::path out = scratch_dir("cli_demo_index");
    fs::remove_all(out);
    fs::create_directories(out);
    write_json(out / "fabric" / "fit.json",
               {{"start_error", 11000.0}, {"final_error", 9030.0}, {"final_error_floor", 1234.0}, {"seconds", 151.0}, {"evaluations", 71}});
    fs::copy_file(source_path("formats/examples/cotton.fabric.json"), out / "fabric" / "cotton.fabric.json");
    // A scan comparison (eval cloth's default): its windows read in mm.
    write_json(out / "fabric" / "eval.json",
               {{"compared", "scan"},
                {"captures",
                 {{{"windows",
                    {{{"frames", "1-10"}, {"metric_mean", 384.16}, {"metric_floor", 17.64}, {"metric_rms_mm", 19.6}, {"metric_floor_rms_mm", 4.2}}}}}}}});
    // Real videos, as the product writes them (flowvid synth's .mp4), so the
    // browser can be asked to play them.
    const fs::path bank = out / "tiny.bank.exr";
    ASSERT_EQ(run_flowvid({"--progress", "none", "track", "--capture", tiny_flow_capture((out / "tiny").string()), "--out",
                           bank.string()})
                  .exit_code,
              0);
    fs::create_directories(out / "video");
    const CliResult looped = run_flowvid({"--progress", "none", "synth", "--bank", bank.string(), "--frame-count", "12", "--out",
                                          (out / "video" / "loop.mp4").string()});
    ASSERT_EQ(looped.exit_code, 0) << looped.err;
    write_frame(out / "garment" / "frames" / "0001.png");
    fs::copy_file(out / "video" / "loop.mp4", out / "garment" / "garment.mp4");
    fs::create_directories(out / "video" / "edit");
    fs::copy_file(out / "video" / "loop.mp4", out / "video" / "edit" / "edit.mp4");
    write_json(out / "video" / "edit.json", {{"video", (out / "video" / "edit" / "edit.mp4").string()}, {"lines", 14},
                                             {"flowlines", ""}, {"frames", nlohmann::json::array()}});
    write_json(out / "garment" / "garment.json", {{"video", (out / "garment" / "garment.mp4").string()},
                                                  {"mapping", "formula"},
                                                  {"render_seconds", 40.0},
                                                  {"frames", {(out / "garment" / "frames" / "0001.png").string()}}});
    for (const char* which : {"clip", "synth", "edit"}) write_frame(out / "video" / ("frame50_" + std::string(which) + ".png"));
    write_json(out / "video" / "quality.json",
               {{"methods", {{"ours", {{"seam_max_ratio", 0.954}, {"share_above_clip_p99", 0.0}, {"motion_ratio", 0.973}}},
                             {"loop", {{"seam_max_ratio", 5.52}, {"share_above_clip_p99", 0.02}, {"motion_ratio", 1.0}}}}},
                {"clip_reference", {{"seam_max_ratio", 1.117}, {"smallest_transition_ratio", 0.745}}}});
    // The particle edit beside the footage itself over its region (its reference).
    write_json(out / "video" / "quality_edit.json",
               {{"region", {{"ours", {{"detail", 0.617}, {"patch_fidelity", 3.349}, {"share_above_clip_p99", 0.0}, {"motion", 1.306}}}}},
                {"footage_over_region", {{"detail", 1.444}, {"patch_fidelity", 3.087}}}});
    write_json(out / "diagnosis" / "diagnose.json", {{"verdict", "named"},
                                                     {"message", "the gap is explained by wind"},
                                                     {"held_out_over_floor", 7.5},
                                                     {"gap_closed", 0.43},
                                                     {"seconds", 300.0}});

    const CliResult result = run_flowvid({"--progress", "none", "demo", "--only", "formats", "--out", out.string()});
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const std::string index = read_text((out / "index.html").string());

    // Every link resolves to a file the stages wrote.
    std::set<std::string> targets;
    const std::regex href("(?:href|src|poster)=\"([^\"]+)\"");
    for (auto it = std::sregex_iterator(index.begin(), index.end(), href); it != std::sregex_iterator(); ++it)
        targets.insert((*it)[1].str());
    for (const char* expected : {"fabric/cotton.fabric.json", "garment/garment.mp4", "garment/frames/0001.png", "video/loop.mp4",
                                 "video/edit/edit.mp4",
                                 "formats/summaries.json", "video/frame50_clip.png", "video/frame50_synth.png",
                                 "video/frame50_edit.png"})
        EXPECT_EQ(targets.count(expected), 1u) << expected << " not linked";
    for (const std::string& target : targets) EXPECT_TRUE(fs::exists(out / target)) << target;
    // Key figures, as the stages reported them.
    for (const char* figure : {"11000", "9030", "1230", "151", "19.6", "4.2", "RMS depth error", "0.954", "5.52", "0.973", "1.12", "verdict: named", "43%",
                               "the gap is explained by wind", "3.35", "0.617", "3.09", "1.44"})
        EXPECT_NE(index.find(figure), std::string::npos) << figure << " missing from index.html";
    // Each stage's verdict in one sentence with its units (as a reader sees it: quotes unescaped).
    const std::string text = std::regex_replace(index, std::regex("&#39;"), "'");
    for (const char* sentence :
         {"over frames 1-10 the fitted fabric misses the footage by 4.67 times the predictability floor",
          "is 0.954 times the clip's 95th-percentile change (the clip's own largest: 1.12; naive looping: 5.52): no seam",
          "misses held-out frames by 7.50 times the predictability floor; modelling the named effect closes 43% of that gap",
          "Blender simulated and rendered its 1 frames", "the footage itself over the particle edit's region"})
        EXPECT_NE(text.find(sentence), std::string::npos) << sentence;

    // A person sees it: headless Chromium renders the page, thumbnail included.
    const char* chromium = "/usr/bin/chromium";
    ASSERT_TRUE(fs::exists(chromium)) << "Chromium is missing: scripts/bootstrap.sh installs it";
    const fs::path shot = out / "screenshot.png";
    const std::string command = std::string(chromium) +
                                " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run"
                                " --disable-background-networking --disable-component-update --disable-sync"
                                " --hide-scrollbars --user-data-dir=" + (out / "chromium-profile").string() +
                                " --window-size=1000,1600 --screenshot=" + shot.string() + " file://" +
                                fs::absolute(out / "index.html").string() + " > " + (out / "chromium.log").string() + " 2>&1";
    ASSERT_EQ(std::system(command.c_str()), 0) << read_text((out / "chromium.log").string());
    const cv::Mat image = cv::imread(shot.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty()) << "no screenshot";
    cv::Scalar mean, spread;
    cv::meanStdDev(image, mean, spread);
    int thumbnail_pixels = 0, dark_pixels = 0;
    for (int y = 0; y < image.rows; ++y)
        for (int x = 0; x < image.cols; ++x) {
            const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
            if (cv::norm(cv::Vec3i(p) - cv::Vec3i(kThumbnailBgr)) < 12) ++thumbnail_pixels;
            if (p[0] + p[1] + p[2] < 200) ++dark_pixels;  // text
        }
    std::printf("[ measured ] screenshot %dx%d: grey spread %.1f, thumbnail pixels %d (320x240 = 76800), text pixels %d\n",
                image.cols, image.rows, spread[0], thumbnail_pixels, dark_pixels);
    EXPECT_GT(spread[0], 10.0) << "blank page";
    EXPECT_GT(thumbnail_pixels, 0.9 * 320 * 240) << "the thumbnail did not render";
    EXPECT_GT(dark_pixels, 2000) << "no text rendered";

    // The page's videos play: a copy of the page with a script that waits for
    // each <video> to load its first frame (or fail) and writes readyState and
    // error code into the DOM, which headless Chromium dumps. MPEG-4 part 2,
    // which OpenCV wrote before, ends at readyState 0 with error 4.
    std::string harness = index;
    const std::string script = R"(<script>
(function () {
  const videos = Array.from(document.querySelectorAll('video'));
  const settle = v => v.readyState >= 2 ? Promise.resolve() : new Promise(done => {
    v.addEventListener('loadeddata', done); v.addEventListener('error', done); });
  Promise.all(videos.map(settle)).then(() => document.body.setAttribute('data-video-states',
    videos.map(v => v.getAttribute('src') + '=' + v.readyState + '/' + (v.error ? v.error.code : 0)).join(' ')));
})();
</script>)";
    harness.insert(harness.rfind("</body>"), script);
    std::ofstream(out / "harness.html") << harness;
    const std::string dump = out / "harness.dom";
    const std::string play = std::string(chromium) +
                             " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run"
                             " --disable-background-networking --disable-component-update --disable-sync"
                             " --allow-file-access-from-files --virtual-time-budget=10000 --user-data-dir=" +
                             (out / "chromium-profile").string() + " --dump-dom file://" +
                             fs::absolute(out / "harness.html").string() + " > " + dump + " 2> " +
                             (out / "chromium-play.log").string();
    ASSERT_EQ(std::system(play.c_str()), 0) << read_text((out / "chromium-play.log").string());
    const std::string dom = read_text(dump);
    const std::regex state("([^ \"=]+\\.mp4)=(\\d)/(\\d)");
    int videos = 0;
    for (auto it = std::sregex_iterator(dom.begin(), dom.end(), state); it != std::sregex_iterator(); ++it) {
        ++videos;
        std::printf("[ measured ] %s: readyState %s, error %s\n", (*it)[1].str().c_str(), (*it)[2].str().c_str(),
                    (*it)[3].str().c_str());
        EXPECT_GE(std::stoi((*it)[2].str()), 2) << (*it)[1] << " does not play in Chromium";
        EXPECT_EQ((*it)[3].str(), "0") << (*it)[1];
    }
    EXPECT_EQ(videos, 3) << "garment, loop and edit videos in the page; the DOM: " << dom.substr(0, 400);
}

// The loop's verdict against the clip's own largest change: below it, equal
// to it within rounding (a loop that replays the clip's background measures
// the clip's own largest change again: 1.091076 against 1.091063 on the
// demo's waterfall), and clearly above it.
TEST(CliDemo, ALoopAsLargeAsTheClipsOwnLargestChangeIsNotCalledASeam) {
    struct Case {
        double ours;
        const char* ending;
        const char* box;
    };
    for (const Case& c : {Case{1.05, ": no seam stands out from the footage's own changes.", "verdict good"},
                          Case{1.091076, ": as large as the footage's own largest change (within 0.5 %), so no seam",
                               "verdict good"},
                          Case{1.2, ": its worst seam changes more than the footage ever does.", "verdict warn"}}) {
        const fs::path out = scratch_dir("cli_demo_loop_verdict");
        write_json(out / "video" / "quality.json",
                   {{"methods", {{"ours", {{"seam_max_ratio", c.ours}}}, {"loop", {{"seam_max_ratio", 3.78}}}}},
                    {"clip_reference", {{"seam_max_ratio", 1.0910634777161416}}}});
        const CliResult result = run_flowvid({"--progress", "none", "demo", "--only", "formats", "--out", out.string()});
        ASSERT_EQ(result.exit_code, 0) << result.err;
        const std::string index = std::regex_replace(read_text((out / "index.html").string()), std::regex("&#39;"), "'");
        const std::size_t sentence = index.find("The loop's largest frame-to-frame change is");
        ASSERT_NE(sentence, std::string::npos);
        EXPECT_NE(index.find(c.ending, sentence), std::string::npos) << c.ours << ": " << index.substr(sentence, 300);
        // The sentence sits in the box its verdict names.
        EXPECT_NE(index.rfind(c.box, sentence), std::string::npos) << c.ours;
        EXPECT_EQ(index.rfind("<div class=\"verdict", sentence), index.rfind(std::string("<div class=\"") + c.box, sentence))
            << c.ours;
    }
}
