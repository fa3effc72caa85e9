// The cloth-fit objective: material keys, trials loaded from captures, the
// penalty for simulations that fail, and a synthetic recovery: footage
// rendered from our own simulator (Lambertian shading and noise the fit's
// renderer does not have) at a known stretch and bend is fitted back by the
// Halton start + annealing, to within 10 %, with the error at the optimum at
// the noise floor.

#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/optim/annealing.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"
#include "flowvid/video/stripe_render.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

using namespace flowvid;
using namespace flowvid::video;
using namespace flowvid::cloth_fit;

namespace {

formats::Capture capture(const std::string& name) {
    return formats::read_capture(flowvid::testing::shared_path("captures/" + name));
}

// "Plausible cotton" of docs/cloth_model.md.
cloth::ClothMaterial cotton() {
    cloth::ClothMaterial c;
    c.areal_density_kg_per_m2 = 0.15;
    c.stretch_warp_N_per_m = c.stretch_weft_N_per_m = 150.0;
    c.shear_N_per_m = 90.0;
    c.bend_N_m = 3.3e-7;
    c.stretch_warp_damping_N_s_per_m = c.stretch_weft_damping_N_s_per_m = 0.025;
    c.shear_damping_N_s_per_m = 0.012;
    c.bend_damping_N_m_s = 1e-7;
    c.drag_normal_kg_per_m3 = 0.5;
    c.drag_tangential_kg_per_m2_s = 0.16;
    return c;
}

// A static-drape trial of a capture's experiment, its first frame only,
// with nothing to compare yet.
ClothTrial drape_trial(const formats::Capture& c, const std::string& name) {
    ClothTrial trial;
    trial.name = name;
    trial.is_static = true;
    trial.experiment = cloth::experiment_from_capture(c);
    trial.experiment.frame_count = 1;
    for (cloth::PinTrajectory& pin : trial.experiment.pins) pin.positions_m.resize(1);
    return trial;
}

// The silk capture's drape as a one-frame tracks trial whose tracks are the
// capture's truth, handed over in memory as the capacity study does (never
// to a footage fit).
ClothTrial silk_drape_tracks_trial() {
    const formats::Capture drape = capture("cloth-silk-static-1");
    ClothTrial trial = drape_trial(drape, "silk drape");
    trial.frames.resize(1);
    trial.frames[0].number = 1;
    const formats::VertexAnimation truth = *formats::read_capture_truth_positions(drape);
    TrackReference tracks;
    tracks.rows = *truth.grid_rows;
    tracks.cols = *truth.grid_cols;
    tracks.missing_frame_error_mm2 = 1e5;
    tracks.positions_m.push_back(cloth::grid_frames_of(truth).front());
    trial.tracks = tracks;
    return trial;
}

// A fitted silk (soft bending and weft compression): tests/data/cloth/silk.fabric.json.
cloth::ClothMaterial fixture_silk() {
    return cloth::material_from_fabric(
        formats::read_fabric_preset(flowvid::testing::source_path("tests/data/cloth/silk.fabric.json")).parameters);
}

}  // namespace

TEST(ClothFit, MaterialKeysAndTies) {
    cloth::ClothMaterial m = cotton();
    set_material_parameter(m, "stretch_stiffness_N_per_m", 77.0);
    EXPECT_EQ(m.stretch_warp_N_per_m, 77.0);
    EXPECT_EQ(m.stretch_weft_N_per_m, 77.0);
    set_material_parameter(m, "bend_stiffness_N_m", 2e-6);
    EXPECT_EQ(m.bend_N_m, 2e-6);
    set_material_parameter(m, "stretch_damping_N_s_per_m", 0.5);
    EXPECT_EQ(m.stretch_weft_damping_N_s_per_m, 0.5);
    EXPECT_EQ(material_parameter(m, "drag_normal_kg_per_m3"), 0.5);
    EXPECT_EQ(m.shear_N_per_m, 90.0);  // untouched
    try {
        set_material_parameter(m, "bend_stiffnes_N_m", 1.0);
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("bend_stiffnes_N_m"), std::string::npos);
    }
    EXPECT_EQ(static_test_parameters().size(), 6u);
    EXPECT_EQ(waving_test_parameters().size(), 9u);
    EXPECT_THROW(ClothFitProblem({}, static_test_parameters(), {}), std::invalid_argument);
    // A bending floor raises only bending's lower bound (and its upper bound to 10x the floor).
    const std::vector<FittedParameter> floored = with_bending_floor(waving_test_parameters(), 1e-5);
    const std::vector<FittedParameter> plain = waving_test_parameters();
    ASSERT_EQ(floored.size(), plain.size());
    for (std::size_t i = 0; i < plain.size(); ++i) {
        const bool bend = plain[i].key == "bend_stiffness_N_m";
        EXPECT_EQ(floored[i].lower, bend ? 1e-5 : plain[i].lower) << plain[i].key;
        EXPECT_EQ(floored[i].upper, bend ? std::max(plain[i].upper, 1e-4) : plain[i].upper) << plain[i].key;
    }
    EXPECT_EQ(with_bending_floor(plain, 1e-3)[2].upper, 1e-2);
    EXPECT_EQ(with_bending_floor(plain, 0.0)[2].lower, plain[2].lower);
    // The capacity terms add five parameters to the waving set and replace
    // one range: shear goes below the thesis's floor once the diagonal
    // fibres are fitted; every other range stays where it was.
    const std::vector<FittedParameter> capacity = with_terms(plain, capacity_terms(true, DragModel::nonlinear));
    ASSERT_EQ(capacity.size(), 14u);
    for (std::size_t i = 0; i < plain.size(); ++i) {
        EXPECT_EQ(capacity[i].key, plain[i].key);
        const bool shear = plain[i].key == "shear_stiffness_N_per_m";
        EXPECT_EQ(capacity[i].lower, shear ? kShearFloorWithDiagonalFibres_N_per_m : plain[i].lower) << plain[i].key;
        EXPECT_EQ(capacity[i].upper, plain[i].upper) << plain[i].key;
    }
    EXPECT_LT(kShearFloorWithDiagonalFibres_N_per_m, plain[1].lower);
    EXPECT_EQ(capacity.back().key, "diagonal_tension_stiffness_N_per_m");
    // Fit targets by their command-line names, both ways.
    for (const FitTarget target : {FitTarget::footage, FitTarget::scan, FitTarget::tracks})
        EXPECT_EQ(fit_target_from_name(fit_target_name(target)), target);
    EXPECT_FALSE(fit_target_from_name("Scan").has_value());
}

TEST(ClothFit, LoadsTrialsFromCaptures) {
    const ClothTrial still = load_trial(capture("cloth-cotton-static-1"));
    EXPECT_TRUE(still.is_static);
    ASSERT_EQ(still.frames.size(), 1u);
    EXPECT_EQ(still.experiment.frame_count, 1);
    EXPECT_EQ(still.experiment.pins[0].positions_m.size(), 1u);
    EXPECT_GT(still.frames[0].angles.valid_count(), 15000);

    TrialLoadSettings settings;
    settings.waving_frames = 6;
    settings.full_weight_frames = 2;
    settings.half_life_frames = 2.0;
    const ClothTrial waving = load_trial(capture("cloth-cotton-waving-1"), settings);
    EXPECT_FALSE(waving.is_static);
    ASSERT_EQ(waving.frames.size(), 6u);
    EXPECT_EQ(waving.frames[5].number, 6);
    EXPECT_EQ(waving.frames[1].weight, 1.0);
    EXPECT_NEAR(waving.frames[5].weight, std::exp2(-2.0), 1e-12);
    EXPECT_EQ(waving.experiment.frame_count, 8);  // two more for the pins' spline
    EXPECT_EQ(waving.experiment.pins[1].positions_m.size(), 8u);

    // The static weight scales the drape's frames only.
    settings.static_weight = 2.5;
    EXPECT_EQ(load_trial(capture("cloth-cotton-static-1"), settings).frames[0].weight, 2.5);
    const ClothTrial same_waving = load_trial(capture("cloth-cotton-waving-1"), settings);
    EXPECT_EQ(same_waving.frames[1].weight, 1.0);
    EXPECT_NEAR(same_waving.frames[5].weight, std::exp2(-2.0), 1e-12);
}

// A fabric that cannot hang (negative stretch stiffness): no equilibrium, so
// every compared frame costs the largest error, a finite number the
// optimizer ranks last, not an exception.
TEST(ClothFit, FailedSimulationsCostTheLargestError) {
    ClothFitSettings settings;
    settings.swatch.rows = settings.swatch.cols = 8;
    settings.base = cotton();
    settings.warm_start = false;
    const ClothFitProblem problem({load_trial(capture("cloth-cotton-static-1"))}, static_test_parameters(), settings);
    cloth::ClothMaterial broken = cotton();
    broken.stretch_warp_N_per_m = broken.stretch_weft_N_per_m = -100.0;
    broken.shear_N_per_m = -100.0;
    const ClothEvaluation e = problem.evaluate(broken);
    ASSERT_EQ(e.trials.size(), 1u);
    EXPECT_FALSE(e.trials[0].report.ok());
    EXPECT_EQ(e.trials[0].simulated_frames, 0);
    const double worst = missing_frame_error(problem.trials()[0].frames[0], settings.metric);
    EXPECT_DOUBLE_EQ(e.total, worst);
    EXPECT_GT(worst, problem.evaluate(cotton()).total);
}

TEST(ClothFit, RecoversStretchAndBendFromSyntheticFootage) {
    const formats::Capture c = capture("cloth-cotton-static-1");
    ClothTrial trial = drape_trial(c, "synthetic static");
    trial.camera = *c.camera;
    trial.projector = *c.projector;
    trial.angle_map = AngleMapSettings::for_stripe_period(expected_stripe_period_px(c));

    ClothFitSettings settings;
    settings.swatch.rows = settings.swatch.cols = 12;
    settings.base = cotton();
    cloth::ClothMaterial truth = cotton();
    truth.stretch_warp_N_per_m = truth.stretch_weft_N_per_m = 60.0;
    truth.bend_N_m = 2e-6;

    // The footage: our simulator at the true material, rendered with shading
    // and background the fit's renderer does not use, plus noise sigma 0.02.
    {
        const ClothFitProblem generator({trial}, {{"bend_stiffness_N_m", 1e-9, 1e-4, true}}, settings);
        const cloth::SwatchRun run = generator.simulate(0, truth);
        ASSERT_TRUE(run.equilibrium.converged);
        StripeRenderSettings look;
        look.shading = StripeShading::lambertian;
        look.background = 0.1f;
        StripeRenderer renderer(trial.camera, trial.projector, look);
        StripeImage footage = renderer.render(vertices_from_vector(run.simulation.frames[0]), run.swatch.mesh.triangles);
        std::mt19937 rng(5);
        std::normal_distribution<float> noise(0.0f, 0.02f);
        for (float& v : footage.image.pixels) v += noise(rng);
        video::ReferenceFrame reference;
        reference.number = 1;
        reference.silhouette = footage.silhouette;
        AngleMapper(trial.angle_map).compute(footage.image, footage.silhouette, reference.angles);
        trial.frames.push_back(reference);
    }

    const ClothFitProblem problem({trial},
                                  {{"stretch_stiffness_N_per_m", 10.0, 1e4, true}, {"bend_stiffness_N_m", 1e-9, 1e-4, true}},
                                  settings);
    const double floor = problem.evaluate(truth).total;  // noise and shading only
    optim::MinimizeSettings fit;
    fit.threads = 2;
    fit.design_points = 16;
    // 120 evaluations reached the floor (within 10 %) at 1 of 4 annealing
    // seeds once the equilibrium's definite steps were factorised (the
    // objective is as rough as before: its candidates settle in other
    // nearby equilibria than with CG, so the search takes another path);
    // 160 at all 4 (E 5.89-6.24 against 6.25).
    fit.annealing.max_evaluations = 160;
    fit.annealing.evaluations_per_stage = 6;
    fit.annealing.fit_schedule_to_budget = true;
    const auto start = std::chrono::steady_clock::now();
    const optim::MinimizeResult r = optim::minimize(problem.objective(), problem.space(), fit);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double stretch = r.annealing.best_values(0), bend = r.annealing.best_values(1);
    std::printf("[measured] synthetic static fit: stretch %.2f N/m (truth 60, %+.1f %%), bend %.3g N m (truth 2e-6, "
                "%+.1f %%), E %.2f vs noise floor %.2f (start %.2f, base material %.2f), %lld evaluations, %.1f s\n",
                stretch, 100 * (stretch / 60 - 1), bend, 100 * (bend / 2e-6 - 1), r.annealing.best_value, floor,
                r.design.best_value(), problem.evaluate(settings.base).total, r.evaluations, seconds);
    EXPECT_NEAR(stretch, 60.0, 6.0);
    EXPECT_NEAR(bend, 2e-6, 2e-7);
    EXPECT_LE(r.annealing.best_value, 1.1 * floor);
}

// A fitted material becomes a valid fabric preset: ranges of the fitted
// parameters, the variability analysis's spread as uncertainty, provenance.
TEST(ClothFit, WritesAFittedPresetWithUncertainty) {
    ClothFitSettings settings;
    settings.swatch.rows = settings.swatch.cols = 8;
    settings.base = cotton();
    settings.warm_start = false;
    const formats::Capture c = capture("cloth-cotton-static-1");
    const ClothFitProblem problem({load_trial(c)}, static_test_parameters(), settings);
    const ClothEvaluation final = problem.evaluate(cotton());
    optim::VariabilityReport variability;
    for (const optim::Parameter& p : problem.space().parameters()) {
        optim::ParameterVariability v;
        v.name = p.name;
        v.stddev = 0.1 * material_parameter(cotton(), p.name);
        variability.parameters.push_back(v);
    }
    const formats::FabricPreset preset = fitted_preset("cotton (test)", problem, {c}, cotton(), final, 7, &variability);
    const std::string path = flowvid::testing::scratch_dir("cloth_fit_preset") + "/cotton.fabric.json";
    formats::write_fabric_preset(path, preset);
    const formats::FabricPreset back = formats::read_fabric_preset(path);
    EXPECT_EQ(back.parameters.bend_stiffness_N_m.value, 3.3e-7);
    ASSERT_TRUE(back.parameters.bend_stiffness_N_m.uncertainty.has_value());
    EXPECT_NEAR(*back.parameters.bend_stiffness_N_m.uncertainty, 3.3e-8, 1e-20);
    ASSERT_TRUE(back.parameters.stretch_weft_stiffness_N_per_m.range.has_value());
    EXPECT_EQ((*back.parameters.stretch_weft_stiffness_N_per_m.range)[1], 1e4);
    EXPECT_FALSE(back.parameters.drag_normal_kg_per_m3.uncertainty.has_value());  // not fitted
    ASSERT_EQ(back.provenance.captures.size(), 1u);
    EXPECT_EQ(back.provenance.captures[0].capture_json_sha256, c.capture_json_sha256);
    EXPECT_EQ(back.provenance.captures[0].test, "static");
    ASSERT_EQ(back.provenance.final_errors.size(), 1u);
    EXPECT_DOUBLE_EQ(back.provenance.final_errors[0].error, final.trials[0].error);
    EXPECT_EQ(back.provenance.seed, 7u);
}

TEST(ClothFit, RecoversStretchAndBendFromSynthetic3dTracks) {
    // A static drape of our own simulator at a known material, measured as
    // 3D tracks on a 9 x 9 uv grid with 0.3 mm noise and a few unseen points
    // (NaN), is fitted back: the tracks metric sees the shape itself, folds
    // included, where the angle map sees stripe orientation. The warp's
    // compression ratio is fitted too but a drape this lightly loaded hardly
    // pins it (printed, not checked): the waving tests must.
    ClothTrial trial;
    trial.name = "synthetic tracks";
    trial.is_static = true;
    trial.experiment.width_m = trial.experiment.height_m = 0.3;
    trial.experiment.mass_kg = 0.0135;
    trial.experiment.fps = 30.0;
    trial.experiment.frame_count = 1;
    trial.experiment.pins = {{Eigen::Vector2d(0.0, 1.0), {Eigen::Vector3d(-0.09, 0.0, 1.2)}},
                             {Eigen::Vector2d(1.0, 1.0), {Eigen::Vector3d(0.09, 0.0, 1.2)}}};
    trial.frames.resize(1);
    trial.frames[0].number = 1;

    ClothFitSettings settings;
    settings.swatch.rows = settings.swatch.cols = 12;
    settings.base = cotton();
    cloth::ClothMaterial truth = cotton();
    truth.stretch_warp_N_per_m = truth.stretch_weft_N_per_m = 60.0;
    truth.bend_N_m = 2e-6;
    truth.stretch_warp_compression_ratio = 0.05;  // the weft stays symmetric (1), as the fit holds it

    TrackReference tracks;
    tracks.rows = tracks.cols = 9;
    tracks.missing_frame_error_mm2 = 1e5;
    {
        ClothTrial unmeasured = trial;
        unmeasured.frames.clear();  // nothing to compare yet
        const ClothFitProblem generator({unmeasured}, {{"bend_stiffness_N_m", 1e-9, 1e-4, true}}, settings);
        const cloth::SwatchRun run = generator.simulate(0, truth);
        ASSERT_TRUE(run.equilibrium.converged);
        Eigen::MatrixX3d measured = cloth::UvSampler(run.swatch.mesh, 9, 9).sample(run.simulation.frames[0]);
        std::mt19937 rng(3);
        std::normal_distribution<double> noise(0.0, 3e-4);
        for (Eigen::Index i = 0; i < measured.rows(); ++i)
            for (int k = 0; k < 3; ++k) measured(i, k) += noise(rng);
        for (const int unseen : {3, 40, 41, 77}) measured.row(unseen).setConstant(std::numeric_limits<double>::quiet_NaN());
        tracks.positions_m.push_back(measured);
    }
    trial.tracks = tracks;

    const ClothFitProblem problem({trial},
                                  {{"stretch_stiffness_N_per_m", 10.0, 1e4, true},
                                   {"bend_stiffness_N_m", 1e-9, 1e-4, true},
                                   {"stretch_warp_compression_ratio", 1e-3, 1.0, true}},
                                  settings);
    const double floor = problem.evaluate(truth).total;  // the noise alone, about (0.3 mm)^2 * 3
    optim::MinimizeSettings fit;
    fit.threads = 2;
    fit.design_points = 24;
    fit.annealing.max_evaluations = 160;
    fit.annealing.evaluations_per_stage = 8;
    fit.annealing.fit_schedule_to_budget = true;
    const optim::MinimizeResult r = optim::minimize(problem.objective(), problem.space(), fit);
    const double stretch = r.annealing.best_values(0), bend = r.annealing.best_values(1), ratio = r.annealing.best_values(2);
    const double rms = tracks_rms_mm(problem.trials()[0], r.annealing.best_value);
    std::printf("[measured] synthetic tracks fit: stretch %.1f N/m (truth 60), bend %.3g N m (truth 2e-6), warp compression "
                "ratio %.3g (truth 0.05, weft held at 1), RMS %.2f mm vs noise %.2f mm (base material %.2f mm), %lld evaluations\n",
                stretch, bend, ratio, rms, tracks_rms_mm(problem.trials()[0], floor),
                tracks_rms_mm(problem.trials()[0], problem.evaluate(settings.base).total), r.evaluations);
    EXPECT_NEAR(bend, 2e-6, 4e-7);
    EXPECT_NEAR(stretch, 60.0, 9.0);
    EXPECT_LE(rms, 1.5 * tracks_rms_mm(problem.trials()[0], floor) + 0.2);
    EXPECT_GT(tracks_rms_mm(problem.trials()[0], problem.evaluate(settings.base).total), 5.0 * rms)
        << "the base material must be far off for the recovery to mean anything";
}

TEST(ClothFit, ATracksFitScoresTheDrapeItsPredictionStartsFrom) {
    // Hung silk this floppy has many equilibria. A prediction settles a
    // fabric into the one nearest the measured first frame; the fit must
    // score that same drape. Settled instead from the base fabric's own
    // equilibrium, a fabric lands in another fold and the fit tunes a drape
    // no prediction shows. The measured shape here is the capture's truth,
    // handed over as tracks in memory as the capacity study does (never to a
    // footage fit).
    const ClothTrial trial = silk_drape_tracks_trial();

    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    settings.candidate_bows = {1.0};  // and the measured shape
    settings.base = middle_of_ranges(settings.base, capacity_terms(true, DragModel::nonlinear));
    const cloth::ClothMaterial silk = fixture_silk();

    const double predicted = assess_trial(trial, silk, settings, std::nullopt, nullptr).frames.at(0).total;
    const ClothFitProblem problem({trial}, {{"bend_stiffness_N_m", 1e-9, 1e-4, true}}, settings);
    const double scored = problem.evaluate(silk).trials.at(0).error;
    settings.warm_start_from_measurement = false;
    const double from_base = ClothFitProblem({trial}, {{"bend_stiffness_N_m", 1e-9, 1e-4, true}}, settings).evaluate(silk).trials.at(0).error;
    std::printf("[measured] silk drape, mean square distance: predicted %.1f mm^2, scored by the fit %.1f, settled from the "
                "base fabric's equilibrium %.1f\n",
                predicted, scored, from_base);
    EXPECT_NEAR(scored, predicted, 1e-6 * predicted);
    EXPECT_GT(std::abs(from_base - predicted), 0.03 * predicted) << "the two starts must differ for the check to mean anything";
}

TEST(ClothFit, ASecondDrapeMeshScoresTheDrapeOnThatMeshToo) {
    // A fit that sees one mesh can pick a fabric whose drape holds on that
    // mesh alone. With a second drape mesh, each static drape is also
    // simulated on it and compared with the same measurements: its error
    // must be what a prediction on that mesh scores, counted in the total
    // and in the least-squares residuals.
    ClothTrial trial = silk_drape_tracks_trial();
    const TrackReference& tracks = *trial.tracks;

    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    settings.swatch.rows = settings.swatch.cols = 16;
    settings.candidate_bows = {1.0};  // and the measured shape
    settings.base = middle_of_ranges(settings.base, capacity_terms(true, DragModel::nonlinear));
    const cloth::ClothMaterial silk = fixture_silk();
    const std::vector<FittedParameter> bending = {{"bend_stiffness_N_m", 1e-9, 1e-4, true}};

    ClothFitSettings coarse = settings;
    coarse.swatch.rows = coarse.swatch.cols = 8;
    const double on_coarse_mesh = assess_trial(trial, silk, coarse, std::nullopt, nullptr).frames.at(0).total;
    const double on_fit_mesh = assess_trial(trial, silk, settings, std::nullopt, nullptr).frames.at(0).total;

    settings.second_drape_rows = settings.second_drape_cols = 8;
    const ClothFitProblem problem({trial}, bending, settings);
    const ClothEvaluation evaluation = problem.evaluate(silk);
    const TrialEvaluation& scored = evaluation.trials.at(0);
    std::printf("[measured] silk drape on 16x16 / 8x8 meshes, mean square distance: %.1f / %.1f mm^2\n", scored.error,
                scored.second_mesh_error);
    EXPECT_NEAR(scored.error, on_fit_mesh, 1e-6 * on_fit_mesh);
    EXPECT_NEAR(scored.second_mesh_error, on_coarse_mesh, 1e-6 * on_coarse_mesh);
    EXPECT_GT(std::abs(on_coarse_mesh - on_fit_mesh), 0.03 * on_fit_mesh) << "the two meshes must differ for the check to mean anything";
    EXPECT_NEAR(evaluation.total, scored.error + scored.second_mesh_error, 1e-12 * evaluation.total);
    const Eigen::VectorXd r = problem.residuals(silk);
    EXPECT_NEAR(r.squaredNorm(), evaluation.total, 1e-9 * evaluation.total);
    EXPECT_EQ(r.size(), 2 * 3 * tracks.rows * tracks.cols) << "both meshes' entries, every point seen";

    // Waving trials keep one mesh: their cost is the fit's.
    trial.is_static = false;
    EXPECT_FALSE(ClothFitProblem({trial}, bending, settings).has_second_mesh(0));
}

TEST(ClothFit, AFitCutsAFarOffCandidatesEquilibriumShortButAPredictionDoesNot) {
    // A fit's candidates settle from a nearby warm start, so one that needs
    // more than the fit's 400 Newton iterations is far off and scores as a
    // failed run instead of costing the search seconds. A prediction of the
    // same fabric must still get its full solve. Here the "far" start is the
    // flat hanging swatch (no warm start), from which this soft silk needs
    // more than 400 iterations.
    const ClothTrial trial = silk_drape_tracks_trial();
    const TrackReference& tracks = *trial.tracks;
    const cloth::ClothMaterial silk = fixture_silk();
    const std::vector<FittedParameter> bending = {{"bend_stiffness_N_m", 1e-9, 1e-4, true}};
    ClothFitSettings settings;
    settings.swatch.simulation.integrator = cloth::Integrator::implicit_euler;
    settings.warm_start = false;

    // CG definite steps: factorised ones (the default on this mesh) settle
    // this silk from the flat start in fewer than 400 iterations.
    settings.swatch.equilibrium.factorised_max_free_vertices = 0;
    settings.evaluation_equilibrium_iterations = 0;  // the simulator's own limit
    const cloth::SwatchRun full = ClothFitProblem({trial}, bending, settings).simulate(0, silk);
    std::printf("[measured] silk drape from the flat start: %d Newton iterations\n", full.equilibrium.iterations);
    ASSERT_TRUE(full.equilibrium.converged) << full.equilibrium.reason;
    ASSERT_GT(full.equilibrium.iterations, 400) << "the case this test is for";

    settings.evaluation_equilibrium_iterations = 400;  // the default
    const ClothFitProblem problem({trial}, bending, settings);
    const TrialEvaluation cut = problem.evaluate(silk).trials.at(0);
    EXPECT_EQ(cut.simulated_frames, 0);
    EXPECT_DOUBLE_EQ(cut.error, tracks.missing_frame_error_mm2);
    const double predicted = assess_trial(trial, silk, settings, std::nullopt, nullptr).frames.at(0).total;
    EXPECT_LT(predicted, 0.1 * tracks.missing_frame_error_mm2) << "the prediction solves to the end";
}

TEST(ClothFit, ATracksFitWeighsEachDrapeAsMuchAsAWavingTest) {
    TrialLoadSettings load;
    load.target = FitTarget::tracks;
    load.waving_frames = 20;
    load.full_weight_frames = 10;
    load.half_life_frames = 5.0;
    // Ten frames of weight 1, then 2^(-j/5) for j = 1..10: a geometric sum.
    const double ratio = std::pow(2.0, -0.2);
    const double expected = 10.0 + ratio * (1.0 - std::pow(ratio, 10)) / (1.0 - ratio);
    EXPECT_NEAR(balanced_static_weight(load), expected, 1e-12);
    const std::vector<formats::Capture> both = {capture("cloth-silk-static-1"), capture("cloth-silk-waving-1")};
    EXPECT_NEAR(default_static_weight(load, both), expected, 1e-12);
    EXPECT_EQ(default_static_weight(load, {capture("cloth-silk-static-1")}), 1.0) << "a drape alone has nothing to balance";
    load.target = FitTarget::scan;
    EXPECT_EQ(default_static_weight(load, both), 1.0);
    load.target = FitTarget::footage;
    EXPECT_EQ(default_static_weight(load, both), 1.0);
}

namespace {
// A small fit of bending and stretch to the cotton drape on an 8 x 8 mesh.
ClothFitRequest small_drape_fit(long long evaluations) {
    ClothFitRequest request;
    request.captures = {capture("cloth-cotton-static-1")};
    request.problem.swatch.rows = request.problem.swatch.cols = 8;
    request.parameters = {{"bend_stiffness_N_m", 1e-8, 1e-5, true}, {"stretch_stiffness_N_per_m", 10.0, 1e4, true}};
    request.evaluations = evaluations;
    request.variability_runs = 0;
    request.threads = 2;
    return request;
}
}  // namespace

TEST(ClothFit, AGivenStartIsWhereTheFitBeginsClampedIntoTheRanges) {
    // ClothFitRequest::start (refining an earlier fit): the fit starts from
    // that fabric, its fitted values clamped into their ranges, its other
    // values kept; without it, from the middle of the ranges.
    ClothFitRequest request = small_drape_fit(10);
    request.polish_evaluations = 0;
    cloth::ClothMaterial start = cotton();
    start.bend_N_m = 1e-3;              // above its range: clamped to 1e-5
    start.stretch_warp_N_per_m = 80.0;  // inside
    start.stretch_weft_N_per_m = 80.0;
    start.shear_N_per_m = 77.0;         // not fitted: kept
    request.start = start;
    const ClothFitOutcome given = fit_cloth(request);
    EXPECT_EQ(given.rounds.size(), 1u) << "10 evaluations pay for no refinement round (a design and two generations)";
    EXPECT_DOUBLE_EQ(given.start.bend_N_m, 1e-5);
    EXPECT_DOUBLE_EQ(given.start.stretch_warp_N_per_m, 80.0);
    EXPECT_DOUBLE_EQ(given.start.shear_N_per_m, 77.0);
    EXPECT_LE(given.final_evaluation.total, given.start_evaluation.total);  // the search keeps a start it cannot beat

    request.start.reset();
    const ClothFitOutcome middle = fit_cloth(request);
    EXPECT_NEAR(middle.start.bend_N_m, std::sqrt(1e-8 * 1e-5), 1e-12);
    EXPECT_NEAR(middle.start.stretch_warp_N_per_m, std::sqrt(10.0 * 1e4), 1e-9);
}

TEST(ClothFit, AHeldParameterIsLeftOutAndKeepsItsStartValue) {
    // ClothFitRequest::held_parameters (`fit cloth --hold`): an ablation, e.g.
    // a fabric fitted without soft compression for the gap diagnosis.
    ClothFitRequest request = small_drape_fit(8);
    request.polish_evaluations = 0;
    request.parameters.push_back({"stretch_warp_compression_ratio", 1e-3, 1.0, true});
    request.held_parameters = {"stretch_warp_compression_ratio", "bend_stiffness_N_m"};
    const ClothFitOutcome held = fit_cloth(request);
    ASSERT_EQ(held.parameters.size(), 1u);
    EXPECT_EQ(held.parameters.front().key, "stretch_stiffness_N_per_m");
    EXPECT_DOUBLE_EQ(held.fitted.stretch_warp_compression_ratio, 1.0);  // the neutral value it started from
    EXPECT_DOUBLE_EQ(held.fitted.bend_N_m, cloth::ClothMaterial{}.bend_N_m);
    EXPECT_NE(held.fitted.stretch_warp_N_per_m, cloth::ClothMaterial{}.stretch_warp_N_per_m);  // the fitted one moved

    // KEY=VALUE holds it at that value: the start and the fitted fabric have it.
    request.held_parameters = {"stretch_warp_compression_ratio", "bend_stiffness_N_m=3e-7"};
    const ClothFitOutcome held_at = fit_cloth(request);
    ASSERT_EQ(held_at.parameters.size(), 1u);
    EXPECT_EQ(held_at.start.bend_N_m, 3e-7);
    EXPECT_EQ(held_at.fitted.bend_N_m, 3e-7);
    EXPECT_NE(held_at.fitted.stretch_warp_N_per_m, held.fitted.stretch_warp_N_per_m);  // a stiffer fabric fits otherwise

    request.held_parameters = {"shear_stiffness_N_per_m"};  // not fitted here
    try {
        fit_cloth(request);
        ADD_FAILURE() << "holding a parameter the fit does not fit must be refused";
    } catch (const UsageError& e) {
        EXPECT_EQ(e.field(), "--hold");
        EXPECT_NE(e.fix().find("stretch_stiffness_N_per_m"), std::string::npos) << e.fix();
    }
    // Values a preset cannot hold are refused before anything is simulated.
    for (const char* bad : {"bend_stiffness_N_m=soft", "bend_stiffness_N_m=", "bend_stiffness_N_m=-1e-7",
                            "bend_stiffness_N_m=nan", "stretch_stiffness_N_per_m=0"}) {
        request.held_parameters = {bad};
        try {
            fit_cloth(request);
            ADD_FAILURE() << bad << " must be refused";
        } catch (const UsageError& e) {
            EXPECT_EQ(e.field(), "--hold") << bad;
            EXPECT_NE(e.fix().find("=1e-6"), std::string::npos) << e.fix();
        }
    }
}

TEST(ClothFit, ARefinementRoundStartsFromTheFirstRoundsFabricWithItsFoldStates) {
    // With a refinement round, a footage fit searches a second time from its
    // first round's best fabric, whose equilibrium picks the fold states
    // again (the first round's were picked by the middle of the ranges).
    // The second round's start error must be that fabric scored by a
    // problem built afresh with it as the base, its best must not be worse
    // than that start, and the rounds share the evaluations.
    ClothFitRequest request = small_drape_fit(60);
    request.refine_rounds = 1;
    const ClothFitOutcome fit = fit_cloth(request);
    ASSERT_EQ(fit.rounds.size(), 2u);
    const ClothFitRound& first = fit.rounds[0];
    const ClothFitRound& second = fit.rounds[1];

    ClothFitSettings settings = request.problem;
    settings.base = fit.start;
    const ClothFitProblem first_problem(load_trials(request.captures, request.load), request.parameters, settings);
    EXPECT_DOUBLE_EQ(first_problem.evaluate(first.best).total, first.best_error);
    settings.base = first.best;
    const ClothFitProblem refined_problem(load_trials(request.captures, request.load), request.parameters, settings);
    EXPECT_DOUBLE_EQ(refined_problem.evaluate(first.best).total, second.start_error);
    std::printf("[measured] refinement: first round %.4g -> %.4g (%lld evaluations), second %.4g -> %.4g (%lld), final %.4g\n",
                first.start_error, first.best_error, first.evaluations, second.start_error, second.best_error,
                second.evaluations, fit.final_evaluation.total);
    EXPECT_LE(second.best_error, second.start_error);
    EXPECT_DOUBLE_EQ(fit.final_evaluation.total, second.best_error);
    EXPECT_EQ(first.evaluations, 36);  // 60 % of the search
    EXPECT_EQ(second.evaluations, 1 + 24);  // its start, then the rest

    request.refine_rounds = 0;  // the default
    const ClothFitOutcome single = fit_cloth(request);
    ASSERT_EQ(single.rounds.size(), 1u);
    EXPECT_EQ(single.rounds[0].evaluations, 60);
}
