#include "flowvid/cloth_fit/cloth_eval.hpp"

#include "flowvid/random.hpp"
#include "flowvid/thread_pool.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace flowvid::cloth_fit {

std::vector<FrameWindow> standard_windows(int frame_count) {
    std::vector<FrameWindow> windows;
    for (const FrameWindow w : {FrameWindow{1, 10}, FrameWindow{11, 25}, FrameWindow{26, std::numeric_limits<int>::max()}})
        if (w.first <= frame_count) windows.push_back({w.first, std::min(w.last, frame_count)});
    if (frame_count > 10) windows.push_back({1, frame_count});
    return windows;
}

std::string window_name(const FrameWindow& window) {
    return std::to_string(window.first) + "-" + std::to_string(window.last);
}

double pixel_footprint_m(const formats::CameraModel& camera, const Eigen::VectorXd& positions) {
    double depth_sum = 0.0;
    const Eigen::Index count = positions.size() / 3;
    for (Eigen::Index i = 0; i < count; ++i) depth_sum += camera.to_camera(positions.segment<3>(3 * i)).z();
    const double focal_px = std::sqrt(camera.K(0, 0) * camera.K(1, 1));
    return count > 0 && focal_px > 0.0 ? depth_sum / static_cast<double>(count) / focal_px : 0.0;
}

FloorSettings reported_floor(int members) {
    FloorSettings floor;
    floor.members = members;
    floor.integrator = cloth::Integrator::implicit_euler;
    floor.implicit_substeps_per_frame = kFloorSubstepsPerFrame;
    return floor;
}

std::map<std::string, double> preset_uncertainty(const formats::FabricParameters& parameters) {
    std::map<std::string, double> sigma;
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table())
        if (const auto& u = (parameters.*info.member).uncertainty; u && *u > 0.0) sigma[info.key] = *u;
    return sigma;
}

namespace {

// The run starts from the equilibrium branch that matches the footage's first
// frame (as the fit does), unless the caller gave a start.
cloth::SwatchRun run_trial(const ClothTrial& trial, const cloth::ClothMaterial& material, const ClothFitSettings& settings,
                           cloth::SwatchOptions options) {
    options.simulation.threads = 1;
    if (options.initial_positions.size() == 0 && settings.warm_start) {
        const Eigen::VectorXd start = matching_equilibrium(trial, material, settings);
        if (start.size() > 0) options.initial_positions = start;
    }
    return cloth::simulate_swatch(trial.experiment, material, options);
}

cloth::ClothMaterial perturbed(const cloth::ClothMaterial& material, const FloorSettings& floor, Random& random) {
    cloth::ClothMaterial m = material;
    std::map<std::pair<double, double>, double> tied_draws;  // (value, sigma) -> its normal draw
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table()) {
        const double value = material_parameter(material, info.key);
        const double jiggle = random.symmetric();
        // The cell share says how the model reads shear, not what the fabric
        // is: no measurement spreads it, and moved past 1 it is refused. Its
        // draw is still taken, so that every other member stays as it was.
        if (info.member == &formats::FabricParameters::shear_cell_fraction) continue;
        double moved = value * (1.0 + floor.relative_perturbation * jiggle);
        const auto sigma = floor.parameter_sigma.find(info.key);
        if (sigma != floor.parameter_sigma.end() && sigma->second > 0.0 && value > 0.0) {
            const auto [draw, fresh] = tied_draws.try_emplace({value, sigma->second}, 0.0);
            if (fresh) draw->second = random.normal();
            moved *= std::exp(draw->second * sigma->second / value);
        }
        set_material_parameter(m, info.key, moved);
    }
    return m;
}

}  // namespace

std::vector<FloorMember> draw_floor_members(const cloth::ClothMaterial& material, const FloorSettings& floor) {
    Random random(floor.seed);
    std::vector<FloorMember> members;
    for (int m = 0; m < floor.members; ++m) {
        cloth::ClothMaterial drawn = perturbed(material, floor, random);
        members.push_back({std::move(drawn), random.next()});
    }
    return members;
}

namespace {

ClothFitSettings floor_run_settings(const ClothFitSettings& settings, const FloorSettings& floor) {
    ClothFitSettings members = settings;
    if (floor.integrator) members.swatch.simulation.integrator = *floor.integrator;
    if (floor.implicit_substeps_per_frame) members.swatch.simulation.implicit_substeps_per_frame = *floor.implicit_substeps_per_frame;
    return members;
}

bool same_run_settings(const ClothFitSettings& a, const ClothFitSettings& b) {
    return a.swatch.simulation.integrator == b.swatch.simulation.integrator &&
           a.swatch.simulation.implicit_substeps_per_frame == b.swatch.simulation.implicit_substeps_per_frame;
}

// The floor around an unperturbed run that the caller already has.
PredictabilityFloor floor_around(const ClothTrial& trial, const cloth::ClothMaterial& material,
                                 const ClothFitSettings& settings, const FloorSettings& floor, int threads,
                                 const cloth::SwatchRun& nominal) {
    PredictabilityFloor out;
    out.members = floor.members;
    out.integrator = settings.swatch.simulation.integrator;
    const bool implicit = out.integrator == cloth::Integrator::implicit_euler || out.integrator == cloth::Integrator::bdf2;
    out.implicit_substeps_per_frame = implicit ? settings.swatch.simulation.implicit_substeps_per_frame : 0;
    out.jitter_m = floor.jitter_m ? *floor.jitter_m : pixel_footprint_m(trial.camera, nominal.simulation.frames.front());
    const int frames = usable_frames(nominal);
    int needed = 0;
    for (const video::ReferenceFrame& reference : trial.frames) needed = std::max(needed, reference.number);
    if (frames < needed)
        throw std::runtime_error("predictability floor of " + trial.name + ": the unperturbed run stopped at frame " +
                                 std::to_string(frames) + " of " + std::to_string(needed) + " (" +
                                 (nominal.simulation.report.reason.empty() ? std::string("no frames") : nominal.simulation.report.reason) +
                                 "); more substeps per frame or a coarser mesh may let it through");
    const cloth::GridFrames nominal_grid = cloth::sample_frames(nominal.swatch.mesh,
        std::vector<Eigen::VectorXd>(nominal.simulation.frames.begin(), nominal.simulation.frames.begin() + frames),
        nominal.swatch.rows, nominal.swatch.cols);
    const ClothTrial as_footage =
        simulated_trial(trial, nominal, settings.metric.silhouette_term == video::SilhouetteTerm::edge_distance);

    // Drawn up front so members do not depend on the thread count.
    const std::vector<FloorMember> drawn = draw_floor_members(material, floor);
    std::vector<std::vector<double>> squared(static_cast<std::size_t>(floor.members));
    std::vector<std::vector<video::FrameError>> errors(static_cast<std::size_t>(floor.members));
    ThreadPool pool(std::max(1, threads));
    pool.run(static_cast<std::size_t>(floor.members), [&](std::size_t m, int) {
        cloth::SwatchOptions options = settings.swatch;
        options.initial_positions = nominal.simulation.frames.front();  // same branch, a few Newton steps
        options.initial_jitter_m = out.jitter_m;
        options.jitter_shape = floor.jitter_shape;
        options.jitter_seed = drawn[m].jitter_seed;
        const cloth::SwatchRun run = run_trial(trial, drawn[m].material, settings, options);
        const int good = std::min(frames, usable_frames(run));
        const cloth::GridFrames grid = cloth::sample_frames(run.swatch.mesh,
            std::vector<Eigen::VectorXd>(run.simulation.frames.begin(), run.simulation.frames.begin() + good),
            run.swatch.rows, run.swatch.cols);
        const std::vector<double> rms = cloth::rms_distance_per_frame_m(grid, nominal_grid);
        squared[m].assign(static_cast<std::size_t>(frames), std::numeric_limits<double>::infinity());
        for (std::size_t f = 0; f < rms.size(); ++f) squared[m][f] = rms[f] * rms[f];
        errors[m] = compare_run(as_footage, run, settings.metric);
    });
    out.vertex_rms_m.assign(static_cast<std::size_t>(frames), 0.0);
    for (int f = 0; f < frames; ++f) {
        double sum = 0.0;
        for (const auto& s : squared) sum += s[static_cast<std::size_t>(f)];
        out.vertex_rms_m[static_cast<std::size_t>(f)] = std::sqrt(sum / std::max(1, floor.members));
    }
    out.metric.assign(trial.frames.size(), 0.0);
    for (const auto& e : errors)
        for (std::size_t k = 0; k < e.size(); ++k) out.metric[k] += e[k].total / std::max(1, floor.members);
    return out;
}

}  // namespace

PredictabilityFloor estimate_floor(const ClothTrial& trial, const cloth::ClothMaterial& material,
                                   const ClothFitSettings& settings, const FloorSettings& floor, int threads) {
    const ClothFitSettings members = floor_run_settings(settings, floor);
    return floor_around(trial, material, members, floor, threads, run_trial(trial, material, members, members.swatch));
}

double weighted_floor(const ClothTrial& trial, const PredictabilityFloor& floor) {
    double sum = 0.0;
    for (std::size_t k = 0; k < trial.frames.size() && k < floor.metric.size(); ++k) sum += trial.frames[k].weight * floor.metric[k];
    return sum;
}

TrialAssessment assess_trial(const ClothTrial& trial, const cloth::ClothMaterial& material,
                             const ClothFitSettings& settings, const std::optional<formats::VertexAnimation>& truth,
                             const FloorSettings* floor, int threads) {
    TrialAssessment out;
    out.name = trial.name;
    out.is_static = trial.is_static;
    const cloth::SwatchRun run = run_trial(trial, material, settings, settings.swatch);
    out.report = run.simulation.report;
    out.frames = compare_run(trial, run, settings.metric);
    for (std::size_t k = 0; k < trial.frames.size(); ++k) {
        out.frame_numbers.push_back(trial.frames[k].number);
        out.weights.push_back(trial.frames[k].weight);
        out.weighted_error += trial.frames[k].weight * out.frames[k].total;
    }
    const int good = usable_frames(run);
    const std::vector<Eigen::VectorXd> frames(run.simulation.frames.begin(), run.simulation.frames.begin() + good);
    int rows = run.swatch.rows, cols = run.swatch.cols;
    if (truth && truth->grid_rows && truth->grid_cols) {
        rows = *truth->grid_rows;
        cols = *truth->grid_cols;
    }
    out.predicted = cloth::sample_frames(run.swatch.mesh, frames, rows, cols);
    if (truth && truth->vertex_count == rows * cols) {
        const cloth::GridFrames real = cloth::grid_frames_of(*truth);
        out.vertex_rms_m = cloth::rms_distance_per_frame_m(out.predicted, real);
    }
    if (floor) {
        const ClothFitSettings members = floor_run_settings(settings, *floor);
        out.floor = same_run_settings(members, settings)
                        ? floor_around(trial, material, members, *floor, threads, run)
                        : floor_around(trial, material, members, *floor, threads,
                                       run_trial(trial, material, members, members.swatch));
    }
    return out;
}

double pooled_rms(const std::vector<double>& per_frame_rms, const FrameWindow& window) {
    // Every frame has the same vertex count, so the pooled RMS is the root of the mean of squares.
    double sum = 0.0;
    int n = 0;
    for (int f = std::max(window.first, 1); f <= window.last && f <= static_cast<int>(per_frame_rms.size()); ++f, ++n)
        sum += per_frame_rms[static_cast<std::size_t>(f - 1)] * per_frame_rms[static_cast<std::size_t>(f - 1)];
    return n ? std::sqrt(sum / n) : std::numeric_limits<double>::quiet_NaN();
}

std::vector<WindowSummary> summarize_windows(const TrialAssessment& a, const std::vector<FrameWindow>& windows) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::vector<WindowSummary> out;
    for (const FrameWindow& w : windows) {
        WindowSummary s{w, 0.0, a.floor ? 0.0 : nan, a.vertex_rms_m.empty() ? nan : 0.0, a.floor ? 0.0 : nan};
        int metric_count = 0;
        for (std::size_t k = 0; k < a.frame_numbers.size(); ++k) {
            if (a.frame_numbers[k] < w.first || a.frame_numbers[k] > w.last) continue;
            s.metric_mean += a.frames[k].total;
            if (a.floor) s.metric_floor_mean += a.floor->metric[k];
            ++metric_count;
        }
        if (metric_count) {
            s.metric_mean /= metric_count;
            if (a.floor) s.metric_floor_mean /= metric_count;
        } else {
            s.metric_mean = s.metric_floor_mean = nan;
        }
        if (!a.vertex_rms_m.empty()) s.vertex_rms_m = pooled_rms(a.vertex_rms_m, w);
        if (a.floor) s.vertex_floor_m = pooled_rms(a.floor->vertex_rms_m, w);
        out.push_back(s);
    }
    return out;
}

}  // namespace flowvid::cloth_fit
