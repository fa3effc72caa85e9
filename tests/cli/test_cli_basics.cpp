// The flowvid tool as a user meets it: help, version, exit codes, validate, info.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

using namespace flowvid::testing;

namespace {
bool mentions(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }
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
    EXPECT_EQ(missing.exit_code, 3);
    EXPECT_TRUE(mentions(missing.err, dir + "/missing.fabric.json")) << missing.err;
}

TEST(Cli, InfoForPeopleAndMachines) {
    CliResult human = run_flowvid({"info", example_preset()});
    EXPECT_EQ(human.exit_code, 0) << human.err;
    EXPECT_TRUE(mentions(human.out, "areal_density_kg_per_m2")) << human.out;

    CliResult machine = run_flowvid({"info", "--json", example_preset()});
    ASSERT_EQ(machine.exit_code, 0) << machine.err;
    const nlohmann::json summary = nlohmann::json::parse(machine.out);
    EXPECT_EQ(summary["kind"], "fabric preset");
    EXPECT_DOUBLE_EQ(summary["parameters"]["areal_density_kg_per_m2"]["value"].get<double>(), 0.15);

    CliResult missing = run_flowvid({"info", "/nonexistent/file.fabric.json"});
    EXPECT_EQ(missing.exit_code, 4) << missing.err;
}
