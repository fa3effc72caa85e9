// Scan fits (FitTarget::scan): the footage's own stripe scan as the shape a
// fit compares with. The depth residual against exact triangulation, its
// immunity to a scan region unwrapped a period off, the metric against
// ground truth on a capture (the truth itself scores at the scan's accuracy,
// the truth moved 10 mm scores about 10 mm), the residual vector against the
// objective, and the start taken from the scanned first frame against the
// hanging start's equilibria and registered to the scan against moved onto
// it, all against truth.

#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"
#include "flowvid/video/stripe_render.hpp"
#include "flowvid/video/stripe_scan.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>

using namespace flowvid;
using namespace flowvid::video;
using namespace flowvid::cloth_fit;

namespace {

bool have_capture(const std::string& name) {
    return std::filesystem::exists(flowvid::testing::shared_path("captures/" + name + "/truth/positions.exr"));
}

formats::Capture capture(const std::string& name) {
    return formats::read_capture(flowvid::testing::shared_path("captures/" + name));
}

// RMS (mm) of the scan residuals of one compared frame for a given shape.
double scan_rms_mm(const ClothTrial& trial, std::size_t frame, const std::vector<Eigen::Vector3d>& vertices,
                   const std::vector<std::array<int, 3>>& triangles) {
    StripeRenderSettings settings;
    settings.projector_coordinates = true;
    StripeRenderer renderer(trial.camera, trial.projector, settings);
    const std::vector<double> r = scan_residuals_m(*trial.scan, frame, renderer.render(vertices, triangles));
    double sum = 0.0;
    for (const double v : r) sum += v * v;
    return 1e3 * std::sqrt(sum / static_cast<double>(scan_measured_count(*trial.scan, frame)));
}

// The RMS distance (mm) of a start on the 24x24 swatch mesh from the
// capture's truth at frame 1 (evaluation only); the truth is read once.
std::function<double(const Eigen::VectorXd&)> first_frame_truth_rms_mm(const formats::Capture& c, const ClothTrial& trial) {
    const cloth::GridFrames real = {cloth::grid_frames_of(*formats::read_capture_truth_positions(c)).front()};
    const cloth::Swatch swatch = cloth::build_swatch(trial.experiment, 24, 24);
    const cloth::UvSampler sampler(swatch.mesh, 24, 24);
    return [real, sampler](const Eigen::VectorXd& x) {
        const cloth::GridFrames simulated = {sampler.sample(x)};
        return 1e3 * cloth::rms_distance_per_frame_m(simulated, real).front();
    };
}

}  // namespace

TEST(ClothScanFit, DepthResidualMatchesTriangulationAndIgnoresPeriodSlips) {
    if (!have_capture("cloth-cotton-static-1")) GTEST_SKIP() << "shared captures not available";
    const formats::Capture c = capture("cloth-cotton-static-1");
    const formats::VertexAnimation truth = *formats::read_capture_truth_positions(c);
    const auto triangles = grid_triangles(*truth.grid_rows, *truth.grid_cols);
    StripeRenderSettings render_settings;
    render_settings.projector_coordinates = true;
    StripeRenderer renderer(*c.camera, *c.projector, render_settings);
    const StripeScanner scanner = scanner_for(c);
    // "Measured": the truth's own projector coordinates, every 6th pixel.
    const StripeImage measured = renderer.render(vertices_of_frame(truth, 0), triangles);
    ScanReference scan;
    scan.period_units = c.projector->pattern.period_px;
    scan.samples.emplace_back();
    for (int y = 0; y < measured.projector_coordinate.height; y += 6)
        for (int x = 0; x < measured.projector_coordinate.width; x += 6) {
            const double v = measured.projector_coordinate.at(x, y);
            if (!std::isfinite(v)) continue;
            const double per_unit = (scanner.triangulate({x, y}, v + 0.5) - scanner.triangulate({x, y}, v - 0.5)).norm();
            scan.samples[0].push_back({x, y, v, per_unit});
        }
    ASSERT_GT(scan.samples[0].size(), 300u);
    // The same surface: no residual.
    for (const double r : scan_residuals_m(scan, 0, measured)) ASSERT_NEAR(r, 0.0, 1e-9);
    // The surface 5 mm further along the camera's axis: each residual is the
    // depth difference exact triangulation gives, to the linearisation's error.
    std::vector<Eigen::Vector3d> moved = vertices_of_frame(truth, 0);
    const Eigen::Vector3d axis = c.camera->camera_from_world.block<3, 3>(0, 0).row(2).transpose();  // camera z in world
    for (Eigen::Vector3d& v : moved) v += 0.005 * axis;
    const StripeImage shifted = renderer.render(moved, triangles);
    const std::vector<double> r = scan_residuals_m(scan, 0, shifted);
    double worst = 0.0;  // relative to the exact depth difference
    int compared = 0;
    for (std::size_t i = 0; i < scan.samples[0].size(); ++i) {
        const ScanReference::Sample& s = scan.samples[0][i];
        const double v = shifted.projector_coordinate.at(s.x, s.y);
        if (!std::isfinite(v)) continue;
        const double exact = (scanner.triangulate({s.x, s.y}, v) - scanner.triangulate({s.x, s.y}, s.projector_coordinate)).norm();
        const double expected = scan.cap_m * std::tanh(exact / scan.cap_m);
        worst = std::max(worst, std::abs(std::abs(r[i]) - expected) / expected);
        ++compared;
    }
    std::printf("[ measured ] %d samples 5 mm deeper: |r| within %.2f %% of exact triangulation\n", compared, 100.0 * worst);
    EXPECT_GT(compared, 250);
    EXPECT_LT(worst, 0.03);  // the depth per unit of v_p is taken at the measured point: a linearisation
    // A region the scan unwrapped one period off costs nothing extra.
    ScanReference slipped = scan;
    for (ScanReference::Sample& s : slipped.samples[0]) s.projector_coordinate += scan.period_units;
    const std::vector<double> r_slipped = scan_residuals_m(slipped, 0, shifted);
    for (std::size_t i = 0; i < r.size(); ++i) ASSERT_NEAR(r_slipped[i], r[i], 1e-9);
}

TEST(ClothScanFit, ScanMetricAgainstGroundTruth) {
    if (!have_capture("cloth-cotton-waving-1")) GTEST_SKIP() << "shared captures not available";
    const formats::Capture c = capture("cloth-cotton-waving-1");
    TrialLoadSettings load;
    load.target = FitTarget::scan;
    load.waving_frames = 5;
    const ClothTrial trial = load_trial(c, load);
    ASSERT_TRUE(trial.scan);
    ASSERT_EQ(trial.scan->samples.size(), 5u);
    const formats::VertexAnimation truth = *formats::read_capture_truth_positions(c);
    const auto triangles = grid_triangles(*truth.grid_rows, *truth.grid_cols);
    const Eigen::Vector3d axis = c.camera->camera_from_world.block<3, 3>(0, 0).row(2).transpose();
    for (std::size_t k = 0; k < 5; ++k) {
        EXPECT_GT(trial.scan->samples[k].size(), 3000u);
        std::vector<Eigen::Vector3d> vertices = vertices_of_frame(truth, static_cast<int>(k));
        const double own = scan_rms_mm(trial, k, vertices, triangles);
        for (Eigen::Vector3d& v : vertices) v -= 0.010 * axis;
        const double moved = scan_rms_mm(trial, k, vertices, triangles);
        std::printf("[ measured ] frame %zu: truth scores %.2f mm, truth 10 mm nearer %.2f mm\n", k + 1, own, moved);
        EXPECT_LT(own, 3.5);  // the scan's accuracy: 1-3 mm (docs/cloth_fitting.md)
        EXPECT_GT(moved, 8.0);
        EXPECT_LT(moved, 13.0);
    }
}

// Depth cannot see a swatch slid sideways within its own surface; the
// background band around the footage's outline can.
TEST(ClothScanFit, OutsideBandSeesASidewaysShiftThatDepthMisses) {
    if (!have_capture("cloth-cotton-static-1")) GTEST_SKIP() << "shared captures not available";
    const formats::Capture c = capture("cloth-cotton-static-1");
    TrialLoadSettings load;
    load.target = FitTarget::scan;
    const ClothTrial with_band = load_trial(c, load);
    load.scan_outside.max_px = 0.0;
    const ClothTrial without_band = load_trial(c, load);
    ASSERT_EQ(with_band.scan->outside.size(), 1u);
    EXPECT_GT(with_band.scan->outside[0].size(), 1000u);
    EXPECT_TRUE(without_band.scan->outside.empty());
    // Every band pixel is background in the footage, 1.5-16 px from its outline.
    ClothFootage footage(c);
    const metrics::DistanceField distance = metrics::signed_distance_field(footage.frame(footage.first()).silhouette);
    for (const ScanReference::Pixel& p : with_band.scan->outside[0]) {
        ASSERT_GE(distance.at(p.x, p.y), 1.5);
        ASSERT_LE(distance.at(p.x, p.y), 16.0);
    }
    const formats::VertexAnimation truth = *formats::read_capture_truth_positions(c);
    const auto triangles = grid_triangles(*truth.grid_rows, *truth.grid_cols);
    std::vector<Eigen::Vector3d> vertices = vertices_of_frame(truth, 0);
    const double own_with = scan_rms_mm(with_band, 0, vertices, triangles);
    const double own_without = scan_rms_mm(without_band, 0, vertices, triangles);
    // 15 mm along the camera's own x axis: across the view.
    const Eigen::Vector3d across = c.camera->camera_from_world.block<3, 3>(0, 0).row(0).transpose();
    for (Eigen::Vector3d& v : vertices) v += 0.015 * across;
    const double moved_with = scan_rms_mm(with_band, 0, vertices, triangles);
    const double moved_without = scan_rms_mm(without_band, 0, vertices, triangles);
    std::printf("[ measured ] truth: %.2f mm with the band, %.2f without; 15 mm sideways: %.2f with, %.2f without\n",
                own_with, own_without, moved_with, moved_without);
    EXPECT_LT(own_with - own_without, 0.5);  // the truth stays within its own outline
    // The band adds the cap (30 mm) for each covered background pixel: the
    // shifted swatch covers a strip about 6 px wide along one side.
    EXPECT_GT(moved_with * moved_with - moved_without * moved_without, 25.0);
}

TEST(ClothScanFit, ResidualsMatchTheObjectiveAndTheScannedStartIsNearerTruth) {
    if (!have_capture("cloth-cotton-static-2")) GTEST_SKIP() << "shared captures not available";
    const formats::Capture c = capture("cloth-cotton-static-2");
    TrialLoadSettings load;
    load.target = FitTarget::scan;
    const ClothTrial trial = load_trial(c, load);
    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    // A fabric near the capture's (the capacity study's cotton fit, rounded).
    cloth::ClothMaterial m;
    m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = 55.0;
    m.shear_N_per_m = 163.0;
    m.bend_N_m = 4.9e-8;
    m.stretch_warp_compression_ratio = 0.38;
    m.stretch_weft_compression_ratio = 0.135;
    m.hem_line_density_kg_per_m = 1.6e-3;
    m.diagonal_tension_N_per_m = 10.2;
    settings.base = m;
    const ClothFitProblem problem({trial}, {{"bend_stiffness_N_m", 1e-9, 1e-4, true}}, settings);
    const double total = problem.evaluate(m).total;
    const Eigen::VectorXd r = problem.residuals(m);
    EXPECT_NEAR(r.squaredNorm(), total, 1e-9 * total);
    EXPECT_EQ(static_cast<std::size_t>(r.size()), trial.scan->samples[0].size() + trial.scan->outside[0].size());

    // Start in the scanned fold state, against the hanging start's equilibria.
    const auto truth_rms_mm = first_frame_truth_rms_mm(c, trial);
    const cloth::ClothMaterial with_mass = cloth::experiment_material(trial.experiment, m);
    const Eigen::VectorXd scanned = matching_equilibrium(trial, with_mass, settings);
    ClothTrial unscanned = trial;
    unscanned.scan->first_frame_points_m.clear();
    const Eigen::VectorXd hanging = matching_equilibrium(unscanned, with_mass, settings);
    ASSERT_GT(scanned.size(), 0);
    ASSERT_GT(hanging.size(), 0);
    std::printf("[ measured ] static-2 start against truth: from the scan %.1f mm, best hanging start %.1f mm\n",
                truth_rms_mm(scanned), truth_rms_mm(hanging));
    EXPECT_LT(truth_rms_mm(scanned), 6.0);
    EXPECT_LT(truth_rms_mm(scanned), 0.7 * truth_rms_mm(hanging));
}

TEST(ClothScanFit, SolvingAgainFromAFoundEquilibriumConverges) {
    // A scan fit's cotton (stiff shear, soft compression) on the held-out
    // drape: the scanned start's equilibrium, solved again from itself,
    // stalled at 1.03e-8 of a vertex's weight (tolerance 1e-8) for 400
    // iterations and the prediction failed. At the rounding limit the
    // solver now says converged.
    if (!have_capture("cloth-cotton-static-2")) GTEST_SKIP() << "shared captures not available";
    TrialLoadSettings load;
    load.target = FitTarget::scan;
    const ClothTrial trial = load_trial(capture("cloth-cotton-static-2"), load);
    cloth::ClothMaterial m;
    m.stretch_warp_N_per_m = m.stretch_weft_N_per_m = 303.0;
    m.stretch_warp_damping_N_s_per_m = m.stretch_weft_damping_N_s_per_m = 0.105;
    m.shear_N_per_m = 2840.0;
    m.shear_damping_N_s_per_m = 0.0828;
    m.bend_N_m = 7.17e-7;
    m.bend_damping_N_m_s = 2.58e-11;
    m.stretch_warp_compression_ratio = 0.16;
    m.stretch_weft_compression_ratio = 0.0852;
    m.hem_line_density_kg_per_m = 0.0029;
    m.diagonal_tension_N_per_m = 6.32;
    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    const Eigen::VectorXd start = matching_equilibrium(trial, m, settings);
    ASSERT_GT(start.size(), 0);
    cloth::SwatchOptions options = settings.swatch;
    options.initial_positions = start;
    const cloth::SwatchRun again = cloth::simulate_swatch(trial.experiment, m, options);
    std::printf("[ measured ] solved again: %d iterations, residual %.3g of a vertex's weight\n", again.equilibrium.iterations,
                again.equilibrium.max_residual_over_weight);
    EXPECT_TRUE(again.equilibrium.converged) << again.equilibrium.reason;
    EXPECT_LE(again.equilibrium.iterations, 12);
    EXPECT_LT(again.equilibrium.max_residual_over_weight, 1e-6);
}

TEST(ClothScanFit, RegisteringTheFabricToTheScanStartsItNearerTheTruth) {
    // A fit's start for a waving trial: the middle of the ranges (the fit's
    // own base) settled from the scanned first frame. Registered to the scan
    // first (pulled to the scanned depths, free to slide across the camera
    // rays), it settles at least as near the truth of frame 1 as when the
    // vertices are only moved onto the scan along the rays. Cotton waving-2:
    // 15.0 -> 5.9 mm in docs/cloth_fitting.md (stop 62), when the diagonal
    // fibres were measured across each triangle and locked the moved start's
    // folds; since they are measured on the mesh's own diagonals (stop 70)
    // the moved start settles near as well: 6.9 -> 6.8 mm.
    if (!have_capture("cloth-cotton-waving-2")) GTEST_SKIP() << "shared captures not available";
    const formats::Capture c = capture("cloth-cotton-waving-2");
    TrialLoadSettings load;
    load.target = FitTarget::scan;
    load.waving_frames = 1;
    const ClothTrial trial = load_trial(c, load);
    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    settings.base = middle_of_ranges(settings.base, parameters_for({trial}, DragModel::nonlinear));
    const auto truth_rms_mm = first_frame_truth_rms_mm(c, trial);
    const Eigen::VectorXd registered = matching_equilibrium(trial, settings.base, settings);
    ClothFitSettings unregistered_settings = settings;
    unregistered_settings.scan_registration_rounds = 0;
    const Eigen::VectorXd moved = matching_equilibrium(trial, settings.base, unregistered_settings);
    ASSERT_GT(registered.size(), 0);
    ASSERT_GT(moved.size(), 0);
    std::printf("[ measured ] waving-2 start against truth: registered %.1f mm, moved along the rays %.1f mm\n",
                truth_rms_mm(registered), truth_rms_mm(moved));
    EXPECT_LT(truth_rms_mm(registered), 8.0);
    EXPECT_LE(truth_rms_mm(registered), truth_rms_mm(moved));
}
