// flowvid fit cloth / predict cloth / eval cloth / recognize as a user runs
// them, kept small (static drape, coarse mesh, few evaluations) so that the
// numbers are checked against independent references rather than waited for.

#include "cli_runner.hpp"
#include "test_support.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

using namespace flowvid::testing;

namespace {

std::string own_dir(const std::string& name) { return scratch_dir(name + "_" + std::to_string(::getpid())); }
const std::string kStatic = "captures/cloth-cotton-static-1";

TEST(CliClothFit, StaticFitIsDeterministicImprovesOnItsStartAndRecordsItsSources) {
    // Silk: its swatch mass (80 g/m^2) differs from the library's default density.
    const std::string kSilkStatic = "captures/cloth-silk-static-1";
    const std::string dir = own_dir("cli_fit_cloth");
    const auto fit = [&](const std::string& out, const std::string& threads) {
        return run_flowvid({"fit", "cloth", "--capture", shared_path(kSilkStatic), "--out", out, "--evaluations", "10",
                            "--variability-runs", "2", "--variability-evaluations", "6", "--resolution", "8x8", "--seed", "3", "--threads", threads,
                            "--json"});
    };
    const CliResult one = fit(dir + "/one.fabric.json", "1");
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const CliResult two = fit(dir + "/two.fabric.json", "2");
    ASSERT_EQ(two.exit_code, 0) << two.err;
    const nlohmann::json summary = nlohmann::json::parse(one.out);
    EXPECT_LT(summary["final_error"].get<double>(), summary["start_error"].get<double>());
    // The default compares the footage's stripe scan; a static drape fits
    // stiffness and damping (6) and the capacity terms (hem, two
    // compression ratios, diagonal fibres: 10).
    EXPECT_EQ(summary["fit_to"], "scan");
    EXPECT_EQ(summary["parameters"].size(), 10u);

    const flowvid::formats::FabricPreset a = flowvid::formats::read_fabric_preset(dir + "/one.fabric.json");
    const flowvid::formats::FabricPreset b = flowvid::formats::read_fabric_preset(dir + "/two.fabric.json");
    EXPECT_TRUE(a.parameters == b.parameters) << "the thread count changed the fit";
    ASSERT_EQ(a.provenance.captures.size(), 1u);
    const flowvid::formats::Capture capture = flowvid::formats::read_capture(shared_path(kSilkStatic));
    EXPECT_EQ(a.provenance.captures[0].capture_json_sha256, capture.capture_json_sha256);
    EXPECT_EQ(a.provenance.captures[0].test, "static");
    // The mass the fit simulated is the capture's weighed swatch: the cloth's
    // area at its density plus the hem around its edge.
    ASSERT_TRUE(capture.swatch.has_value());
    const double width_m = capture.swatch->width_m, height_m = capture.swatch->height_m;
    EXPECT_GT(a.parameters.hem_line_density_kg_per_m.value, 0.0);
    EXPECT_NEAR(a.parameters.areal_density_kg_per_m2.value * width_m * height_m +
                    a.parameters.hem_line_density_kg_per_m.value * 2.0 * (width_m + height_m),
                capture.swatch->mass_kg, 1e-12);
    EXPECT_TRUE(a.parameters.bend_stiffness_N_m.uncertainty.has_value());
    EXPECT_EQ(run_flowvid({"validate", dir + "/one.fabric.json"}).exit_code, 0);
}

TEST(CliClothFit, EvalAgreesWithAnIndependentComparisonOfPredictAndTruth) {
    const std::string dir = own_dir("cli_eval_cloth");
    const std::string preset = source_path("formats/examples/cotton.fabric.json");
    const CliResult predicted = run_flowvid({"predict", "cloth", "--preset", preset, "--capture", shared_path(kStatic),
                                             "--out", dir + "/pred.exr", "--grid", "24x24", "--resolution", "12x12",
                                             "--frame-count", "1"});
    ASSERT_EQ(predicted.exit_code, 0) << predicted.err;
    const CliResult eval = run_flowvid({"eval", "cloth", "--preset", preset, "--capture", shared_path(kStatic),
                                        "--resolution", "12x12", "--floor-members", "2", "--out", dir + "/report",
                                        "--json"});
    ASSERT_EQ(eval.exit_code, 0) << eval.err;
    const nlohmann::json summary = nlohmann::json::parse(eval.out);
    const nlohmann::json& window = summary["captures"][0]["windows"][0];
    EXPECT_EQ(window["frames"], "1-1");
    ASSERT_TRUE(window["vertex_rms_mm"].is_number());
    ASSERT_TRUE(window["vertex_floor_mm"].is_number());
    EXPECT_GT(window["vertex_floor_mm"].get<double>(), 0.0);

    // Reference: RMS of predict's file against the capture's truth, computed here.
    const flowvid::formats::VertexAnimation p = flowvid::formats::read_vertex_animation(dir + "/pred.exr");
    const flowvid::formats::VertexAnimation t =
        *flowvid::formats::read_capture_truth_positions(flowvid::formats::read_capture(shared_path(kStatic)));
    ASSERT_EQ(p.vertex_count, t.vertex_count);
    double sum = 0.0;
    for (int v = 0; v < p.vertex_count; ++v) sum += (p.position(0, v) - t.position(0, v)).cast<double>().squaredNorm();
    const double rms_mm = 1e3 * std::sqrt(sum / p.vertex_count);
    std::printf("[measured] eval %.4f mm, independent %.4f mm\n", window["vertex_rms_mm"].get<double>(), rms_mm);
    EXPECT_NEAR(window["vertex_rms_mm"].get<double>(), rms_mm, 1e-3);  // float32 files
    EXPECT_TRUE(std::filesystem::exists(dir + "/report/eval.html"));
    EXPECT_NE(read_text(dir + "/report/eval.html").find("<svg"), std::string::npos);
}

TEST(CliClothFit, RecognizeRanksPresetsByTheErrorsEvalReports) {
    const std::string dir = own_dir("cli_recognize");
    const std::string cotton = source_path("formats/examples/cotton.fabric.json");
    // A second fabric: the same with 300x the bending stiffness (a stiff card).
    std::string text = read_text(cotton);
    const std::size_t at = text.find("\"bend_stiffness_N_m\"");
    const std::size_t value = text.find("\"value\":", at);
    const std::size_t end = text.find(',', value);
    const double bend = std::stod(text.substr(value + 8, end - value - 8));
    text.replace(value, end - value, "\"value\": " + std::to_string(300 * bend));
    const std::size_t range = text.find("\"range\": [", at);
    const std::size_t range_end = text.find(']', range);
    text.replace(range, range_end + 1 - range, "\"range\": [0.0, 1.0]");
    write_text(dir + "/card.fabric.json", text);

    // recognize the cotton against another preset on the drape (12x12), as JSON or as the table.
    const auto recognize = [&](const std::string& other, bool json) {
        std::vector<std::string> arguments = {"recognize", "--preset", cotton, "--preset", other, "--capture",
                                              shared_path(kStatic), "--resolution", "12x12"};
        if (json) arguments.push_back("--json");
        return run_flowvid(arguments);
    };
    const CliResult r = recognize(dir + "/card.fabric.json", true);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json matrix = nlohmann::json::parse(r.out);
    const nlohmann::json& row = matrix["captures"][0];
    const double e_cotton = row["metric_error"][cotton].get<double>();
    const double e_card = row["metric_error"][dir + "/card.fabric.json"].get<double>();
    EXPECT_EQ(row["recognized_as"], e_cotton < e_card ? cotton : dir + "/card.fabric.json");
    for (const auto& [preset, expected] : {std::pair{cotton, e_cotton}, std::pair{dir + "/card.fabric.json", e_card}}) {
        const CliResult eval = run_flowvid({"eval", "cloth", "--preset", preset, "--capture", shared_path(kStatic),
                                            "--resolution", "12x12", "--floor-members", "0", "--json"});
        ASSERT_EQ(eval.exit_code, 0) << eval.err;
        EXPECT_NEAR(nlohmann::json::parse(eval.out)["captures"][0]["weighted_error"].get<double>(), expected, 1e-9 * expected);
    }
    EXPECT_NE(e_cotton, e_card);
    // Recognised only beyond the floor, compared as the table shows them
    // (RMS mm of the scan: the square root of the weighted error per frame,
    // here one frame): the card drapes far from the cotton, by more than
    // chaos moves either.
    const auto rms_mm = [](double weighted_error) { return std::sqrt(weighted_error); };
    const double margin = std::abs(rms_mm(e_cotton) - rms_mm(e_card));
    EXPECT_NEAR(row["margin"].get<double>(), margin, 1e-9 * margin);
    EXPECT_GT(margin, rms_mm(row["floor"].get<double>()));
    EXPECT_TRUE(row["decided"].get<bool>());

    // Two presets the footage cannot tell apart: the cotton and its twin with
    // the bending changed by one part in a million (what the floor's own
    // runs change) are undecided, whichever comes out lower.
    text = read_text(cotton);
    char twin_bend[40];
    std::snprintf(twin_bend, sizeof twin_bend, "%.17g", bend * (1.0 + 1e-6));
    text.replace(value, end - value, std::string("\"value\": ") + twin_bend);
    write_text(dir + "/twin.fabric.json", text);
    const CliResult twins = recognize(dir + "/twin.fabric.json", true);
    ASSERT_EQ(twins.exit_code, 0) << twins.err;
    const nlohmann::json twin_matrix = nlohmann::json::parse(twins.out);
    const nlohmann::json& twin_row = twin_matrix["captures"][0];
    const double twin_margin = std::abs(rms_mm(twin_row["metric_error"][cotton].get<double>()) -
                                        rms_mm(twin_row["metric_error"][dir + "/twin.fabric.json"].get<double>()));
    std::printf("[measured] cotton vs card: margin %.4g mm, floor %.4g mm; cotton vs its twin: margin %.4g mm, floor %.4g mm\n",
                margin, rms_mm(row["floor"].get<double>()), twin_margin, rms_mm(twin_row["floor"].get<double>()));
    EXPECT_NEAR(twin_row["margin"].get<double>(), twin_margin, 1e-9);
    EXPECT_LE(twin_margin, rms_mm(twin_row["floor"].get<double>()));
    EXPECT_FALSE(twin_row["decided"].get<bool>());
    const CliResult table = recognize(dir + "/twin.fabric.json", false);
    EXPECT_TRUE(mentions(table.out, "undecided: the lowest two differ by less than the floor")) << table.out;
}

TEST(CliClothFit, TracksFitFindsTheFabricThatMadeTheTracks) {
    // Tracks made by our own simulator (the example cotton on an 8 x 8 mesh,
    // measured on a 12 x 12 uv grid) in a copy of the silk drape: a fit to
    // them at the same mesh must come back to under a millimetre (the start,
    // relaxed from the measured first frame, misses by ~7 mm), and say it
    // fitted tracks. One drape cannot tell the diagonal fibres from shear,
    // so the fit may reach the drape with another mix of the two (0.8 mm
    // since the shear range widened; 0.06 before).
    const std::string dir = own_dir("cli_fit_tracks");
    const std::string source = shared_path("captures/cloth-silk-static-1");
    const std::string copy = dir + "/drape";
    std::filesystem::create_directories(copy);
    for (const char* entry : {"frames", "masks", "background.png"})
        std::filesystem::create_symlink(std::filesystem::absolute(source + "/" + entry), copy + "/" + entry);
    const std::string preset = source_path("formats/examples/cotton.fabric.json");
    const CliResult made = run_flowvid({"simulate", "--preset", preset, "--capture", source, "--resolution", "8x8", "--grid",
                                        "12x12", "--out", dir + "/made.glb", "--vat", copy + "/tracks.exr"});
    ASSERT_EQ(made.exit_code, 0) << made.err;
    nlohmann::json capture = nlohmann::json::parse(read_text(source + "/capture.json"));
    capture["tracks"] = {{"file", "tracks.exr"}, {"rows", 12}, {"cols", 12}};
    write_text(copy + "/capture.json", capture.dump(1));
    ASSERT_EQ(run_flowvid({"validate", copy}).exit_code, 0);

    const CliResult fit = run_flowvid({"fit", "cloth", "--capture", copy, "--fit-to", "tracks", "--out", dir + "/back.fabric.json",
                                       "--evaluations", "24", "--variability-runs", "0", "--resolution", "8x8", "--json"});
    ASSERT_EQ(fit.exit_code, 0) << fit.err;
    const nlohmann::json summary = nlohmann::json::parse(fit.out);
    EXPECT_EQ(summary["fit_to"], "tracks");
    // Tracks fits default to the capacity study's weighting (20 waving frames, half-life 5).
    EXPECT_EQ(summary["waving_frames"], 20);
    EXPECT_EQ(summary["half_life_frames"], 5.0);
    EXPECT_EQ(summary["static_weight"], 1.0);
    const double start_rms = std::sqrt(summary["trials"][0]["start_error"].get<double>());
    const double final_rms = summary["trials"][0]["final_rms_mm"].get<double>();
    std::printf("[measured] tracks fit of our own drape: RMS %.3f mm (start %.1f mm)\n", final_rms, start_rms);
    EXPECT_LT(final_rms, 1.0);
    EXPECT_GT(start_rms, 5.0) << "the start must miss for the check to mean anything";
    // Its fabric reads the shear on the cells (share 1), and its floor is
    // reported: the floor's members keep that share (a member moved past 1
    // was refused, which lost the floor whenever the draws moved it up;
    // ClothFloor.MembersKeepTheCellShareAndStayValid).
    EXPECT_EQ(summary["shear_cell_fraction"], 1.0);
    EXPECT_TRUE(summary["trials"][0]["floor"].is_number()) << fit.err;
    EXPECT_EQ(fit.err.find("no predictability floor"), std::string::npos) << fit.err;
    const flowvid::formats::FabricPreset back = flowvid::formats::read_fabric_preset(dir + "/back.fabric.json");
    EXPECT_EQ(back.provenance.metric, "tracks_mean_square_mm2");

    // A second drape mesh: the drape is also fitted on 6x6, whose error the
    // total carries beside the trial's own (the tracks came from 8x8, so a
    // 6x6 drape misses them), and the preset says so.
    const CliResult both = run_flowvid({"fit", "cloth", "--capture", copy, "--fit-to", "tracks", "--out", dir + "/both.fabric.json",
                                        "--evaluations", "12", "--variability-runs", "0", "--resolution", "8x8",
                                        "--second-drape-mesh", "6x6", "--json"});
    ASSERT_EQ(both.exit_code, 0) << both.err;
    const nlohmann::json both_summary = nlohmann::json::parse(both.out);
    EXPECT_EQ(both_summary["second_drape_mesh"], "6x6");
    const double own_mesh = both_summary["trials"][0]["final_error"].get<double>();
    EXPECT_GT(both_summary["final_error"].get<double>(), own_mesh + 0.01) << "the 6x6 drape's error is in the total";
    const flowvid::formats::FabricPreset both_preset = flowvid::formats::read_fabric_preset(dir + "/both.fabric.json");
    EXPECT_EQ(both_preset.provenance.metric_weights.at("second_drape_mesh_rows"), 6.0);
    const CliResult bad_mesh = run_flowvid({"fit", "cloth", "--capture", copy, "--fit-to", "tracks", "--out",
                                            dir + "/bad.fabric.json", "--second-drape-mesh", "6 by 6"});
    EXPECT_NE(bad_mesh.exit_code, 0);
    EXPECT_NE(bad_mesh.err.find("--second-drape-mesh"), std::string::npos) << bad_mesh.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/bad.fabric.json"));

    // --hold KEY=VALUE: the shear held near zero is the preset's, the rest fitted;
    // a value no preset can hold is refused before anything is written.
    const CliResult held = run_flowvid({"fit", "cloth", "--capture", copy, "--fit-to", "tracks", "--out", dir + "/held.fabric.json",
                                        "--evaluations", "12", "--variability-runs", "0", "--resolution", "8x8",
                                        "--hold", "shear_stiffness_N_per_m=1e-6", "--json"});
    ASSERT_EQ(held.exit_code, 0) << held.err;
    const flowvid::formats::FabricPreset held_preset = flowvid::formats::read_fabric_preset(dir + "/held.fabric.json");
    EXPECT_DOUBLE_EQ(held_preset.parameters.shear_stiffness_N_per_m.value, 1e-6);
    EXPECT_EQ(nlohmann::json::parse(held.out)["held_parameters"], nlohmann::json::array({"shear_stiffness_N_per_m=1e-6"}));
    const CliResult refused = run_flowvid({"fit", "cloth", "--capture", copy, "--fit-to", "tracks", "--out",
                                           dir + "/refused.fabric.json", "--hold", "shear_stiffness_N_per_m=0"});
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.err.find("--hold"), std::string::npos) << refused.err;
    EXPECT_NE(refused.err.find("shear_stiffness_N_per_m=1e-6"), std::string::npos) << refused.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/refused.fabric.json"));

    // A capture without tracks is refused for a tracks fit, naming the field and the way out.
    const CliResult none = run_flowvid({"fit", "cloth", "--capture", source, "--fit-to", "tracks", "--out", dir + "/x.fabric.json"});
    EXPECT_EQ(none.exit_code, 3);
    EXPECT_NE(none.err.find("capture.json: /tracks"), std::string::npos) << none.err;
    EXPECT_NE(none.err.find("--fit-to footage"), std::string::npos) << none.err;
}

TEST(CliClothFit, ScanFitComparesTheStripesDepthAndSaysSo) {
    // --fit-to scan on the silk drape: the footage's own stripe scan is what
    // the fit compares with (depth along the camera rays, mm), with the
    // tracks fits' frame defaults and a preset that names the metric. The
    // fitted drape's RMS depth error is measured against the scan's accuracy
    // on this capture (the truth itself scores ~2 mm) and the start's. The
    // figure includes the outline term (background pixels the simulation
    // covers, 3 cm each), which a 12x12 mesh's coarse outline pays more of.
    const std::string dir = own_dir("cli_fit_scan");
    const CliResult fit = run_flowvid({"fit", "cloth", "--capture", shared_path("captures/cloth-silk-static-1"), "--fit-to",
                                       "scan", "--out", dir + "/scan.fabric.json", "--evaluations", "16",
                                       "--variability-runs", "0", "--resolution", "12x12", "--json"});
    ASSERT_EQ(fit.exit_code, 0) << fit.err;
    const nlohmann::json summary = nlohmann::json::parse(fit.out);
    EXPECT_EQ(summary["fit_to"], "scan");
    EXPECT_EQ(summary["waving_frames"], 20);
    EXPECT_EQ(summary["half_life_frames"], 5.0);
    const double start_rms = std::sqrt(summary["trials"][0]["start_error"].get<double>());
    const double final_rms = summary["trials"][0]["final_rms_mm"].get<double>();
    std::printf("[measured] scan fit of the silk drape at 12x12: RMS depth error %.2f mm (start %.2f mm)\n", final_rms, start_rms);
    EXPECT_LE(final_rms, start_rms);
    EXPECT_GT(final_rms, 1.0);   // not below the scan's own accuracy
    EXPECT_LT(final_rms, 14.0);  // a drape in the footage's fold state
    const flowvid::formats::FabricPreset fitted = flowvid::formats::read_fabric_preset(dir + "/scan.fabric.json");
    EXPECT_EQ(fitted.provenance.metric, "scan_depth_mean_square_mm2");
    // Whether the 12x12 mesh it was fitted on (27.3 mm edges) holds the
    // fitted fabric's folds: the library's rule on the written preset, in the
    // summary and, where it does not, in a note.
    const flowvid::cloth::FoldCheck folds =
        flowvid::cloth::check_folds(flowvid::cloth::material_from_fabric(fitted.parameters), 0.3 / 11.0);
    EXPECT_NEAR(summary["fitted_mesh_edge_mm"].get<double>(), 300.0 / 11.0, 1e-6);
    EXPECT_NEAR(summary["fold_length_mm"].get<double>(), 1e3 * folds.fold_length_m, 1e-9);
    EXPECT_EQ(summary["fitted_mesh_holds_folds"].get<bool>(), folds.holds_folds);
    EXPECT_EQ(mentions(fit.err, "the preset reproduces the footage's drape on meshes with edges near that"), !folds.holds_folds)
        << fit.err;

    // eval cloth --compare scan scores the preset the same way: an RMS depth
    // error whose square is the drape's weighted error (weight 1), near the
    // fit's. It settles the drape as a prediction does, which on this
    // 16-evaluation fit lands 0.6 mm (the thesis's shear range) to 1.7 mm
    // (the capacity model's wider one, the start registered to the scan)
    // from the fit's own figure. (Registered, the 12x12 starts are nearer
    // their truth -- silk static-1 14.2 mm against 19.0 moved along the
    // rays, flowvid_bench_equilibrium -- but a mesh this coarse scores
    // about 0.5 mm worse on the scan's depth and outline: 13.8 mm after the
    // fit against 12.2, and this figure 15.5 against 13.8.)
    const CliResult eval = run_flowvid({"eval", "cloth", "--preset", dir + "/scan.fabric.json", "--capture",
                                        shared_path("captures/cloth-silk-static-1"), "--compare", "scan", "--resolution",
                                        "12x12", "--floor-members", "0", "--json"});
    ASSERT_EQ(eval.exit_code, 0) << eval.err;
    const nlohmann::json scored = nlohmann::json::parse(eval.out)["captures"][0];
    const double eval_rms = scored["rms_mm"].get<double>();
    std::printf("[measured] eval cloth --compare scan: %.2f mm (the fit's final %.2f mm)\n", eval_rms, final_rms);
    EXPECT_NEAR(eval_rms * eval_rms, scored["weighted_error"].get<double>(), 1e-9 * eval_rms * eval_rms);
    EXPECT_NEAR(eval_rms, final_rms, 2.0);
    EXPECT_LT(eval_rms, 16.0);
    EXPECT_GT(eval_rms, 1.0);
}

TEST(CliClothFit, CmaesSearchIsDeterministicImprovesOnItsStartAndTravelsThroughShards) {
    // --search cmaes on the silk drape at 8x8: the same preset whatever the
    // thread count (a generation is evaluated in parallel), a final error
    // below the start's, the optimizer named in the preset, and
    // a shard that records the search so that the merge finishes it alike.
    const std::string dir = own_dir("cli_fit_cmaes");
    const auto fit = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"fit", "cloth", "--capture", shared_path("captures/cloth-silk-static-1"), "--out", out,
                                         "--search", "cmaes", "--evaluations", "40", "--variability-runs", "0",
                                         "--resolution", "8x8", "--seed", "5", "--json"};
        args.insert(args.end(), extra.begin(), extra.end());
        return run_flowvid(args);
    };
    const CliResult one = fit(dir + "/one.fabric.json", {"--threads", "1"});
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const CliResult two = fit(dir + "/two.fabric.json", {"--threads", "2"});
    ASSERT_EQ(two.exit_code, 0) << two.err;
    const nlohmann::json summary = nlohmann::json::parse(one.out);
    EXPECT_EQ(summary["search"], "cmaes");
    EXPECT_LT(summary["final_error"].get<double>(), summary["start_error"].get<double>());
    const flowvid::formats::FabricPreset a = flowvid::formats::read_fabric_preset(dir + "/one.fabric.json");
    const flowvid::formats::FabricPreset b = flowvid::formats::read_fabric_preset(dir + "/two.fabric.json");
    EXPECT_TRUE(a.parameters == b.parameters) << "the thread count changed the CMA-ES fit";
    EXPECT_EQ(a.provenance.optimizer, "cmaes");

    const CliResult shard = fit(dir + "/shard.json", {"--shard", "1/2"});
    ASSERT_EQ(shard.exit_code, 0) << shard.err;
    const nlohmann::json shard_file = nlohmann::json::parse(read_text(dir + "/shard.json"));
    EXPECT_EQ(shard_file["request"]["options"]["search"], "cmaes") << shard_file.dump();
    const CliResult merged = run_flowvid({"merge", "--out", dir + "/merged.fabric.json", dir + "/shard.json", "--json"});
    EXPECT_NE(merged.exit_code, 0) << "one of two shards is not a whole fit";
    const CliResult other = fit(dir + "/shard2.json", {"--shard", "2/2"});
    ASSERT_EQ(other.exit_code, 0) << other.err;
    const CliResult whole = run_flowvid({"merge", "--out", dir + "/merged.fabric.json", dir + "/shard.json", dir + "/shard2.json"});
    ASSERT_EQ(whole.exit_code, 0) << whole.err;
    EXPECT_EQ(flowvid::formats::read_fabric_preset(dir + "/merged.fabric.json").provenance.optimizer, "cmaes");
}

TEST(CliClothFit, StartRefinesAPresetAndStaysOutOfShards) {
    // --start: the fit begins at a preset's fabric instead of the middle of
    // the ranges. Its start error is then that preset's own error on the
    // capture (eval cloth scores the same drape from the same fabric), and the
    // fit keeps it when it finds nothing better. Angle maps: the example
    // preset has no capacity terms, which a scan fit's start would clamp into
    // their ranges (a hem of at least 1e-5 kg/m), so its start would be
    // another fabric than the preset's.
    const std::string dir = own_dir("cli_fit_start");
    const std::string preset = source_path("formats/examples/cotton.fabric.json");
    const auto fit = [&](const std::vector<std::string>& extra) {
        std::vector<std::string> args = {"fit", "cloth", "--capture", shared_path(kStatic), "--out", dir + "/refined.fabric.json",
                                         "--evaluations", "10", "--variability-runs", "0", "--resolution", "8x8", "--fit-to",
                                         "footage", "--json"};
        args.insert(args.end(), extra.begin(), extra.end());
        return run_flowvid(args);
    };
    const CliResult refined = fit({"--start", preset});
    ASSERT_EQ(refined.exit_code, 0) << refined.err;
    const nlohmann::json summary = nlohmann::json::parse(refined.out);
    EXPECT_EQ(summary["start"], preset);
    const CliResult middle = fit({});
    ASSERT_EQ(middle.exit_code, 0) << middle.err;
    const nlohmann::json from_middle = nlohmann::json::parse(middle.out);
    EXPECT_EQ(from_middle["start"], "middle of the ranges");
    const double start_error = summary["start_error"].get<double>();
    std::printf("[measured] start error from the preset %.4g, from the middle of the ranges %.4g; final %.4g\n", start_error,
                from_middle["start_error"].get<double>(), summary["final_error"].get<double>());
    EXPECT_NE(start_error, from_middle["start_error"].get<double>());
    EXPECT_LE(summary["final_error"].get<double>(), start_error);
    const CliResult eval = run_flowvid({"eval", "cloth", "--preset", preset, "--capture", shared_path(kStatic), "--resolution",
                                        "8x8", "--floor-members", "0", "--compare", "footage", "--json"});
    ASSERT_EQ(eval.exit_code, 0) << eval.err;
    EXPECT_NEAR(nlohmann::json::parse(eval.out)["captures"][0]["weighted_error"].get<double>(), start_error, 1e-6 * start_error);

    const CliResult sharded = fit({"--start", preset, "--shards", "2"});
    EXPECT_EQ(sharded.exit_code, 2);
    EXPECT_NE(sharded.err.find("--start"), std::string::npos) << sharded.err;
    const CliResult missing = fit({"--start", dir + "/no-such.fabric.json"});
    EXPECT_EQ(missing.exit_code, 2);
    EXPECT_NE(missing.err.find("no-such.fabric.json"), std::string::npos) << missing.err;
}

TEST(CliClothFit, RefinementRoundsAreReportedShareTheEvaluationsAndStayOutOfShards) {
    // --refine-rounds 1: a footage fit refines once when its evaluations pay
    // for a design and two generations (static drape: 6 parameters, 7 + 2 x
    // 9 = 25, 40 % of 64); the summary lists each round, and the final error
    // is the last round's best on its own fold states. One round by default.
    const std::string dir = own_dir("cli_fit_rounds");
    const auto fit = [&](const std::vector<std::string>& extra) {
        std::vector<std::string> args = {"fit", "cloth", "--capture", shared_path(kStatic), "--out", dir + "/r.fabric.json",
                                         "--evaluations", "64", "--variability-runs", "0", "--resolution", "8x8", "--fit-to",
                                         "footage", "--json"};
        args.insert(args.end(), extra.begin(), extra.end());
        return run_flowvid(args);
    };
    const CliResult refined = fit({"--refine-rounds", "1"});
    ASSERT_EQ(refined.exit_code, 0) << refined.err;
    const nlohmann::json summary = nlohmann::json::parse(refined.out);
    ASSERT_EQ(summary["rounds"].size(), 2u) << summary.dump(1);
    const nlohmann::json& first = summary["rounds"][0];
    const nlohmann::json& second = summary["rounds"][1];
    EXPECT_DOUBLE_EQ(first["start_error"].get<double>(), summary["start_error"].get<double>());
    EXPECT_LE(first["best_error"].get<double>(), first["start_error"].get<double>());
    EXPECT_LE(second["best_error"].get<double>(), second["start_error"].get<double>());
    EXPECT_DOUBLE_EQ(summary["final_error"].get<double>(), second["best_error"].get<double>());
    EXPECT_EQ(first["evaluations"].get<long long>() + second["evaluations"].get<long long>(), 64 + 1)
        << "the rounds share --evaluations (+ the second round's start)";

    const CliResult single = fit({});
    ASSERT_EQ(single.exit_code, 0) << single.err;
    EXPECT_EQ(nlohmann::json::parse(single.out)["rounds"].size(), 1u);
    const CliResult sharded = fit({"--refine-rounds", "1", "--shards", "2"});
    EXPECT_EQ(sharded.exit_code, 2);
    EXPECT_NE(sharded.err.find("--refine-rounds"), std::string::npos) << sharded.err;
}

TEST(CliClothFit, BadRequestsNameTheProblem) {
    const CliResult rigid = run_flowvid({"fit", "cloth", "--capture", shared_path("captures/rigid-toss-major"), "--out",
                                         own_dir("cli_fit_bad") + "/x.fabric.json"});
    EXPECT_EQ(rigid.exit_code, 3);
    EXPECT_NE(rigid.err.find("/kind"), std::string::npos) << rigid.err;
    const CliResult resolution = run_flowvid({"eval", "cloth", "--preset", source_path("formats/examples/cotton.fabric.json"),
                                              "--capture", shared_path(kStatic), "--resolution", "1x1"});
    EXPECT_EQ(resolution.exit_code, 2);
    EXPECT_NE(resolution.err.find("--resolution 1x1"), std::string::npos) << resolution.err;
}

}  // namespace
