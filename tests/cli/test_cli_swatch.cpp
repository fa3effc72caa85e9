// flowvid swatch as the Blender add-on's CLI backend runs it: an experiment as JSON in, every frame out.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

using namespace flowvid::testing;

namespace {

std::string own_dir(const std::string& name) { return scratch_dir(name + "_" + std::to_string(::getpid())); }

// Two top corners of a 0.2 m swatch, moving 1 cm along x per frame.
flowvid::cloth::SwatchExperiment moving_corners(int frames) {
    flowvid::cloth::SwatchExperiment experiment;
    experiment.width_m = experiment.height_m = 0.2;
    experiment.fps = 30.0;
    experiment.frame_count = frames;
    for (const double u : {0.0, 1.0}) {
        flowvid::cloth::PinTrajectory pin;
        pin.uv = {u, 1.0};
        for (int f = 0; f < frames; ++f) pin.positions_m.emplace_back(0.16 * u + 0.01 * f, 0.0, 0.0);
        experiment.pins.push_back(pin);
    }
    return experiment;
}

std::string write_experiment(const std::string& dir, const flowvid::cloth::SwatchExperiment& experiment) {
    nlohmann::json pins = nlohmann::json::array();
    for (const auto& pin : experiment.pins) {
        nlohmann::json positions = nlohmann::json::array();
        for (const auto& p : pin.positions_m) positions.push_back({p.x(), p.y(), p.z()});
        pins.push_back({{"uv", {pin.uv.x(), pin.uv.y()}}, {"positions_m", positions}});
    }
    const std::string path = dir + "/experiment.json";
    // As the Blender add-on writes it (flowvid.swatch_experiment 1.0, unsorted keys, compact).
    std::ofstream(path) << nlohmann::json{{"format", "flowvid.swatch_experiment"}, {"version", "1.0"},
                                          {"name", "moving corners"},
                                          {"width_m", experiment.width_m}, {"height_m", experiment.height_m},
                                          {"fps", experiment.fps}, {"frame_count", experiment.frame_count},
                                          {"pins", pins}}
                               .dump();
    return path;
}

TEST(CliSwatch, FramesAreTheLibrarysAndThePinsFollowTheExperiment) {
    const std::string dir = own_dir("cli_swatch");
    const int frames = 6;
    const flowvid::cloth::SwatchExperiment experiment = moving_corners(frames);
    const std::string preset = source_path("formats/examples/cotton.fabric.json");
    const CliResult result = run_flowvid({"swatch", "--preset", preset, "--experiment", write_experiment(dir, experiment),
                                          "--grid", "9x9", "--integrator", "rk4_adaptive", "--out",
                                          dir + "/nested/frames.json", "--json"});
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_EQ(nlohmann::json::parse(result.out)["frames"], frames);
    nlohmann::json written;
    std::ifstream(dir + "/nested/frames.json") >> written;
    ASSERT_EQ(written["status"], "ok");
    EXPECT_EQ(written["format"], "flowvid.swatch_frames");
    EXPECT_EQ(written["version"], "1.0");
    // What the add-on writes and what the command writes are both files `flowvid validate` accepts.
    const CliResult validated = run_flowvid({"validate", dir + "/experiment.json", dir + "/nested/frames.json"});
    EXPECT_EQ(validated.exit_code, 0) << validated.out << validated.err;
    ASSERT_EQ(written["frames"].size(), static_cast<std::size_t>(frames));

    // Reference: the library's own run with the options the Python module uses (flowvid.cloth.simulate_swatch).
    flowvid::cloth::SwatchOptions options;
    options.rows = options.cols = 9;
    options.simulation.integrator = flowvid::cloth::Integrator::rk4_adaptive;
    options.simulation.implicit_substeps_per_frame = 10;
    const flowvid::cloth::SwatchRun run = flowvid::cloth::simulate_swatch(
        experiment, flowvid::cloth::material_from_fabric(flowvid::cloth::read_preset_for_simulation(preset).parameters),
        options);
    const auto reference = flowvid::cloth::sample_frames(run.swatch.mesh, run.simulation.frames, 9, 9);
    double worst_m = 0.0;
    for (int f = 0; f < frames; ++f)
        for (int i = 0; i < 81; ++i)
            for (int k = 0; k < 3; ++k)
                worst_m = std::max(worst_m, std::abs(written["frames"][f][i][k].get<double>() - reference[f](i, k)));
    // The pinned corners (row 8, columns 0 and 8) are where the experiment puts them at every frame.
    double worst_pin_m = 0.0;
    for (int f = 0; f < frames; ++f)
        for (int p = 0; p < 2; ++p) {
            const int vertex = written["pinned_vertices"][p].get<int>();
            for (int k = 0; k < 3; ++k)
                worst_pin_m = std::max(worst_pin_m, std::abs(written["frames"][f][vertex][k].get<double>() -
                                                             experiment.pins[p].positions_m[f](k)));
        }
    std::printf("[measured] CLI vs library frames: worst %.1e m; pinned corners vs experiment: worst %.1e m\n",
                worst_m, worst_pin_m);
    EXPECT_LT(worst_m, 1e-12);  // the same computation, printed with round-trip precision
    EXPECT_LT(worst_pin_m, 1e-9);
    // The hung swatch sags: the middle of its bottom row hangs about a swatch height below the pins.
    const double sag_m = -written["frames"][0][4][2].get<double>();
    EXPECT_GT(sag_m, 0.15);
    EXPECT_LT(sag_m, 0.25);
}

TEST(CliSwatch, AnExperimentMissingFieldsIsRefusedNamingThemAll) {
    const std::string dir = own_dir("cli_swatch_bad");
    std::ofstream(dir + "/bad.json") << R"({"format": "flowvid.swatch_experiment", "version": "1.0", "width_m": 0.2,
        "fps": 30, "frame_count": 2, "pins": [{"uv": [0, 1.5]}, {"uv": [1, 1], "positions_m": [[0, 0, 0]]}]})";
    const CliResult result = run_flowvid({"swatch", "--preset", source_path("formats/examples/cotton.fabric.json"),
                                          "--experiment", dir + "/bad.json", "--out", dir + "/frames.json"});
    EXPECT_EQ(result.exit_code, 3) << result.err;
    EXPECT_NE(result.err.find("/height_m"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("/pins/0/positions_m"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("/pins/0/uv/1"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("/pins/1/positions_m"), std::string::npos) << result.err;  // 1 point, 2 frames
    EXPECT_FALSE(std::filesystem::exists(dir + "/frames.json"));
}

TEST(CliSwatch, AnExperimentWithoutItsFormatIsRefusedNamingIt) {
    const std::string dir = own_dir("cli_swatch_headerless");
    std::ofstream(dir + "/old.json") << R"({"width_m": 0.2, "height_m": 0.2, "fps": 30, "frame_count": 1,
        "pins": [{"uv": [0, 1], "positions_m": [[0, 0, 0]]}]})";
    const CliResult result = run_flowvid({"swatch", "--preset", source_path("formats/examples/cotton.fabric.json"),
                                          "--experiment", dir + "/old.json", "--out", dir + "/frames.json"});
    EXPECT_EQ(result.exit_code, 3) << result.err;
    EXPECT_NE(result.err.find("/format"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("flowvid.swatch_experiment"), std::string::npos) << result.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/frames.json"));
}

TEST(CliSwatch, HelpTeachesTheExperimentFile) {
    const CliResult result = run_flowvid({"swatch", "--help"});
    EXPECT_EQ(result.exit_code, 0);
    for (const char* taught : {"\"positions_m\"", "--experiment", "Examples:", "Exit codes", "flowvid.swatch_experiment",
                               "flowvid.swatch_frames"})
        EXPECT_NE(result.out.find(taught), std::string::npos) << taught;
}

}  // namespace
