// flowvid demo's index.html: every output a stage left is linked, with its
// key figures and a thumbnail, and the page renders in headless Chromium.
// The stages themselves take minutes; here their outputs are stand-ins
// written by the test, so the page is checked against known figures.

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
    write_json(out / "fabric" / "eval.json",
               {{"captures", {{{"windows", {{{"frames", "1-10"}, {"metric_mean", 382.0}, {"metric_floor", 20.9}}}}}}}});
    write_frame(out / "garment" / "frames" / "0001.png");
    std::ofstream(out / "garment" / "garment.mp4") << "stand-in";
    write_json(out / "garment" / "garment.json", {{"video", (out / "garment" / "garment.mp4").string()},
                                                  {"mapping", "formula"},
                                                  {"render_seconds", 40.0},
                                                  {"frames", {(out / "garment" / "frames" / "0001.png").string()}}});
    fs::create_directories(out / "video");
    std::ofstream(out / "video" / "loop.mp4") << "stand-in";
    for (const char* which : {"clip", "synth", "edit"}) write_frame(out / "video" / ("frame50_" + std::string(which) + ".png"));
    write_json(out / "video" / "quality.json",
               {{"methods", {{"ours", {{"seam_max_ratio", 0.954}, {"share_above_clip_p99", 0.0}, {"motion_ratio", 0.973}}},
                             {"loop", {{"seam_max_ratio", 5.52}, {"share_above_clip_p99", 0.02}, {"motion_ratio", 1.0}}}}},
                {"clip_reference", {{"seam_max_ratio", 1.117}, {"smallest_transition_ratio", 0.745}}}});
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
    const std::regex href("(?:href|src)=\"([^\"]+)\"");
    for (auto it = std::sregex_iterator(index.begin(), index.end(), href); it != std::sregex_iterator(); ++it)
        targets.insert((*it)[1].str());
    for (const char* expected : {"fabric/cotton.fabric.json", "garment/garment.mp4", "garment/frames/0001.png", "video/loop.mp4",
                                 "formats/summaries.json", "video/frame50_clip.png", "video/frame50_synth.png",
                                 "video/frame50_edit.png"})
        EXPECT_EQ(targets.count(expected), 1u) << expected << " not linked";
    for (const std::string& target : targets) EXPECT_TRUE(fs::exists(out / target)) << target;
    // Key figures, as the stages reported them.
    for (const char* figure : {"11000", "9030", "1230", "151", "382", "20.9", "0.954", "5.52", "0.973", "1.12", "verdict: named", "43%",
                               "the gap is explained by wind"})
        EXPECT_NE(index.find(figure), std::string::npos) << figure << " missing from index.html";

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
}
