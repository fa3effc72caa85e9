// Hostile and clumsy input through the CLI, as an attacker or a tired user
// would give it: each case must end with the documented exit code and a
// message naming the file, the field and the fix, within generous time and
// memory limits (a guard against hangs and blow-ups, not a speed test).

#include "cli_fixtures.hpp"
#include "cli_runner.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

using namespace flowvid::testing;
namespace fs = std::filesystem;

namespace {

constexpr int kExitUsage = 2;
constexpr int kExitInvalidInput = 3;
constexpr int kExitInterrupted = 130;
constexpr int kLimitSeconds = 30;
constexpr long kLimitKilobytes = 1L << 20;  // 1 GiB of address space

using flowvid::testing::mentions;
std::string own_dir(const std::string& name) { return scratch_dir(name + "_" + std::to_string(::getpid())); }

struct LimitedRun {
    int exit_code = -1;
    std::string err;
    double seconds = 0.0;
    bool killed = false;  // by the time limit
};

// Runs flowvid under `ulimit -v` and a hard time limit; `interrupt_after_s`
// > 0 sends SIGINT (Ctrl-C) that long after the start.
LimitedRun run_limited(const std::vector<std::string>& arguments, double interrupt_after_s = 0.0,
                       const std::string& environment = {}) {
    static int counter = 0;
    const std::string dir = scratch_dir("hostile_run_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::string command = environment + " " + shell_quote(FLOWVID_CLI_PATH);
    for (const std::string& argument : arguments) command += " " + shell_quote(argument);
    command += " >/dev/null 2>" + shell_quote(dir + "/err") + " </dev/null";
    std::string script = "ulimit -v " + std::to_string(kLimitKilobytes) + "; ";
    if (interrupt_after_s > 0.0)
        script += "(" + command + ") & pid=$!; sleep " + std::to_string(interrupt_after_s) +
                  "; kill -INT $pid 2>/dev/null; wait $pid";
    else
        script += command;
    // The outer timeout kills the whole group when a case hangs.
    const std::string run = "timeout -k 5 " + std::to_string(kLimitSeconds) + " bash -c " + shell_quote(script);
    const auto start = std::chrono::steady_clock::now();
    const int status = std::system(run.c_str());
    LimitedRun result;
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    result.killed = result.exit_code == 124 || result.exit_code == 137;
    result.err = read_text(dir + "/err");
    return result;
}

std::size_t line_count(const std::string& text) { return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')); }

// Every refusal names the file and says how to fix it.
void expect_refused(const LimitedRun& run, const std::string& file, const std::string& says) {
    EXPECT_FALSE(run.killed) << "hit the " << kLimitSeconds << " s limit";
    EXPECT_EQ(run.exit_code, kExitInvalidInput) << run.err;
    EXPECT_TRUE(mentions(run.err, file)) << run.err;
    EXPECT_TRUE(mentions(run.err, says)) << run.err;
    EXPECT_TRUE(mentions(run.err, "(fix: ")) << run.err;
    EXPECT_FALSE(mentions(run.err, "json.exception")) << run.err;
    std::printf("[measured] %s: exit %d in %.2f s\n", says.c_str(), run.exit_code, run.seconds);
}

std::string example_preset_text() { return read_text(source_path("formats/examples/cotton.fabric.json")); }

std::string with_replaced(std::string text, const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    if (at == std::string::npos) ADD_FAILURE() << "no \"" << from << "\" in the example";
    else text.replace(at, from.size(), to);
    return text;
}

// A copy of the tiny cloth capture whose capture.json is changed by `edit`.
std::string edited_capture(const std::string& dir, const std::function<void(nlohmann::json&)>& edit) {
    fs::copy(test_data("formats/capture/tiny-cloth"), dir, fs::copy_options::recursive);
    nlohmann::json document = nlohmann::json::parse(read_text(dir + "/capture.json"));
    edit(document);
    write_text(dir + "/capture.json", document.dump(2));
    return dir;
}

// The example motion .glb with its JSON chunk changed by `edit`.
std::string edited_glb(const std::string& path, const std::function<void(nlohmann::json&)>& edit) {
    const std::string bytes = read_text(source_path("formats/examples/example.motion.glb"));
    auto u32 = [&](std::size_t at) {
        return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at])) |
               static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 1])) << 8 |
               static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 2])) << 16 |
               static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 3])) << 24;
    };
    const std::uint32_t json_length = u32(12);
    nlohmann::json document = nlohmann::json::parse(bytes.substr(20, json_length));
    edit(document);
    std::string json = document.dump();
    while (json.size() % 4) json += ' ';
    const std::string rest = bytes.substr(20 + json_length);
    auto put = [](std::string& out, std::uint32_t v) {
        for (int i = 0; i < 4; ++i) out += static_cast<char>((v >> (8 * i)) & 0xFF);
    };
    std::string out = "glTF";
    put(out, 2);
    put(out, static_cast<std::uint32_t>(12 + 8 + json.size() + rest.size()));
    put(out, static_cast<std::uint32_t>(json.size()));
    out += "JSON";
    out += json + rest;
    std::ofstream(path, std::ios::binary) << out;
    return path;
}

}  // namespace

TEST(CliHostile, DeeplyNestedJsonIsRefusedBeforeParsingInEveryReader) {
    const std::string dir = own_dir("hostile_nesting");
    const std::string deep = std::string(100000, '[') + std::string(100000, ']');
    write_text(dir + "/d.fabric.json", deep);
    expect_refused(run_limited({"validate", dir + "/d.fabric.json"}), "d.fabric.json", "nest deeper than");
    write_text(dir + "/deep.json", deep);
    expect_refused(run_limited({"merge", "--out", dir + "/m.fabric.json", dir + "/deep.json"}), "deep.json",
                   "nest deeper than");
    EXPECT_FALSE(fs::exists(dir + "/m.fabric.json"));
    // An object nested inside a flowvid file just below the limit still parses.
    const std::string nested = with_replaced(example_preset_text(), "\"name\"",
                                             "\"x\": " + std::string(150, '[') + std::string(150, ']') + ", \"name\"");
    write_text(dir + "/ok.fabric.json", nested);
    const LimitedRun ok = run_limited({"validate", dir + "/ok.fabric.json"});
    EXPECT_FALSE(mentions(ok.err, "nest deeper")) << ok.err;
}

TEST(CliHostile, NumbersBeyondDoubleAndNonFiniteLiteralsNameTheirPlace) {
    const std::string dir = own_dir("hostile_numbers");
    const std::string text = example_preset_text();
    write_text(dir + "/big.fabric.json", with_replaced(text, "\"version\"", "\"x\": 1e999, \"version\""));
    expect_refused(run_limited({"validate", dir + "/big.fabric.json"}), "big.fabric.json", "beyond the range of a double");
    write_text(dir + "/nan.fabric.json", with_replaced(text, "\"version\"", "\"x\": NaN, \"version\""));
    expect_refused(run_limited({"validate", dir + "/nan.fabric.json"}), "nan.fabric.json", "JSON has no NaN or Infinity");
    write_text(dir + "/inf.fabric.json", with_replaced(text, "\"version\"", "\"x\": -Infinity, \"version\""));
    expect_refused(run_limited({"validate", dir + "/inf.fabric.json"}), "inf.fabric.json", "JSON has no NaN or Infinity");
}

TEST(CliHostile, SvgEntityExpansionIsBoundedAndManyAttributesStayLinear) {
    const std::string dir = own_dir("hostile_svg");
    // One 100 KB entity used 10 000 times: a 1 GB expansion from a 132 KB file.
    std::string bomb = "<?xml version=\"1.0\"?>\n<!DOCTYPE svg [<!ENTITY big \"" + std::string(100000, 'x') +
                       "\">]>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"64\" height=\"64\"><title>";
    for (int i = 0; i < 10000; ++i) bomb += "&big;";
    bomb += "</title></svg>\n";
    write_text(dir + "/bomb.svg", bomb);
    expect_refused(run_limited({"validate", dir + "/bomb.svg"}), "bomb.svg", "entity references expand to more than");

    // 300 000 distinct attributes on one path (3.5 MB).
    std::string many = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"64\" height=\"64\"><g id=\"input\"><path id=\"in-1\" "
                       "d=\"M 1,1 L 60,60\"";
    for (int i = 0; i < 300000; ++i) many += " a" + std::to_string(i) + "=\"1\"";
    many += "/></g></svg>\n";
    write_text(dir + "/many.svg", many);
    const LimitedRun attributes = run_limited({"validate", dir + "/many.svg"});
    EXPECT_FALSE(attributes.killed);
    EXPECT_TRUE(attributes.exit_code == 0 || attributes.exit_code == kExitInvalidInput) << attributes.err;
    EXPECT_LT(line_count(attributes.err), 200u) << "every attribute listed";
    std::printf("[measured] 300 000 attributes: exit %d in %.2f s\n", attributes.exit_code, attributes.seconds);
}

TEST(CliHostile, ManyFlowLinesValidateInLinearTimeInJsonAndSvg) {
    const std::string dir = own_dir("hostile_lines");
    const int lines = 100000;
    nlohmann::json document = {{"format", "flowvid.flowlines"}, {"version", "1.0"}, {"image", {{"width", 640}, {"height", 480}, {"pixel_convention", "opencv"}}}};
    nlohmann::json inputs = nlohmann::json::array(), outputs = nlohmann::json::array();
    std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"640\" height=\"480\" viewBox=\"0 0 640 480\">\n<g id=\"input\">\n";
    for (int i = 0; i < lines; ++i) {
        const double x = 1.0 + (i % 600);
        inputs.push_back({{"id", "in-" + std::to_string(i)}, {"points", {{x, 10.0}, {x, 400.0}}}});
        svg += "<path id=\"in-" + std::to_string(i) + "\" d=\"M " + std::to_string(x) + ",10 L " + std::to_string(x) + ",400\"/>\n";
    }
    svg += "</g>\n<g id=\"output\">\n";
    for (int i = 0; i < lines; ++i) {
        const double x = 1.0 + (i % 600);
        // Each output names the input furthest from the start of the list.
        const std::string from = "in-" + std::to_string(lines - 1 - i);
        outputs.push_back({{"id", "out-" + std::to_string(i)}, {"from", from}, {"points", {{x, 20.0}, {x, 300.0}}}});
        svg += "<path id=\"out-" + std::to_string(i) + "\" data-from=\"" + from + "\" d=\"M " + std::to_string(x) +
               ",20 L " + std::to_string(x) + ",300\"/>\n";
    }
    svg += "</g>\n</svg>\n";
    document["inputs"] = inputs;
    document["outputs"] = outputs;
    write_text(dir + "/many.flowlines.json", document.dump());
    write_text(dir + "/many.svg", svg);
    for (const std::string name : {"many.flowlines.json", "many.svg"}) {
        const LimitedRun run = run_limited({"validate", dir + "/" + name});
        EXPECT_FALSE(run.killed) << name;
        EXPECT_EQ(run.exit_code, 0) << name << ": " << run.err.substr(0, 2000);
        std::printf("[measured] %s, %d + %d lines: %.2f s\n", name.c_str(), lines, lines, run.seconds);
    }
}

TEST(CliHostile, CaptureRangesAndPathsOutsideTheFolderAreRefused) {
    const std::string dir = own_dir("hostile_capture");
    for (const char* fps : {"1e-300", "0.001", "5000"}) {
        const std::string capture = edited_capture(dir + "/fps-" + std::string(fps), [&](nlohmann::json& c) {
            c["fps"] = std::stod(fps);
        });
        expect_refused(run_limited({"validate", capture}), "capture.json", "/fps");
    }
    const std::string wide = edited_capture(dir + "/wide", [](nlohmann::json& c) { c["swatch"]["width_m"] = 1e308; });
    const LimitedRun wide_run = run_limited({"validate", wide});
    expect_refused(wide_run, "capture.json", "/swatch/width_m");
    EXPECT_LT(line_count(wide_run.err), 20u) << "one problem, not one per triangle";

    const std::string outside = edited_capture(dir + "/outside", [](nlohmann::json& c) { c["background"] = "../../../../../../etc/passwd"; });
    const LimitedRun refused = run_limited({"validate", outside});
    expect_refused(refused, "capture.json", "leads outside the capture folder");
    EXPECT_TRUE(mentions(refused.err, "/background")) << refused.err;
    EXPECT_FALSE(mentions(refused.err, "root:")) << "the file outside was opened and quoted";
    // Trusted on request: the path is then followed (and /etc/passwd is no image).
    const LimitedRun allowed = run_limited({"--allow-outside-paths", "validate", outside});
    EXPECT_FALSE(mentions(allowed.err, "leads outside")) << allowed.err;
    EXPECT_FALSE(mentions(allowed.err, "root:")) << allowed.err;
}

TEST(CliHostile, GlbIndicesAndOffsetsOutsideTheirRangeAreRefusedAsWritten) {
    const std::string dir = own_dir("hostile_glb");
    const std::string negative = edited_glb(dir + "/negative.glb", [](nlohmann::json& d) { d["bufferViews"][0]["byteOffset"] = -384; });
    const LimitedRun offset = run_limited({"validate", negative});
    expect_refused(offset, "negative.glb", "/bufferViews/0/byteOffset");
    EXPECT_TRUE(mentions(offset.err, "-384")) << offset.err;
    const std::string huge = edited_glb(dir + "/huge.glb", [](nlohmann::json& d) {
        d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 1e12;
    });
    const LimitedRun index = run_limited({"validate", huge});
    expect_refused(index, "huge.glb", "/meshes/0/primitives/0/attributes/POSITION");
    EXPECT_TRUE(mentions(index.err, "1000000000000")) << index.err;
    EXPECT_FALSE(mentions(index.err, "-727379968")) << index.err;
}

TEST(CliHostile, MillionsOfProblemsAreCountedNotListed) {
    const std::string dir = own_dir("hostile_problems");
    nlohmann::json shard = nlohmann::json::parse(read_text(source_path("formats/examples/cloth.fit_shard.json")));
    nlohmann::json parameters = nlohmann::json::array();
    for (int i = 0; i < 500000; ++i) parameters.push_back({{"name", "bend_stiffness_N_m"}, {"value", 1e-6}});
    shard["result"]["parameters"] = parameters;
    write_text(dir + "/dup.json", shard.dump());
    const LimitedRun run = run_limited({"validate", dir + "/dup.json"});
    EXPECT_FALSE(run.killed);
    EXPECT_EQ(run.exit_code, kExitInvalidInput) << run.err.substr(0, 2000);
    EXPECT_LT(line_count(run.err), 150u);
    EXPECT_TRUE(mentions(run.err, "more problems are not listed")) << run.err.substr(run.err.size() > 2000 ? run.err.size() - 2000 : 0);
    std::printf("[measured] 500 000 duplicate parameters: %zu lines in %.2f s\n", line_count(run.err), run.seconds);
}

TEST(CliHostile, OutputsThatWouldDestroyInputsAreRefusedAndTheInputsKept) {
    const std::string dir = own_dir("hostile_overwrite");
    const std::string preset = dir + "/p.fabric.json";
    write_text(preset, example_preset_text());
    fs::copy(test_data("formats/capture/tiny-cloth"), dir + "/capture", fs::copy_options::recursive);
    const std::string capture_json = read_text(dir + "/capture/capture.json");

    const CliResult fit = run_flowvid({"fit", "cloth", "--capture", dir + "/capture", "--out", dir + "/capture/capture.json",
                                       "--evaluations", "10"});
    EXPECT_EQ(fit.exit_code, kExitUsage) << fit.err;
    EXPECT_TRUE(mentions(fit.err, "would destroy it")) << fit.err;
    EXPECT_EQ(read_text(dir + "/capture/capture.json"), capture_json);

    const CliResult simulate = run_flowvid({"simulate", "--preset", preset, "--capture", dir + "/capture", "--out", preset});
    EXPECT_EQ(simulate.exit_code, kExitUsage) << simulate.err;
    EXPECT_TRUE(mentions(simulate.err, "--preset")) << simulate.err;
    EXPECT_EQ(read_text(preset), example_preset_text());
    // The same file reached by another spelling.
    const CliResult spelled = run_flowvid({"simulate", "--preset", preset, "--capture", dir + "/capture", "--out",
                                           dir + "/capture/../p.fabric.json"});
    EXPECT_EQ(spelled.exit_code, kExitUsage) << spelled.err;

    const CliResult twice = run_flowvid({"simulate", "--preset", preset, "--capture", dir + "/capture", "--out",
                                         dir + "/x.glb", "--vat", dir + "/x.glb"});
    EXPECT_EQ(twice.exit_code, kExitUsage) << twice.err;
    EXPECT_TRUE(mentions(twice.err, "--out and --vat both name")) << twice.err;
    EXPECT_FALSE(fs::exists(dir + "/x.glb"));
}

TEST(CliHostile, CtrlCStopsAFineMeshSimulationWithinSecondsAndWritesNothing) {
    const std::string dir = own_dir("hostile_interrupt");
    // The 48x48 rk4 example of `flowvid help simulate`: seconds per frame, so
    // only a check inside the equilibrium and the steps stops it promptly.
    const LimitedRun run = run_limited({"simulate", "--preset", source_path("formats/examples/cotton.fabric.json"),
                                        "--capture", source_path("data/demo/cotton-waving"), "--out", dir + "/fine.glb",
                                        "--resolution", "48x48", "--integrator", "rk4"},
                                       2.0);
    EXPECT_EQ(run.exit_code, kExitInterrupted) << run.err;
    EXPECT_LT(run.seconds, 2.0 + 8.0) << "Ctrl-C took effect only after " << run.seconds - 2.0 << " s";
    EXPECT_FALSE(fs::exists(dir + "/fine.glb"));
    std::printf("[measured] simulate 48x48 rk4, SIGINT at 2 s: exit %d after %.2f s\n", run.exit_code, run.seconds);
}

TEST(CliHostile, AnInterruptedVideoLeavesThePreviousFileWhole) {
    const std::string dir = own_dir("hostile_video");
    const std::string capture = tiny_flow_capture(own_dir("hostile_video_clip"));
    const std::string bank = own_dir("hostile_video_bank") + "/clip.bank.exr";
    ASSERT_EQ(run_flowvid({"track", "--capture", capture, "--out", bank}).exit_code, 0);
    const std::string video = dir + "/s.mp4";
    write_text(video, "the previous good video");
    const LimitedRun run = run_limited({"synth", "--bank", bank, "--frames", "1:1000000", "--out", video}, 2.0);
    EXPECT_EQ(run.exit_code, kExitInterrupted) << run.err;
    EXPECT_EQ(read_text(video), "the previous good video");
    for (const fs::directory_entry& entry : fs::directory_iterator(dir))
        EXPECT_EQ(entry.path().filename(), "s.mp4") << "left behind: " << entry.path();
}

TEST(CliHostile, FitClothHonoursSourceDateEpoch) {
    if (!fs::exists(shared_path("captures/cloth-silk-static-1"))) GTEST_SKIP() << "needs ../shared/captures";
    const std::string dir = own_dir("hostile_epoch");
    std::vector<std::string> bytes;
    for (const char* run_name : {"a", "b"}) {
        const std::string out = dir + "/" + run_name + "/silk.fabric.json";
        fs::create_directories(dir + "/" + run_name);
        const LimitedRun run = run_limited({"fit", "cloth", "--capture", shared_path("captures/cloth-silk-static-1"), "--out", out,
                                            "--evaluations", "10", "--resolution", "8x8", "--variability-runs", "0", "--seed", "5"},
                                           0.0, "SOURCE_DATE_EPOCH=1000000000");
        ASSERT_EQ(run.exit_code, 0) << run.err;
        bytes.push_back(read_text(out));
        EXPECT_EQ(nlohmann::json::parse(bytes.back())["provenance"]["created_utc"], "2001-09-09T01:46:40Z");
    }
    EXPECT_EQ(bytes[0], bytes[1]);
}

TEST(CliHostile, ADamagedFrameIsNamedOnceWithOneFixAndNoLibraryChatter) {
    const std::string dir = own_dir("hostile_png");
    auto cut_short = [](const std::string& path) {  // as by an interrupted copy
        const std::string bytes = read_text(path);
        write_text(path, bytes.substr(0, bytes.size() / 2));
    };
    fs::copy(test_data("formats/capture/tiny-cloth"), dir + "/capture", fs::copy_options::recursive);
    cut_short(dir + "/capture/frames/000001.png");
    fs::copy(test_data("formats/capture/tiny-cloth"), dir + "/middle", fs::copy_options::recursive);
    cut_short(dir + "/middle/frames/000002.png");  // validation reads the first and last frame only
    const LimitedRun validated = run_limited({"validate", dir + "/capture"});
    expect_refused(validated, "capture.json", "cut short");
    EXPECT_TRUE(mentions(validated.err, "frames/000001.png")) << validated.err;
    std::istringstream lines(validated.err);
    for (std::string line; std::getline(lines, line);) {
        std::size_t fixes = 0;
        for (std::size_t at = line.find("(fix: "); at != std::string::npos; at = line.find("(fix: ", at + 1)) ++fixes;
        EXPECT_LE(fixes, 1u) << line;
    }
    // Frame 2 is read only by the work itself, which names it and prints no decoder chatter.
    const LimitedRun fit = run_limited({"fit", "cloth", "--capture", dir + "/middle", "--out", dir + "/x.fabric.json",
                                        "--evaluations", "10", "--resolution", "8x8", "--variability-runs", "0"});
    EXPECT_FALSE(mentions(fit.err, "libpng")) << fit.err;
    EXPECT_NE(fit.exit_code, 0);
    EXPECT_TRUE(mentions(fit.err, "frames/000002.png")) << fit.err;
    EXPECT_TRUE(mentions(fit.err, "cut short")) << fit.err;
    EXPECT_FALSE(fs::exists(dir + "/x.fabric.json"));
}
