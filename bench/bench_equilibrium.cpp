// Static equilibrium solve speed: the definite steps factorised (sparse
// LDL^T) against CG, in one run, on the solves a fit makes.
//
// A fit settles every candidate fabric from the same warm start (the middle
// of the ranges' equilibrium nearest the capture's measured first frame) and
// stops at EquilibriumOptions::max_iterations = 400 per candidate. This bench
// does the same for seeded candidates drawn from the middle half of each
// fitted parameter's range (where a search spends its evaluations), on each
// grid, once with the definite steps factorised and once with CG (the
// default, factorised_max_free_vertices = 0), and prints total time, Newton
// iterations and the ratio. The two solves may settle in different local
// minima of a soft fabric; the largest vertex distance between them is
// printed beside the times.
//
// Which equilibrium a solve settles in matters as much as its speed: a
// fit's start for each trial is the equilibrium nearest the shape the
// footage measured at frame 1 (cloth_fit::matching_equilibrium). With
// --starts, each capture's start is found with each solve and its RMS
// distance to the capture's frame 1 in truth/ is printed (evaluation only:
// nothing here fits).
//
// --fabric PRESET settles the starts with that fabric (a fitted preset,
// as `predict cloth` and `eval cloth` pick theirs) instead of the middle of
// the ranges (as a fit picks its own).
//
// --registration-rounds N and --registration-tolerance-mm X set how the
// starts are registered to the scan (ClothFitSettings::
// scan_registration_rounds, scan_registration_tolerance_m; 0 rounds: moved
// onto the scan along the rays and settled). --starts-only skips the
// candidates' timing.
//
// --max-step-edges sets the factorised steps' limit
// (EquilibriumOptions::factorised_max_step_edges).
//
//   flowvid_bench_equilibrium [--captures DIR,DIR] [--grids 16,24,48] [--candidates N] [--seed N]
//                             [--max-step-edges X] [--starts|--starts-only [--fabric PRESET]
//                             [--registration-rounds N] [--registration-tolerance-mm X]]

#include "flowvid/cloth/swatch.hpp"
#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/cloth_fit/cloth_fit.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "option_value.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace fc = flowvid::cloth;
namespace cf = flowvid::cloth_fit;

namespace {

struct Options {
    std::vector<std::string> captures = {std::string(FLOWVID_SHARED_DIR) + "/captures/cloth-silk-static-1",
                                         std::string(FLOWVID_SHARED_DIR) + "/captures/cloth-silk-waving-1"};
    std::vector<int> grids = {16, 24, 48};
    int candidates = 6;
    std::uint64_t seed = 1;
    bool starts = false;
    double max_step_edges = fc::EquilibriumOptions{}.factorised_max_step_edges;
    std::string fabric;  // the starts' fabric (a preset); empty: the middle of the ranges, as a fit's
    int registration_rounds = cf::ClothFitSettings{}.scan_registration_rounds;
    double registration_tolerance_m = cf::ClothFitSettings{}.scan_registration_tolerance_m;
    bool starts_only = false;  // skip the candidates' timing
};

struct Totals {
    double seconds = 0.0;
    long long iterations = 0;
    int not_converged = 0;
};

}  // namespace

int main(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() { return flowvid::bench::option_value(argc, argv, i); };
        if (a == "--captures") o.captures = flowvid::bench::comma_list(next());
        else if (a == "--grids") {
            o.grids.clear();
            for (const std::string& g : flowvid::bench::comma_list(next())) o.grids.push_back(std::atoi(g.c_str()));
        } else if (a == "--candidates") o.candidates = std::max(1, std::atoi(next().c_str()));
        else if (a == "--seed") o.seed = static_cast<std::uint64_t>(std::atoll(next().c_str()));
        else if (a == "--starts") o.starts = true;
        else if (a == "--fabric") o.fabric = next();
        else if (a == "--max-step-edges") o.max_step_edges = std::atof(next().c_str());
        else if (a == "--registration-rounds") o.registration_rounds = std::atoi(next().c_str());
        else if (a == "--registration-tolerance-mm") o.registration_tolerance_m = 1e-3 * std::atof(next().c_str());
        else if (a == "--starts-only") o.starts = o.starts_only = true;
        else {
            std::fprintf(stderr, "usage: %s [--captures DIR,DIR] [--grids 16,24,48] [--candidates N] [--seed N] [--max-step-edges X] [--starts|--starts-only [--fabric PRESET] [--registration-rounds N] [--registration-tolerance-mm X]]\n",
                         argv[0]);
            return a == "--help" ? 0 : 2;
        }
    }

    std::vector<flowvid::formats::Capture> captures;
    for (const std::string& path : o.captures) captures.push_back(flowvid::formats::read_capture(path));
    cf::TrialLoadSettings load;  // as `fit cloth` loads its default target, the stripe scan
    load.target = cf::kDefaultFitTarget;
    load.waving_frames = cf::kTracksWavingFrames;
    load.half_life_frames = cf::kTracksHalfLifeFrames;
    const std::vector<cf::ClothTrial> trials = cf::load_trials(captures, load);
    const std::vector<cf::FittedParameter> parameters = cf::parameters_for(trials, cf::DragModel::nonlinear);

    // The candidates, the same on every grid and for both solves.
    std::mt19937_64 random(o.seed);
    std::uniform_real_distribution<double> middle_half(0.25, 0.75);
    std::vector<Eigen::VectorXd> candidates;
    for (int c = 0; c < o.candidates; ++c) {
        Eigen::VectorXd values(static_cast<Eigen::Index>(parameters.size()));
        for (std::size_t k = 0; k < parameters.size(); ++k) {
            const cf::FittedParameter& p = parameters[k];
            const double t = middle_half(random);
            values(static_cast<Eigen::Index>(k)) =
                p.log_scale ? std::exp(std::log(p.lower) + t * (std::log(p.upper) - std::log(p.lower)))
                            : p.lower + t * (p.upper - p.lower);
        }
        candidates.push_back(values);
    }
    std::printf("captures:");
    for (const std::string& path : o.captures) std::printf(" %s", path.c_str());
    std::printf("\n%d candidate fabrics (seed %llu) x %zu trials per grid, one thread, each solve from the fit's warm "
                "start, at most 400 Newton iterations\n",
                o.candidates, static_cast<unsigned long long>(o.seed), trials.size());

    // The starts' fabric (--fabric), read once.
    std::optional<fc::ClothMaterial> preset;
    if (!o.fabric.empty())
        preset = fc::material_from_fabric(flowvid::formats::read_fabric_preset(o.fabric).parameters);

    for (const int grid : o.grids) {
        cf::ClothFitSettings settings;
        settings.swatch = fc::run_swatch_options(grid, grid, fc::Integrator::implicit_euler, 1.0, 1);
        settings.base = cf::middle_of_ranges(settings.base, parameters);
        settings.scan_registration_rounds = o.registration_rounds;
        settings.scan_registration_tolerance_m = o.registration_tolerance_m;
        if (o.starts) {
            for (std::size_t t = 0; t < trials.size(); ++t) {
                const auto truth = flowvid::formats::read_capture_truth_positions(captures[t]);
                if (!truth || !truth->grid_rows || !truth->grid_cols) continue;
                const fc::GridFrames real = {fc::grid_frames_of(*truth).front()};
                const fc::Swatch swatch = fc::build_swatch(trials[t].experiment, grid, grid);
                const fc::UvSampler sampler(swatch.mesh, *truth->grid_rows, *truth->grid_cols);
                double rms_mm[2] = {NAN, NAN};
                double seconds[2] = {0.0, 0.0};
                for (int solve = 0; solve < 2; ++solve) {
                    cf::ClothFitSettings with_solve = settings;
                    with_solve.swatch.equilibrium.factorised_max_free_vertices = solve == 0 ? grid * grid : 0;
                    with_solve.swatch.equilibrium.factorised_max_step_edges = o.max_step_edges;
                    const auto start = std::chrono::steady_clock::now();
                    const fc::ClothMaterial fabric =
                        preset ? fc::experiment_material(trials[t].experiment, *preset) : settings.base;
                    const Eigen::VectorXd x = cf::matching_equilibrium(trials[t], fabric, with_solve);
                    seconds[solve] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                    if (x.size() > 0)
                        rms_mm[solve] = 1e3 * fc::rms_distance_per_frame_m({sampler.sample(x)}, real).front();
                }
                std::printf("%dx%d  start of %s from its frame 1, RMS to truth: factorised %.1f mm (%.1f s), CG %.1f mm "
                            "(%.1f s)\n",
                            grid, grid, trials[t].name.c_str(), rms_mm[0], seconds[0], rms_mm[1], seconds[1]);
            }
        }
        if (o.starts_only) continue;
        // The warm starts, found once with the default solve, as a fit finds them.
        std::vector<Eigen::VectorXd> warm;
        std::vector<fc::SwatchExperiment> experiments;
        for (const cf::ClothTrial& trial : trials) {
            warm.push_back(cf::matching_equilibrium(trial, settings.base, settings));
            fc::SwatchExperiment equilibrium_only = trial.experiment;
            equilibrium_only.frame_count = 1;
            for (fc::PinTrajectory& pin : equilibrium_only.pins)
                pin.positions_m.resize(std::min<std::size_t>(pin.positions_m.size(), 1));
            experiments.push_back(equilibrium_only);
        }
        const cf::ClothFitProblem problem(trials, parameters, settings);
        Totals totals[2];
        double largest_difference_m = 0.0;
        for (const Eigen::VectorXd& values : candidates) {
            const fc::ClothMaterial material = problem.material(values);
            for (std::size_t t = 0; t < trials.size(); ++t) {
                if (warm[t].size() == 0) continue;
                Eigen::VectorXd settled[2];
                for (int solve = 0; solve < 2; ++solve) {
                    fc::SwatchOptions options = settings.swatch;
                    options.initial_positions = warm[t];
                    options.equilibrium.max_iterations = 400;
                    options.equilibrium.factorised_max_free_vertices = solve == 0 ? grid * grid : 0;
                    options.equilibrium.factorised_max_step_edges = o.max_step_edges;
                    const auto start = std::chrono::steady_clock::now();
                    const fc::SwatchRun run = fc::simulate_swatch(experiments[t], material, options);
                    totals[solve].seconds +=
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                    totals[solve].iterations += run.equilibrium.iterations;
                    if (!run.equilibrium.converged) ++totals[solve].not_converged;
                    if (!run.simulation.frames.empty()) settled[solve] = run.simulation.frames.front();
                }
                if (settled[0].size() == settled[1].size() && settled[0].size() > 0)
                    for (Eigen::Index v = 0; v < settled[0].size() / 3; ++v)
                        largest_difference_m =
                            std::max(largest_difference_m, (settled[0].segment<3>(3 * v) - settled[1].segment<3>(3 * v)).norm());
            }
        }
        std::printf("\n%dx%d  factorised: %.2f s, %lld Newton iterations, %d not converged\n", grid, grid,
                    totals[0].seconds, totals[0].iterations, totals[0].not_converged);
        std::printf("%dx%d  CG:         %.2f s, %lld Newton iterations, %d not converged\n", grid, grid,
                    totals[1].seconds, totals[1].iterations, totals[1].not_converged);
        std::printf("%dx%d  CG time / factorised time: %.2fx; largest distance between their equilibria %.2f mm\n",
                    grid, grid, totals[1].seconds / std::max(totals[0].seconds, 1e-9), 1e3 * largest_difference_m);
    }
    return 0;
}
