// The flowvid tool as a user meets it: help, version, exit codes, validate, info.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/formats/fabric_preset.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

using namespace flowvid::testing;

namespace {
using flowvid::testing::mentions;
std::string example_preset() { return source_path("formats/examples/cotton.fabric.json"); }
}  // namespace

TEST(Cli, VersionAndHelp) {
    CliResult version = run_flowvid({"--version"});
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_TRUE(mentions(version.out, "flowvid " FLOWVID_VERSION_STRING)) << version.out;

    CliResult help = run_flowvid({"--help"});
    EXPECT_EQ(help.exit_code, 0);
    for (const char* command : {"validate", "info", "convert", "Exit codes"})
        EXPECT_TRUE(mentions(help.out, command)) << command << "\n" << help.out;

    CliResult help_validate = run_flowvid({"help", "validate"});
    EXPECT_EQ(help_validate.exit_code, 0);
    EXPECT_TRUE(mentions(help_validate.out, "Examples")) << help_validate.out;
}

TEST(Cli, UsageErrorsExitWith2) {
    EXPECT_EQ(run_flowvid({"no-such-command"}).exit_code, 2);
    EXPECT_EQ(run_flowvid({"validate"}).exit_code, 2);  // FILE is required
    EXPECT_EQ(run_flowvid({"help", "no-such-command"}).exit_code, 2);
    EXPECT_EQ(run_flowvid({"--progress", "sideways", "validate", example_preset()}).exit_code, 2);
}

TEST(Cli, ValidateValidAndInvalidFiles) {
    CliResult ok = run_flowvid({"validate", example_preset()});
    EXPECT_EQ(ok.exit_code, 0) << ok.err;
    EXPECT_TRUE(mentions(ok.out, example_preset() + ": valid")) << ok.out;

    const std::string dir = scratch_dir("cli_validate_bad");
    const std::string bad = dir + "/bad.fabric.json";
    nlohmann::json document = nlohmann::json::parse(read_text(example_preset()));
    document["parameters"]["shear_stiffness_N_per_m"]["value"] = -1;
    document["version"] = "1.4";
    write_text(bad, document.dump());
    CliResult invalid = run_flowvid({"validate", example_preset(), bad});
    EXPECT_EQ(invalid.exit_code, 3);
    EXPECT_TRUE(mentions(invalid.out, bad + ": invalid")) << invalid.out;
    EXPECT_TRUE(mentions(invalid.err, bad + ": /parameters/shear_stiffness_N_per_m/value")) << invalid.err;
    EXPECT_TRUE(mentions(invalid.err, "warning: " + bad + ": /version")) << invalid.err;

    CliResult missing = run_flowvid({"validate", dir + "/missing.fabric.json"});
    EXPECT_EQ(missing.exit_code, 4);  // an I/O error, as documented, not an invalid file
    EXPECT_TRUE(mentions(missing.err, dir + "/missing.fabric.json")) << missing.err;

    // A JSON file declaring a format flowvid does not read is told which ones it does.
    const std::string misnamed = dir + "/preset.json";
    write_text(misnamed, R"({"format": "flowvid.fabric_preset", "version": 1})");
    for (const char* command : {"validate", "info"}) {
        CliResult r = run_flowvid({command, misnamed});
        EXPECT_EQ(r.exit_code, 3) << command;
        EXPECT_TRUE(mentions(r.err, misnamed + ": /format: \"flowvid.fabric_preset\" is not a format")) << r.err;
        EXPECT_TRUE(mentions(r.err, "flowvid.fabric (fabric presets)")) << r.err;
    }
}

TEST(Cli, InfoForPeopleAndMachines) {
    CliResult human = run_flowvid({"info", example_preset()});
    EXPECT_EQ(human.exit_code, 0) << human.err;
    EXPECT_TRUE(mentions(human.out, "areal_density_kg_per_m2")) << human.out;

    // For machines a preset prints as the preset itself: saved, it validates
    // and reads back as the same preset.
    CliResult machine = run_flowvid({"info", "--json", example_preset()});
    ASSERT_EQ(machine.exit_code, 0) << machine.err;
    const nlohmann::json summary = nlohmann::json::parse(machine.out);
    EXPECT_EQ(summary["format"], "flowvid.fabric");
    EXPECT_DOUBLE_EQ(summary["parameters"]["areal_density_kg_per_m2"]["value"].get<double>(), 0.15);
    const std::string saved = scratch_dir("cli_info_json") + "/from_info.fabric.json";
    write_text(saved, machine.out);
    const CliResult revalidated = run_flowvid({"validate", saved});
    EXPECT_EQ(revalidated.exit_code, 0) << revalidated.err;
    EXPECT_EQ(flowvid::formats::read_fabric_preset(saved), flowvid::formats::read_fabric_preset(example_preset()));
    // Other files print a summary with their kind and path.
    const std::string fit = source_path("formats/examples/toss.rigid_fit.json");
    CliResult fit_info = run_flowvid({"info", "--json", fit});
    ASSERT_EQ(fit_info.exit_code, 0) << fit_info.err;
    EXPECT_EQ(nlohmann::json::parse(fit_info.out)["kind"], "rigid fit");
    EXPECT_EQ(nlohmann::json::parse(fit_info.out)["path"], fit);

    CliResult missing = run_flowvid({"info", "/nonexistent/file.fabric.json"});
    EXPECT_EQ(missing.exit_code, 4) << missing.err;
}

TEST(Cli, ConvertSvgToFlowLinesAndBack) {
    const std::string svg = shared_path("captures/video-waterfall-cascade/flowlines.svg");
    const std::string dir = scratch_dir("cli_convert");
    CliResult to_json = run_flowvid({"convert", svg, dir + "/lines.flowlines.json"});
    if (to_json.exit_code != 0 && !std::ifstream(svg)) GTEST_SKIP() << "../shared is absent";
    ASSERT_EQ(to_json.exit_code, 0) << to_json.err;
    EXPECT_TRUE(mentions(to_json.out, "7 input and 10 output lines")) << to_json.out;
    const nlohmann::json lines = nlohmann::json::parse(read_text(dir + "/lines.flowlines.json"));
    EXPECT_EQ(lines["format"], "flowvid.flowlines");
    // out-8 of the waterfall edit starts at (90, 0) and carries in-3's texture.
    bool found = false;
    for (const auto& line : lines["outputs"])
        if (line["id"] == "out-8") {
            found = true;
            EXPECT_EQ(line["from"], "in-3");
            EXPECT_DOUBLE_EQ(line["points"][0][0].get<double>(), 90.0);
            EXPECT_DOUBLE_EQ(line["points"][0][1].get<double>(), 0.0);
        }
    EXPECT_TRUE(found);

    CliResult to_svg = run_flowvid({"convert", dir + "/lines.flowlines.json", dir + "/again.svg"});
    ASSERT_EQ(to_svg.exit_code, 0) << to_svg.err;
    CliResult back = run_flowvid({"convert", dir + "/again.svg", dir + "/again.flowlines.json"});
    ASSERT_EQ(back.exit_code, 0) << back.err;
    EXPECT_EQ(read_text(dir + "/again.flowlines.json"), read_text(dir + "/lines.flowlines.json"));

    const std::string motion = source_path("formats/examples/example.motion.glb");
    CliResult wrong_kind = run_flowvid({"convert", motion, dir + "/x.svg"});
    EXPECT_EQ(wrong_kind.exit_code, 3);
    EXPECT_TRUE(mentions(wrong_kind.err, motion)) << wrong_kind.err;
    CliResult bad_out = run_flowvid({"convert", svg, dir + "/x.txt"});
    EXPECT_EQ(bad_out.exit_code, 2);
}

// flowvid convert on fabric presets: U3M and OpenUSD out and back to the same
// preset, Blender settings for a mesh, info on the written files, and the
// mistakes a user makes (no --mesh, wrong output type, a broken mesh).
TEST(Cli, ConvertFabricPresetToU3mUsdaBlenderAndBack) {
    const std::string dir = scratch_dir("cli_convert_preset");
    // Written back as the current version: the example's 1.1 parameters and
    // the one 1.2 added at its neutral value.
    nlohmann::json original = nlohmann::json::parse(read_text(example_preset()));
    original["version"] = "1.2";
    original["parameters"]["shear_cell_fraction"] = {{"value", 0.0}};
    for (const char* type : {".u3m", ".usda"}) {
        const std::string converted = dir + "/cotton" + type;
        CliResult to = run_flowvid({"convert", example_preset(), converted});
        ASSERT_EQ(to.exit_code, 0) << to.err;
        EXPECT_TRUE(mentions(to.out, converted)) << to.out;
        const std::string back = dir + "/back" + type + ".fabric.json";
        CliResult from = run_flowvid({"convert", converted, back});
        ASSERT_EQ(from.exit_code, 0) << from.err;
        EXPECT_EQ(nlohmann::json::parse(read_text(back)), original) << type;
        CliResult info = run_flowvid({"info", "--json", converted});
        ASSERT_EQ(info.exit_code, 0) << info.err;
        const nlohmann::json summary = nlohmann::json::parse(info.out);
        EXPECT_DOUBLE_EQ(summary["parameters"]["bend_stiffness_N_m"]["value"].get<double>(), 2e-5) << type;
        EXPECT_EQ(run_flowvid({"validate", converted}).exit_code, 0) << type;
    }

    const std::string mesh = test_data("cloth/panel_9x5.obj");
    CliResult blender = run_flowvid({"convert", example_preset(), dir + "/panel.blender.json", "--mesh", mesh, "--fps", "30"});
    ASSERT_EQ(blender.exit_code, 0) << blender.err;
    const nlohmann::json settings = nlohmann::json::parse(read_text(dir + "/panel.blender.json"));
    EXPECT_EQ(settings["format"], "flowvid.blender_cloth");
    EXPECT_EQ(settings["mesh"]["vertex_count"], 45);
    EXPECT_NEAR(settings["settings"]["time_scale"].get<double>(), std::sqrt(1000.0) / 30.0, 1e-12);
    EXPECT_NEAR(settings["settings"]["mass"].get<double>(), 1000.0 * 0.15 * 0.12 / 45, 1e-12);
    EXPECT_EQ(settings["settings"]["bending_model"], "ANGULAR");
    EXPECT_EQ(settings["settings"]["quality"], 10);
    EXPECT_EQ(settings["scene"]["fps"], 30.0);
    // What convert wrote is a file flowvid validates and describes.
    CliResult valid = run_flowvid({"validate", dir + "/panel.blender.json"});
    EXPECT_EQ(valid.exit_code, 0) << valid.out << valid.err;
    EXPECT_TRUE(mentions(valid.out, "panel.blender.json: valid")) << valid.out;
    CliResult described = run_flowvid({"info", "--json", dir + "/panel.blender.json"});
    ASSERT_EQ(described.exit_code, 0) << described.err;
    const nlohmann::json summary = nlohmann::json::parse(described.out);
    EXPECT_EQ(summary["kind"], "Blender cloth settings");
    EXPECT_EQ(summary["preset"], "cotton (example)");
    EXPECT_EQ(summary["vertex_count"], 45);
    EXPECT_EQ(summary["fps"], 30.0);
    EXPECT_EQ(summary["settings"]["quality"], 10);
    EXPECT_NEAR(summary["settings"]["time_scale"].get<double>(), std::sqrt(1000.0) / 30.0, 1e-12);
    // The bundled example too; a broken copy is refused naming the field.
    const std::string example = source_path("formats/examples/panel.blender.json");
    EXPECT_EQ(run_flowvid({"validate", example}).exit_code, 0);
    CliResult example_info = run_flowvid({"info", "--json", example});
    ASSERT_EQ(example_info.exit_code, 0) << example_info.err;
    EXPECT_EQ(nlohmann::json::parse(example_info.out)["settings"]["bending_model"], "ANGULAR");
    nlohmann::json broken_settings = settings;
    broken_settings["settings"]["mass"] = -0.4;
    broken_settings["scene"].erase("fps");
    write_text(dir + "/broken.blender.json", broken_settings.dump(2));
    CliResult refused = run_flowvid({"validate", dir + "/broken.blender.json"});
    EXPECT_NE(refused.exit_code, 0);
    EXPECT_TRUE(mentions(refused.out + refused.err, "/settings/mass: value -0.4 is out of range")) << refused.out << refused.err;
    EXPECT_TRUE(mentions(refused.out + refused.err, "/scene/fps: missing")) << refused.out << refused.err;

    CliResult no_mesh = run_flowvid({"convert", example_preset(), dir + "/x.blender.json"});
    EXPECT_EQ(no_mesh.exit_code, 2);
    EXPECT_TRUE(mentions(no_mesh.err, "--mesh")) << no_mesh.err;
    CliResult svg = run_flowvid({"convert", example_preset(), dir + "/x.svg"});
    EXPECT_EQ(svg.exit_code, 2);
    EXPECT_TRUE(mentions(svg.err, ".u3m")) << svg.err;
    write_text(dir + "/broken.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
    CliResult broken = run_flowvid({"convert", example_preset(), dir + "/y.blender.json", "--mesh", dir + "/broken.obj"});
    EXPECT_EQ(broken.exit_code, 3);
    EXPECT_TRUE(mentions(broken.err, dir + "/broken.obj")) << broken.err;
    EXPECT_TRUE(mentions(broken.err, "line 3")) << broken.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/y.blender.json"));

    CliResult help = run_flowvid({"convert", "--help"});
    EXPECT_TRUE(mentions(help.out, "flowvid convert cotton.fabric.json cotton.u3m")) << help.out;
    EXPECT_TRUE(mentions(help.out, "--mesh")) << help.out;
}

TEST(Cli, EverySharedCaptureAndExampleValidates) {
    std::vector<std::string> arguments = {"validate"};
    const std::filesystem::path captures = shared_path("captures");
    if (!std::filesystem::is_directory(captures)) GTEST_SKIP() << "../shared is absent";
    int count = 0;
    for (const auto& entry : std::filesystem::directory_iterator(captures))
        if (entry.is_directory()) {
            arguments.push_back(entry.path().string());
            ++count;
        }
    for (const auto& entry : std::filesystem::directory_iterator(source_path("formats/examples")))
        arguments.push_back(entry.path().string());
    EXPECT_GE(count, 13);
    CliResult result = run_flowvid(arguments);
    EXPECT_EQ(result.exit_code, 0) << result.err;
    EXPECT_FALSE(mentions(result.out, "invalid")) << result.out;
}

TEST(Cli, DemoFormatsStage) {
    const std::string dir = scratch_dir("cli_demo");
    CliResult result = run_flowvid({"--progress", "json", "demo", "--only", "formats", "--out", dir});
    EXPECT_EQ(result.exit_code, 0) << result.out << result.err;
    EXPECT_TRUE(mentions(result.out, "JSON -> SVG -> JSON: identical")) << result.out;
    EXPECT_TRUE(mentions(result.err, "{\"event\":\"done\"")) << result.err;
    const nlohmann::json summaries = nlohmann::json::parse(read_text(dir + "/formats/summaries.json"));
    std::size_t examples = 0;
    for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(source_path("formats/examples"))) ++examples;
    EXPECT_EQ(summaries.size(), examples);
    EXPECT_EQ(run_flowvid({"demo", "--only", "nonsense"}).exit_code, 2);
}

namespace {

// The commands `flowvid help WORDS` lists under "Subcommands:", as word lists.
std::vector<std::vector<std::string>> subcommands_of(const std::vector<std::string>& words) {
    std::vector<std::string> args = {"help"};
    args.insert(args.end(), words.begin(), words.end());
    const CliResult help = run_flowvid(args);
    std::vector<std::vector<std::string>> found;
    std::istringstream lines(help.out);
    std::string line;
    bool listing = false;
    while (std::getline(lines, line)) {
        if (line.rfind("Subcommands:", 0) == 0) {
            listing = true;
            continue;
        }
        if (listing && (line.size() < 3 || line[0] != ' ')) break;
        if (!listing) continue;
        std::istringstream fields(line);
        std::string name;
        fields >> name;
        if (name.empty() || name == "help") continue;
        std::vector<std::string> command = words;
        command.push_back(name);
        found.push_back(command);
    }
    return found;
}

std::string joined(const std::vector<std::string>& words) {
    std::string text;
    for (const std::string& w : words) text += (text.empty() ? "" : " ") + w;
    return text;
}

}  // namespace

// One frame grammar: walks every command's help (`flowvid help WORDS`, also
// a check of help for nested commands); each that takes frames offers both
// --frames A:B and --frame-count N, and refuses a bare --frames N with both
// spellings. The set of such commands is pinned so none slips out.
TEST(Cli, EveryCommandTakesOneFrameGrammar) {
    std::vector<std::vector<std::string>> leaves, open = subcommands_of({});
    ASSERT_GE(open.size(), 15u);
    while (!open.empty()) {
        const std::vector<std::string> command = open.back();
        open.pop_back();
        const std::vector<std::vector<std::string>> children = subcommands_of(command);
        if (children.empty()) leaves.push_back(command);
        open.insert(open.end(), children.begin(), children.end());
    }
    std::set<std::string> with_frames;
    for (const std::vector<std::string>& command : leaves) {
        std::vector<std::string> help_args = {"help"};
        help_args.insert(help_args.end(), command.begin(), command.end());
        const CliResult help = run_flowvid(help_args);
        ASSERT_EQ(help.exit_code, 0) << joined(command) << ": " << help.err;
        EXPECT_TRUE(mentions(help.out, "Usage: flowvid " + joined(command))) << help.out;
        const bool range = mentions(help.out, "--frames A:B"), count = mentions(help.out, "--frame-count N");
        EXPECT_EQ(range, count) << joined(command) << " offers only one of --frames A:B and --frame-count N";
        EXPECT_FALSE(mentions(help.out, "--frames INT") || mentions(help.out, "--frames TEXT")) << joined(command);
        if (!range) continue;
        with_frames.insert(joined(command));
        std::vector<std::string> bare = command;
        bare.insert(bare.end(), {"--frames", "12"});
        const CliResult refused = run_flowvid(bare);
        EXPECT_EQ(refused.exit_code, 2) << joined(command);
        EXPECT_TRUE(mentions(refused.err, "--frame-count 12") && mentions(refused.err, "1:12"))
            << joined(command) << ": " << refused.err;
    }
    const std::set<std::string> expected = {"bench gap", "diagnose", "edit",          "eval cloth", "fit cloth",
                                            "fit rigid", "predict cloth", "predict rigid", "quality",   "recognize",
                                            "rectify",   "simulate", "synth",         "track"};
    EXPECT_EQ(with_frames, expected);
}

// Ranges mean the frames named, counts the first N; a command that always
// starts at the first frame says so; the flags every command shares work
// after the command too; help takes a command's words; --report still
// writes where --out would, with a warning.
TEST(Cli, FrameRangesCountsAndGlobalFlagsAnywhere) {
    const std::string dir = scratch_dir("cli_frame_grammar");
    // fit cloth compares waving frames from the wave's start.
    const CliResult later = run_flowvid({"fit", "cloth", "--capture", shared_path("captures/cloth-cotton-waving-1"), "--out",
                                         dir + "/x.fabric.json", "--frames", "3:20"});
    if (!std::filesystem::exists(shared_path("captures/cloth-cotton-waving-1"))) GTEST_SKIP() << "../shared is absent";
    EXPECT_EQ(later.exit_code, 2);
    EXPECT_TRUE(mentions(later.err, "from the first one, 1") && mentions(later.err, "--frames 1:B or --frame-count N"))
        << later.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/x.fabric.json"));

    // The global --progress after the command: JSON progress events on stderr.
    const CliResult simulated = run_flowvid({"simulate", "--preset", example_preset(), "--capture",
                                             shared_path("captures/cloth-cotton-waving-1"), "--vat", dir + "/a.exr",
                                             "--resolution", "8x8", "--frames", "1:3", "--json", "--progress", "json"});
    ASSERT_EQ(simulated.exit_code, 0) << simulated.err;
    EXPECT_EQ(nlohmann::json::parse(simulated.out)["frames"], 3);
    EXPECT_TRUE(mentions(simulated.err, "\"event\"")) << simulated.err;
    const CliResult counted = run_flowvid({"--progress", "none", "simulate", "--preset", example_preset(), "--capture",
                                           shared_path("captures/cloth-cotton-waving-1"), "--vat", dir + "/b.exr",
                                           "--resolution", "8x8", "--frame-count", "3"});
    ASSERT_EQ(counted.exit_code, 0) << counted.err;
    EXPECT_EQ(read_text(dir + "/a.exr"), read_text(dir + "/b.exr"));  // 1:3 and the first 3 are one run
    EXPECT_FALSE(mentions(counted.err, "\"event\""));
    const CliResult too_many = run_flowvid({"simulate", "--preset", example_preset(), "--capture",
                                            shared_path("captures/cloth-cotton-waving-1"), "--vat", dir + "/c.exr",
                                            "--frame-count", "100000"});
    EXPECT_EQ(too_many.exit_code, 2);
    EXPECT_TRUE(mentions(too_many.err, "the capture's pins cover")) << too_many.err;

    const CliResult help = run_flowvid({"help", "fit", "cloth"});
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_TRUE(mentions(help.out, "Usage: flowvid fit cloth")) << help.out;
    const CliResult unknown = run_flowvid({"help", "fit", "clothes"});
    EXPECT_EQ(unknown.exit_code, 2);
    EXPECT_TRUE(mentions(unknown.err, "flowvid help fit")) << unknown.err;

    // eval cloth's old --report: the same files as --out, and a warning.
    const CliResult old_spelling = run_flowvid({"eval", "cloth", "--preset", example_preset(), "--capture",
                                                shared_path("captures/cloth-cotton-static-1"), "--resolution", "8x8",
                                                "--floor-members", "0", "--report", dir + "/eval"});
    ASSERT_EQ(old_spelling.exit_code, 0) << old_spelling.err;
    EXPECT_TRUE(mentions(old_spelling.err, "--report is now --out")) << old_spelling.err;
    EXPECT_TRUE(std::filesystem::exists(dir + "/eval/eval.json"));
}
