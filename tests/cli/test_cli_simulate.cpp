// flowvid simulate as a user runs it: a preset driven by a shared capture's pins.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/motion_gltf.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <unistd.h>

using namespace flowvid::testing;
namespace fs = std::filesystem;

namespace {

using flowvid::testing::mentions;
std::string own_dir(const std::string& name) { return scratch_dir(name + "_" + std::to_string(::getpid())); }

const std::string kWaving = "captures/cloth-cotton-waving-1";

TEST(CliSimulate, PinnedCornersFollowTheCapturesPinsAndFilesAgree) {
    const std::string dir = own_dir("cli_simulate");
    const int frames = 12;
    const CliResult result = run_flowvid({"simulate", "--preset", source_path("formats/examples/cotton.fabric.json"),
                                          "--capture", shared_path(kWaving), "--out", dir + "/nested/wave.glb", "--vat",
                                          dir + "/wave.exr", "--frame-count", std::to_string(frames), "--grid", "13x13",
                                          "--json"});
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const nlohmann::json summary = nlohmann::json::parse(result.out);
    EXPECT_EQ(summary["frames"], frames);
    EXPECT_LT(summary["equilibrium_residual_N"].get<double>(), 1e-6);

    const flowvid::formats::VertexAnimation vat = flowvid::formats::read_vertex_animation(dir + "/wave.exr");
    ASSERT_EQ(vat.frame_count, frames);
    ASSERT_EQ(vat.grid_rows.value_or(0), 13);
    ASSERT_EQ(vat.grid_cols.value_or(0), 13);
    EXPECT_DOUBLE_EQ(vat.fps, 30.0);

    // Reference: the capture's own pin trajectories. The grid point at each
    // pin's uv is the pinned vertex (13x13 grid points fall on 24x24 vertices
    // only at the corners, where the pins are).
    const flowvid::formats::Capture capture = flowvid::formats::read_capture(shared_path(kWaving));
    const flowvid::cloth::SwatchExperiment experiment = flowvid::cloth::experiment_from_capture(capture);
    double worst_m = 0.0;
    for (const flowvid::cloth::PinTrajectory& pin : experiment.pins) {
        const int c = static_cast<int>(std::lround(pin.uv.x() * 12));
        const int r = static_cast<int>(std::lround(pin.uv.y() * 12));
        for (int f = 0; f < frames; ++f)
            worst_m = std::max(worst_m, (vat.position(f, r * 13 + c).cast<double>() - pin.positions_m[static_cast<std::size_t>(f)]).norm());
    }
    std::printf("[measured] worst pinned-corner distance from the capture's pins: %.2e m\n", worst_m);
    EXPECT_LT(worst_m, 1e-5);  // float32 storage of ~1 m coordinates

    // The cloth hangs below its pins at rest and moves with them.
    double lowest_pin_z = 1e9, mean_z = 0.0;
    for (const auto& pin : experiment.pins) lowest_pin_z = std::min(lowest_pin_z, pin.positions_m[0].z());
    for (int v = 0; v < vat.vertex_count; ++v) mean_z += vat.position(0, v).z() / vat.vertex_count;
    EXPECT_LT(mean_z, lowest_pin_z - 0.05);

    // The glTF holds the same positions (float rounding) and the grid's triangles.
    const flowvid::formats::MeshAnimation gltf = flowvid::formats::read_motion_gltf(dir + "/nested/wave.glb");
    ASSERT_EQ(gltf.frame_count(), frames);
    ASSERT_EQ(gltf.vertex_count(), 169);
    EXPECT_EQ(gltf.triangles.size(), 2u * 12u * 12u);
    double gltf_vs_vat = 0.0;
    for (int f = 0; f < frames; ++f)
        for (int v = 0; v < 169; ++v)
            gltf_vs_vat = std::max(gltf_vs_vat, static_cast<double>((gltf.frames_positions_m[f][v] - vat.position(f, v)).norm()));
    EXPECT_LT(gltf_vs_vat, 1e-5);
}

TEST(CliSimulate, SaysWhenTheMeshIsTooCoarseForTheFabricsFolds) {
    // A soft silk folds finer than a 12 x 12 mesh's edges: the drape is then
    // the mesh's (docs/cloth_model.md, "Folds finer than the grid"), and
    // simulate says so, with the resolution that holds the folds. The
    // example cotton (bending 2e-5 N m) folds at about 24 mm: no note.
    const std::string dir = own_dir("cli_simulate_folds");
    const std::string capture_dir = shared_path("captures/cloth-silk-static-1");
    const flowvid::formats::Capture capture = flowvid::formats::read_capture(capture_dir);
    const flowvid::cloth::SwatchExperiment experiment = flowvid::cloth::experiment_from_capture(capture);
    for (const std::string preset : {source_path("tests/data/cloth/silk.fabric.json"), source_path("formats/examples/cotton.fabric.json")}) {
        const CliResult result = run_flowvid({"simulate", "--preset", preset, "--capture", capture_dir, "--vat", dir + "/drape.exr",
                                              "--frame-count", "1", "--resolution", "12x12", "--json"});
        ASSERT_EQ(result.exit_code, 0) << result.err;
        const nlohmann::json summary = nlohmann::json::parse(result.out);
        const flowvid::cloth::ClothMaterial material = flowvid::cloth::experiment_material(
            experiment, flowvid::cloth::material_from_fabric(flowvid::formats::read_fabric_preset(preset).parameters));
        const double fold_m = flowvid::cloth::fold_length_m(material);
        const double edge_m = std::max(experiment.width_m, experiment.height_m) / 11.0;
        EXPECT_NEAR(summary["fold_length_mm"].get<double>(), 1e3 * fold_m, 1e-9);
        EXPECT_NEAR(summary["mesh_edge_mm"].get<double>(), 1e3 * edge_m, 1e-9);
        const bool holds = edge_m <= flowvid::cloth::kLongestEdgePerFoldLength * fold_m;
        EXPECT_EQ(summary["mesh_holds_folds"].get<bool>(), holds);
        EXPECT_EQ(holds, mentions(preset, "cotton")) << 1e3 * fold_m << " mm folds";
        const int needed = static_cast<int>(std::ceil(std::max(experiment.width_m, experiment.height_m) /
                                                      (flowvid::cloth::kLongestEdgePerFoldLength * fold_m))) + 1;
        EXPECT_EQ(mentions(result.err, "so it folds at its own scale and a finer mesh drapes differently"), !holds) << result.err;
        if (!holds) {
            EXPECT_TRUE(mentions(result.err, "--resolution " + std::to_string(needed) + "x" + std::to_string(needed))) << result.err;
            EXPECT_LE(std::max(experiment.width_m, experiment.height_m) / (needed - 1),
                      flowvid::cloth::kLongestEdgePerFoldLength * fold_m);  // the advice holds the folds
        }
    }
}

TEST(CliSimulate, InfoSaysWhetherAGarmentsEdgesHoldAPresetsFolds) {
    // What the Blender add-on asks for a garment (its mean edge): the same
    // rule as simulate's, from the preset alone (no capture's mass). The
    // test silk folds at (7.452e-7 / (0.08 * 9.81))^(1/3) = 9.83 mm, so
    // edges up to 13.1 mm hold its folds.
    const std::string preset = source_path("tests/data/cloth/silk.fabric.json");
    const flowvid::cloth::ClothMaterial material =
        flowvid::cloth::material_from_fabric(flowvid::formats::read_fabric_preset(preset).parameters);
    const double fold_mm = 1e3 * std::cbrt(material.bend_N_m / (material.areal_density_kg_per_m2 * 9.81));
    for (const double edge_mm : {12.0, 20.0}) {
        const CliResult result = run_flowvid({"info", "--json", "--mesh-edge-mm", std::to_string(edge_mm), preset});
        ASSERT_EQ(result.exit_code, 0) << result.err;
        const nlohmann::json check = nlohmann::json::parse(result.out);
        EXPECT_EQ(check["kind"], "fold check");
        EXPECT_NEAR(check["fold_length_mm"].get<double>(), fold_mm, 1e-9);
        EXPECT_NEAR(check["longest_edge_mm"].get<double>(), 4.0 / 3.0 * fold_mm, 1e-9);
        EXPECT_NEAR(check["mesh_edge_mm"].get<double>(), edge_mm, 1e-9);
        EXPECT_EQ(check["mesh_holds_folds"].get<bool>(), edge_mm < 4.0 / 3.0 * fold_mm) << edge_mm;

        const CliResult text = run_flowvid({"info", "--mesh-edge-mm", std::to_string(edge_mm), preset});
        ASSERT_EQ(text.exit_code, 0) << text.err;
        EXPECT_EQ(mentions(text.out, "too long: the cloth folds at the mesh's scale"), edge_mm > 4.0 / 3.0 * fold_mm) << text.out;
    }
    // The swatch it was fitted on (provenance: 13.04 mm edges) holds the
    // folds too; the same preset fitted on a 12x12 swatch (27.3 mm edges)
    // would not, and then info says which meshes reproduce the filmed drape.
    const CliResult own = run_flowvid({"info", "--json", "--mesh-edge-mm", "20", preset});
    ASSERT_EQ(own.exit_code, 0) << own.err;
    const nlohmann::json own_check = nlohmann::json::parse(own.out);
    EXPECT_NEAR(own_check["fitted_edge_mm"].get<double>(), 300.0 / 23.0, 1e-9);
    EXPECT_TRUE(own_check["fitted_mesh_holds_folds"].get<bool>());
    const std::string dir = own_dir("cli_info_folds");
    nlohmann::json coarse = nlohmann::json::parse(read_text(preset));
    coarse["provenance"]["swatch_edge_length_m"] = 0.3 / 11.0;
    write_text(dir + "/coarse.fabric.json", coarse.dump(1));
    const CliResult coarse_json = run_flowvid({"info", "--json", "--mesh-edge-mm", "20", dir + "/coarse.fabric.json"});
    ASSERT_EQ(coarse_json.exit_code, 0) << coarse_json.err;
    EXPECT_FALSE(nlohmann::json::parse(coarse_json.out)["fitted_mesh_holds_folds"].get<bool>());
    const CliResult coarse_text = run_flowvid({"info", dir + "/coarse.fabric.json"});
    EXPECT_TRUE(mentions(coarse_text.out, "meshes with edges near 27.3 mm reproduce the filmed drape")) << coarse_text.out;
    EXPECT_FALSE(mentions(run_flowvid({"info", preset}).out, "reproduce the filmed drape"));

    // Plain info ends with the fold length; the option is for presets only.
    const CliResult plain = run_flowvid({"info", preset});
    ASSERT_EQ(plain.exit_code, 0) << plain.err;
    EXPECT_TRUE(mentions(plain.out, "folds: about 9.83 mm when hung")) << plain.out;
    const CliResult capture = run_flowvid({"info", "--mesh-edge-mm", "12", shared_path(kWaving)});
    EXPECT_EQ(capture.exit_code, 2);
    EXPECT_TRUE(mentions(capture.err, "--mesh-edge-mm")) << capture.err;
    EXPECT_TRUE(mentions(capture.err, "fabric presets only")) << capture.err;
}

TEST(CliSimulate, BadRequestsNameTheProblemAndWriteNothing) {
    const std::string dir = own_dir("cli_simulate_bad");
    const std::string preset = source_path("formats/examples/cotton.fabric.json");
    const CliResult nothing = run_flowvid({"simulate", "--preset", preset, "--capture", shared_path(kWaving)});
    EXPECT_EQ(nothing.exit_code, 2);
    EXPECT_TRUE(mentions(nothing.err, "--out")) << nothing.err;

    const CliResult grid = run_flowvid({"simulate", "--preset", preset, "--capture", shared_path(kWaving), "--out",
                                        dir + "/a.glb", "--grid", "24by24"});
    EXPECT_EQ(grid.exit_code, 2);
    EXPECT_TRUE(mentions(grid.err, "--grid 24by24")) << grid.err;

    const CliResult rigid = run_flowvid({"simulate", "--preset", preset, "--capture",
                                         shared_path("captures/rigid-toss-major"), "--out", dir + "/a.glb"});
    EXPECT_EQ(rigid.exit_code, 3);
    EXPECT_TRUE(mentions(rigid.err, "capture.json")) << rigid.err;
    EXPECT_TRUE(mentions(rigid.err, "/kind")) << rigid.err;

    // A preset whose fabric cannot hold together: the run blows up, the
    // message names the frame, and no file appears.
    std::string text = read_text(preset);
    const std::string key = "\"stretch_warp_stiffness_N_per_m\":";
    const std::size_t at = text.find(key);
    ASSERT_NE(at, std::string::npos);
    const std::size_t value = text.find("\"value\":", at);
    const std::size_t end = text.find(',', value);
    text.replace(value, end - value, "\"value\": 0.001");
    const std::size_t range = text.find("[10.0", at);
    text.replace(range, 5, "[0.0001");
    write_text(dir + "/limp.fabric.json", text);
    const CliResult limp = run_flowvid({"simulate", "--preset", dir + "/limp.fabric.json", "--capture",
                                        shared_path(kWaving), "--out", dir + "/limp.glb", "--frame-count", "20",
                                        "--integrator", "rk4"});
    EXPECT_EQ(limp.exit_code, 1) << limp.out << limp.err;
    EXPECT_TRUE(mentions(limp.err, "at frame")) << limp.err;
    EXPECT_FALSE(fs::exists(dir + "/limp.glb"));
}

}  // namespace
