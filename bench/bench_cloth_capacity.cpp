// Cloth model capacity: how closely can the fabric model reproduce the
// Blender captures at best? (docs/cloth_model.md, "Model capacity".)
//
// The footage fit asks two things at once: what the model can reach, and
// how close the angle-map metric gets to it. This study answers the first
// alone. For each fabric it gives every public capture its own ground truth
// as 3D `tracks` in a scratch copy -- THE ONE PLACE TRUTH IS HANDED TO A
// FIT, and only as tracks -- fits static-1 + waving-1 to them (`fit cloth
// --fit-to tracks`: same optimizer, same preset), then predicts the
// held-out waving-2 and static drape, starting from each trial's measured
// first frame, and prints the RMS vertex error against truth per window:
// frame 1, 1-10, 11-25, 26-end, all. Each model variant (the terms the fit
// may use) is a row; the last rows are Blender itself, re-run from the same
// measured first frame on other meshes (the bound a mesh-independent model
// faces) and with the other fabric's preset. The last fitted fabric is also
// simulated at 12 x 12 and 48 x 48: a preset must be the same fabric on any mesh;
// each drape also on 24 x 24 from its measured shape as a 12 x 12 mesh holds
// it, which separates what the start's sub-grid detail moves from the mesh's own.
//
//   flowvid_bench_cloth_capacity [--fabrics cotton,silk] [--variants today,...] [--captures DIR]
//                                [--evaluations 400[,800]] [--threads 2] [--seed 1]
//                                [--scratch DIR] [--json FILE]
//                                [--blender PATH | --no-blender] [--blender-grids 12,24,48] [--no-resolution]
//                                [--nested-from EARLIER.json] [--min-bending N_m] [--fit-to tracks|scan|footage] [--resolution-of PRESET]
//                                [--search annealing|cmaes] [--second-drape-mesh RxC|none] [--hem-energy]
//
// --hem-energy adds, to each drape's mesh agreement, what holding its bottom
// corners where the measured frame has them costs each mesh, per term of
// the potential energy (docs/cloth_model.md, "Folds finer than the grid").
// --fit-to scan or footage fits the footage alone (the shared captures, not
// the scratch copies) and scores its predictions the same way: how close
// the footage fit gets to the model's capacity (docs/cloth_fitting.md).
// Every fitted fabric is also written to the scratch folder as a preset,
// and the JSON record keeps each fit's progress reports (evaluations, best
// training error; as often as the optimizer reports).
//
// Blender runs are cached in the scratch folder (they take minutes at 48x48).

#include "flowvid/cloth/equilibrium.hpp"
#include "flowvid/cloth/material.hpp"
#include "flowvid/cloth/model.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/cloth/swatch_output.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/vertex_animation.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"
#include "flowvid/optim/least_squares.hpp"
#include "fit_curve.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"

#include "option_value.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

namespace fc = flowvid::cloth;
namespace ff = flowvid::formats;
namespace cf = flowvid::cloth_fit;
namespace optim = flowvid::optim;
namespace fs = std::filesystem;

namespace {

struct Options {
    std::vector<std::string> fabrics = {"cotton", "silk"};
    std::vector<std::string> variants = {"today"};
    std::vector<long long> evaluations = {400};
    int threads = 2;
    std::uint64_t seed = 1;
    std::string scratch = "cloth_capacity_scratch";
    std::string json;
    std::string blender = "blender";
    bool run_blender = true;
    bool check_resolution = true;
    std::string nested_from;  // an earlier run's --json: its smallest variant's fit seeds the larger ones
    std::vector<int> blender_grids = {12, 24, 48};
    // The waving trial's fitted frames and their weighting (fit cloth
    // --fit-to tracks's defaults: 20 frames, full weight for 10, then
    // halving every 5; the study before them used 50 and 10).
    int waving_frames = cf::kTracksWavingFrames;
    double half_life_frames = cf::kTracksHalfLifeFrames;
    // The static drape's frame against a waving frame's full weight (unset:
    // fit cloth's default, a drape counting as much as a waving test).
    std::optional<double> static_weight;
    // A floor on the fitted bending stiffness (N m), 0: the fit's own range.
    // Folds much finer than the mesh make a drape mesh-dependent; a floor
    // trades reach for a preset that is the same fabric on any mesh.
    double min_bending_N_m = 0.0;
    // Each static drape also fitted on this mesh (ClothFitSettings'
    // second drape mesh; 0: none).
    int second_drape_rows = 0;
    int second_drape_cols = 0;
    // A preset whose mesh agreement to check instead of the last fitted one
    // (with --variants "" no fit runs; one fabric at a time).
    std::string resolution_of;
    bool hem_energy = false;
    // A scan fit's background band (px from the footage's outline; 0: off).
    double outside_band_px = cf::ScanOutsideBand{}.max_px;
    // Presets to score on the fit's own training objective instead of
    // fitting (does the objective prefer the fabric nearer the truth?).
    std::vector<std::string> score;
    double budget_seconds = 0.0;  // fit cloth --budget-seconds (0: the evaluations alone end the fit)
    std::optional<double> shear_cells;  // fit cloth --shear-cells (unset: its default for the fit target)
    // With --score: each preset's held-out waving-2 prediction is repeated
    // with its bending and air drag changed by k parts in a million (k = 1..N,
    // both signs), as the captures' README measured Blender's own chaos.
    int chaos_members = 0;
    bool score_from_measured_start = false;  // --score-from-measured-start
    std::string score_start_material;        // --score-start-material
    std::string start_from;                  // --start-from: the fits start from this preset (fit cloth --start)
    int refine_rounds = 0;                   // --refine-rounds (fit cloth's)
    flowvid::optim::SearchMethod search = flowvid::optim::SearchMethod::annealing;  // fit cloth --search
    // What the fit compares with: the scratch copies' tracks (the model's
    // capacity), or the footage alone (--fit-to scan: its stripe scan;
    // footage: its angle maps and silhouettes; the shared captures, never
    // truth). The predictions are scored the same way.
    cf::FitTarget fit_to = cf::FitTarget::tracks;
};

// Where the captures are: ../shared/captures, or --captures DIR (another set
// of cloth-<fabric>-{static,waving}-N captures with truth/, scored the same way).
std::string& captures_dir() {
    static std::string dir = std::string(FLOWVID_SHARED_DIR) + "/captures";
    return dir;
}

std::string shared_capture(const std::string& name) { return captures_dir() + "/" + name; }

// ---- Scratch copies: the capture with its truth as tracks -------------------

Eigen::MatrixX3d resample(const Eigen::MatrixX3d& grid, int rows, int cols, int out_rows, int out_cols);

// A copy of the capture whose capture.json declares tracks.exr = its own
// truth/positions.exr. Frames, masks and background are linked, not copied.
// With `first_frame_through_grid` > 0 the first frame is what a mesh of that
// many rows and columns holds of it (resampled to that grid and back), the
// others as measured: a start without the shape's detail finer than that mesh.
std::string tracks_copy(const std::string& name, const fs::path& scratch, int first_frame_through_grid = 0) {
    const fs::path source = shared_capture(name);
    const fs::path copy = scratch / "tracks" /
                          (first_frame_through_grid > 0 ? name + "-start-through-" + std::to_string(first_frame_through_grid) : name);
    fs::create_directories(copy);
    for (const char* entry : {"frames", "masks", "background.png"}) {
        const fs::path target = source / entry;
        const fs::path link = copy / entry;
        std::error_code ec;
        if (fs::exists(target) && !fs::exists(fs::symlink_status(link)))
            fs::create_symlink(fs::absolute(target), link, ec);
    }
    const ff::Capture capture = ff::read_capture(source.string());
    std::optional<ff::VertexAnimation> truth = ff::read_capture_truth_positions(capture);
    if (!truth) throw std::runtime_error(name + " has no truth/positions.exr");
    if (first_frame_through_grid > 0) {
        if (!truth->grid_rows || !truth->grid_cols) throw std::runtime_error(name + "'s truth/positions.exr is not a uv grid");
        const int rows = *truth->grid_rows, cols = *truth->grid_cols, g = first_frame_through_grid;
        Eigen::MatrixX3d first(rows * cols, 3);
        for (int v = 0; v < rows * cols; ++v) first.row(v) = truth->position(0, v).cast<double>().transpose();
        const Eigen::MatrixX3d held = resample(resample(first, rows, cols, g, g), g, g, rows, cols);
        for (int v = 0; v < rows * cols; ++v) truth->positions_m[static_cast<std::size_t>(v)] = held.row(v).transpose().cast<float>();
    }
    ff::write_vertex_animation((copy / "tracks.exr").string(), *truth);
    std::ifstream in(source / "capture.json");
    nlohmann::json document = nlohmann::json::parse(in);
    document["tracks"] = {{"file", "tracks.exr"}, {"rows", *truth->grid_rows}, {"cols", *truth->grid_cols}};
    ff::write_file_atomically((copy / "capture.json").string(), [&](std::ostream& out) { out << document.dump(1) << '\n'; });
    return copy.string();
}

// ---- Windows -----------------------------------------------------------------

struct Windows {
    double frame1 = NAN, f1_10 = NAN, f11_25 = NAN, f26_end = NAN, all = NAN;  // mm
};

Windows windows_of(const std::vector<double>& per_frame_rms_m) {
    const int n = static_cast<int>(per_frame_rms_m.size());
    auto pooled = [&](int first, int last) { return 1e3 * cf::pooled_rms(per_frame_rms_m, {first, std::min(last, n)}); };
    Windows w;
    w.frame1 = pooled(1, 1);
    if (n >= 10) w.f1_10 = pooled(1, 10);
    if (n >= 25) w.f11_25 = pooled(11, 25);
    if (n >= 26) w.f26_end = pooled(26, n);
    w.all = pooled(1, n);
    return w;
}

nlohmann::json windows_json(const Windows& w) {
    auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
    return {{"frame_1", number(w.frame1)}, {"frames_1_10", number(w.f1_10)}, {"frames_11_25", number(w.f11_25)},
            {"frames_26_end", number(w.f26_end)}, {"all", number(w.all)}};
}

std::string cell(double v) {
    char text[32];
    if (!std::isfinite(v)) return "  -  ";
    std::snprintf(text, sizeof text, "%5.1f", v);
    return text;
}

// ---- Model variants: which terms the fit may use -----------------------------

// today: the 9 parameters of the thesis's waving fit; compression: + the
// two compression ratios; linear-drag: + linear normal drag; hem: + the
// hem's line density; diagonal: + the diagonal tension fibres and the wider
// shear range they call for; all: every one of them (what fit cloth
// --fit-to tracks fits: cf::capacity_terms).
std::vector<cf::FittedParameter> variant_parameters(const std::string& variant) {
    std::vector<cf::FittedParameter> terms;
    const bool compression = variant == "compression" || variant == "all";
    const bool linear_drag = variant == "linear-drag" || variant == "all";
    const bool hem = variant == "hem" || variant == "all";
    const bool diagonal = variant == "diagonal" || variant == "all";
    if (variant != "today" && !compression && !linear_drag && !hem && !diagonal)
        throw std::invalid_argument("unknown variant '" + variant +
                                    "' (known: today, compression, linear-drag, hem, diagonal, all)");
    for (const cf::FittedParameter& term : cf::capacity_terms(true, cf::DragModel::nonlinear)) {
        bool wanted = compression;  // the two compression ratios
        if (term.key == "hem_line_density_kg_per_m") wanted = hem;
        if (term.key == "drag_linear_normal_kg_per_m2_s") wanted = linear_drag;
        if (term.key == "diagonal_tension_stiffness_N_per_m" || term.key == "shear_stiffness_N_per_m") wanted = diagonal;
        if (wanted) terms.push_back(term);
    }
    return cf::with_terms(cf::waving_test_parameters(), terms);
}

// ---- Predictions from the fitted material ----------------------------------

// --equilibrium-steps cg: every static solve (fits and predictions) solves
// its definite steps by CG, as before factorised steps (docs/cloth_model.md,
// "Factorised definite steps"): which nearby equilibrium a solve finds is
// the solve path's as much as the start's.
bool& cg_equilibrium_steps() {
    static bool cg = false;
    return cg;
}

cf::ClothFitSettings fit_settings() {
    cf::ClothFitSettings settings;
    settings.swatch.simulation.integrator = fc::Integrator::implicit_euler;  // fit cloth's default
    if (cg_equilibrium_steps()) settings.swatch.equilibrium.factorised_max_free_vertices = 0;
    return settings;
}

// What the fits (and --score) read: the trials' frames and weights.
cf::TrialLoadSettings training_load(const Options& o, const std::vector<ff::Capture>& captures) {
    cf::TrialLoadSettings load;
    load.target = o.fit_to;
    load.half_life_frames = o.half_life_frames;  // late, chaotic frames count less
    load.waving_frames = o.waving_frames;
    load.static_weight = o.static_weight.value_or(cf::default_static_weight(load, captures));
    load.scan_outside.max_px = o.outside_band_px;
    return load;
}

// The material on one capture, started from the capture's measured first
// frame (its tracks), against its truth per window (read from the shared
// capture: the scratch copy has tracks, not truth/).
Windows predict(const std::string& tracks_folder, const fc::ClothMaterial& material, int threads) {
    const ff::Capture capture = ff::read_capture(tracks_folder);
    const ff::Capture original = ff::read_capture(shared_capture(fs::path(tracks_folder).filename().string()));
    cf::TrialLoadSettings load;
    load.target = cf::FitTarget::tracks;
    load.waving_frames = capture.frames.count;
    const cf::ClothTrial trial = cf::load_trial(capture, load);
    const cf::TrialAssessment a =
        cf::assess_trial(trial, material, fit_settings(), ff::read_capture_truth_positions(original), nullptr, threads);
    if (!a.report.ok())
        std::fprintf(stderr, "  %s: the prediction stopped at frame %d: %s\n", trial.name.c_str(), a.report.frame,
                     a.report.reason.c_str());
    return windows_of(a.vertex_rms_m);
}

// The material on one capture at a rows x rows mesh, from its measured first
// frame, read back at the truth's 24 x 24 uv grid (for the resolution check).
fc::GridFrames predict_at(const std::string& tracks_folder, const fc::ClothMaterial& material, int rows, int threads) {
    const ff::Capture capture = ff::read_capture(tracks_folder);
    cf::TrialLoadSettings load;
    load.target = cf::FitTarget::tracks;
    load.waving_frames = capture.frames.count;
    const cf::ClothTrial trial = cf::load_trial(capture, load);
    cf::ClothFitSettings settings = fit_settings();
    settings.swatch.rows = settings.swatch.cols = rows;
    const cf::TrialAssessment a = cf::assess_trial(trial, material, settings, std::nullopt, nullptr, threads);
    fc::GridFrames out;
    if (!a.report.ok()) {
        std::fprintf(stderr, "  %s at %dx%d: the prediction stopped at frame %d: %s\n", trial.name.c_str(), rows, rows,
                     a.report.frame, a.report.reason.c_str());
        return out;
    }
    for (const Eigen::MatrixX3d& frame : a.predicted) out.push_back(resample(frame, rows, rows, 24, 24));
    return out;
}

// The material's drape on `capture_name`'s static experiment as `flowvid
// simulate` makes it (the static equilibrium from the hanging start, no
// measured shape), at a rows x rows mesh, sampled at the 12 x 12 uv points
// where the drape test (StaticDrapeConvergesWithResolution) compares meshes.
// Empty on failure (printed).
std::optional<Eigen::MatrixX3d> equilibrium_drape_at(const std::string& capture_name, const fc::ClothMaterial& material,
                                                     int rows) {
    fc::SwatchExperiment experiment = fc::experiment_from_capture(ff::read_capture(shared_capture(capture_name)));
    experiment.frame_count = 1;
    for (fc::PinTrajectory& pin : experiment.pins) pin.positions_m.resize(1);
    fc::SwatchOptions options = fit_settings().swatch;
    options.rows = options.cols = rows;
    const fc::SwatchRun run = fc::simulate_swatch(experiment, fc::experiment_material(experiment, material), options);
    if (!run.simulation.report.ok()) {
        std::fprintf(stderr, "  %s drape at %dx%d: %s\n", capture_name.c_str(), rows, rows, run.simulation.report.reason.c_str());
        return std::nullopt;
    }
    return fc::sample_run(run, 12, 12).front();
}

// ---- Blender's own cloth, re-run from the measured first frame --------------

// Bilinear resampling of a rows x cols grid of points to another grid.
Eigen::MatrixX3d resample(const Eigen::MatrixX3d& grid, int rows, int cols, int out_rows, int out_cols) {
    Eigen::MatrixX3d out(out_rows * out_cols, 3);
    for (int r = 0; r < out_rows; ++r)
        for (int c = 0; c < out_cols; ++c) {
            const double y = static_cast<double>(r) / (out_rows - 1) * (rows - 1);
            const double x = static_cast<double>(c) / (out_cols - 1) * (cols - 1);
            const int r0 = std::min(static_cast<int>(y), rows - 2), c0 = std::min(static_cast<int>(x), cols - 2);
            const double fy = y - r0, fx = x - c0;
            out.row(r * out_cols + c) = (1 - fy) * (1 - fx) * grid.row(r0 * cols + c0) + (1 - fy) * fx * grid.row(r0 * cols + c0 + 1) +
                                        fy * (1 - fx) * grid.row((r0 + 1) * cols + c0) + fy * fx * grid.row((r0 + 1) * cols + c0 + 1);
        }
    return out;
}

// One Blender run of `preset_capture`'s preset on `capture_name`'s experiment
// at a grid x grid mesh, `frames` frames after its preroll: from the flat
// hanging swatch (its pins sliding in, as the captures were made) or, with
// `start`, from those positions with the pins held. With `mass_of_grid` > 0
// the swatch weighs what the preset gives it on that grid (the per-vertex
// mass scaled), else the preset's mass per vertex. `change_ppm` changes
// the preset's bending and air damping by that many parts in a million (a
// chaos ensemble's member). Cached in the scratch folder by `key`. Empty on
// failure (printed).
fc::GridFrames blender_run(const Options& o, const std::string& capture_name, const std::string& preset_capture, int grid,
                           int frames, const std::optional<Eigen::MatrixX3d>& start, int mass_of_grid, const std::string& key,
                           const fs::path& scratch, int change_ppm = 0) {
    const fs::path folder = scratch / "blender";
    fs::create_directories(folder);
    const fs::path start_file = folder / (key + ".start.raw"), positions = folder / (key + ".positions.raw");
    if (!fs::exists(positions)) {
        std::ostringstream cmd;
        cmd << o.blender << " -b --factory-startup -noaudio -t " << o.threads << " --python \"" << FLOWVID_SOURCE_DIR
            << "/bench/blender_cloth_swatch.py\" -- --capture \"" << shared_capture(capture_name) << "\" --preset-from \""
            << shared_capture(preset_capture) << "\" --rows " << grid << " --cols " << grid << " --frames " << frames;
        if (start) {
            std::ofstream out(start_file, std::ios::binary);
            for (Eigen::Index i = 0; i < start->rows(); ++i)
                for (int k = 0; k < 3; ++k) {
                    const double value = (*start)(i, k);
                    out.write(reinterpret_cast<const char*>(&value), sizeof value);
                }
            cmd << " --quality 10 --preroll 100 --start-positions \"" << start_file.string() << "\"";
        } else {
            cmd << " --quality 5";  // the captures' own quality, preroll and slide
        }
        if (mass_of_grid > 0) cmd << " --mass-of-grid " << mass_of_grid;
        if (change_ppm != 0) cmd << " --change-ppm " << change_ppm;
        cmd << " --positions-out \"" << positions.string() << ".part\" > \"" << (folder / (key + ".log")).string() << "\" 2>&1";
        std::fprintf(stderr, "  blender: %s\n", key.c_str());
        if (std::system(cmd.str().c_str()) != 0 || !fs::exists(positions.string() + ".part")) {
            std::fprintf(stderr, "  blender run failed (log: %s)\n", (folder / (key + ".log")).string().c_str());
            return {};
        }
        fs::rename(positions.string() + ".part", positions);
    }
    std::ifstream in(positions, std::ios::binary);
    std::vector<double> values;
    for (double v; in.read(reinterpret_cast<char*>(&v), sizeof v);) values.push_back(v);
    const std::size_t per_frame = static_cast<std::size_t>(3 * grid * grid);
    fc::GridFrames run;
    for (std::size_t f = 0; f * per_frame + per_frame <= values.size() && static_cast<int>(f) < frames; ++f) {
        Eigen::MatrixX3d g(grid * grid, 3);
        for (int i = 0; i < grid * grid; ++i)
            for (int k = 0; k < 3; ++k) g(i, k) = values[f * per_frame + static_cast<std::size_t>(3 * i + k)];
        run.push_back(g);
    }
    return run;
}

// Blender's cloth with `preset_capture`'s preset on `capture`'s experiment at
// a grid x grid mesh, started from the truth's first frame and settled for
// 100 frames with the pins held, then driven by the pins; its RMS distance to
// the truth per frame, read back at the truth's grid. With `change_ppm`, the
// preset's bending and air damping changed by that many parts in a million.
// Empty on failure.
std::vector<double> blender_rms(const Options& o, const std::string& capture_name, const std::string& preset_capture,
                                int grid, const fs::path& scratch, int change_ppm = 0) {
    const ff::Capture capture = ff::read_capture(shared_capture(capture_name));
    const ff::VertexAnimation truth = *ff::read_capture_truth_positions(capture);
    const int rows = *truth.grid_rows, cols = *truth.grid_cols;
    const fc::GridFrames real = fc::grid_frames_of(truth);
    const int frames = capture.kind == "cloth.static" ? 2 : capture.frames.count;
    const std::string key = capture_name + "_" + preset_capture + "_" + std::to_string(grid) +
                            (change_ppm != 0 ? "_ppm" + std::to_string(change_ppm) : std::string());
    const fc::GridFrames run = blender_run(o, capture_name, preset_capture, grid, frames, resample(real.front(), rows, cols, grid, grid),
                                           0, key, scratch, change_ppm);
    if (run.empty()) return {};
    fc::GridFrames simulated;
    for (const Eigen::MatrixX3d& g : run) simulated.push_back(resample(g, grid, grid, rows, cols));
    const fc::GridFrames compared(real.begin(), real.begin() + static_cast<std::ptrdiff_t>(simulated.size()));
    return fc::rms_distance_per_frame_m(simulated, compared);
}

// Blender's own drape of `capture_name` with its own preset at a grid x grid
// mesh, at the 12 x 12 uv points where the drape test compares meshes: from
// the hanging start (as the captures were made) or from the measured first
// frame, with the preset's per-vertex mass or with the 24 x 24 swatch's total
// mass held. How far Blender's fabric itself is from one mesh to another.
std::optional<Eigen::MatrixX3d> blender_drape_at(const Options& o, const std::string& capture_name, int grid, bool measured_start,
                                                 bool hold_total_mass, const fs::path& scratch) {
    const ff::Capture capture = ff::read_capture(shared_capture(capture_name));
    const ff::VertexAnimation truth = *ff::read_capture_truth_positions(capture);
    const int rows = *truth.grid_rows, cols = *truth.grid_cols;
    std::optional<Eigen::MatrixX3d> start;
    if (measured_start) start = resample(fc::grid_frames_of(truth).front(), rows, cols, grid, grid);
    const std::string key = capture_name + "_drape_" + std::to_string(grid) + (measured_start ? "_measured" : "_hanging") +
                            (hold_total_mass ? "_held_mass" : "");
    const fc::GridFrames run = blender_run(o, capture_name, capture_name, grid, 1, start, hold_total_mass ? rows : 0, key, scratch);
    if (run.empty()) return std::nullopt;
    return resample(run.front(), grid, grid, 12, 12);
}

// Largest distance (mm) between two meshes' drapes sampled at the same uv
// points; NaN when either run failed.
double max_distance_mm(const std::optional<Eigen::MatrixX3d>& a, const std::optional<Eigen::MatrixX3d>& b) {
    return a && b ? 1e3 * (*a - *b).rowwise().norm().maxCoeff() : std::nan("");
}

// Root mean square of the same distances (the captures README's measure of
// Blender's own mesh dependence); NaN when either run failed.
double rms_distance_mm(const std::optional<Eigen::MatrixX3d>& a, const std::optional<Eigen::MatrixX3d>& b) {
    return a && b ? 1e3 * std::sqrt((*a - *b).rowwise().squaredNorm().mean()) : std::nan("");
}

// The distance between a drape's two bottom corners (mm; row 0 of a grid of
// `cols` columns is the free bottom hem): how far the hanging swatch has
// drawn in sideways, where its meshes disagree most. NaN when the run failed.
double hem_width_mm(const std::optional<Eigen::MatrixX3d>& grid, int cols) {
    return grid ? 1e3 * (grid->row(cols - 1) - grid->row(0)).norm() : std::nan("");
}

// One drape on three meshes, compared at the same uv points: printed after
// `label` and recorded under `record` (max and RMS, mm; and each mesh's hem
// width).
void report_mesh_agreement(const std::string& label, std::map<int, std::optional<Eigen::MatrixX3d>>& shapes, nlohmann::json& record) {
    auto max_mm = [&](int a, int b) { return max_distance_mm(shapes[a], shapes[b]); };
    auto rms_mm = [&](int a, int b) { return rms_distance_mm(shapes[a], shapes[b]); };
    const double hem_12 = hem_width_mm(shapes[12], 12), hem_24 = hem_width_mm(shapes[24], 12), hem_48 = hem_width_mm(shapes[48], 12);
    std::printf("|   %s: at the 12x12 uv points, max / RMS, 12x12 vs 24x24 %s / %s, 24x24 vs 48x48 %s / %s mm; hem width "
                "12x12 / 24x24 / 48x48 %s / %s / %s mm |\n",
                label.c_str(), cell(max_mm(12, 24)).c_str(), cell(rms_mm(12, 24)).c_str(), cell(max_mm(24, 48)).c_str(),
                cell(rms_mm(24, 48)).c_str(), cell(hem_12).c_str(), cell(hem_24).c_str(), cell(hem_48).c_str());
    record = {{"max_12_24_mm", max_mm(12, 24)},
              {"max_24_48_mm", max_mm(24, 48)},
              {"rms_12_24_mm", rms_mm(12, 24)},
              {"rms_24_48_mm", rms_mm(24, 48)},
              {"hem_width_mm", {{"12", hem_12}, {"24", hem_24}, {"48", hem_48}}}};
}

// What holds each mesh's hem where it is: the drape of `material` on
// `capture_name`'s static experiment from its measured first frame (truth,
// resampled to the mesh), solved free and again with its two bottom corners
// held where the measured frame has them. The held drape's potential energy
// above the free one, per term, is what the mesh asks for the measured hem
// width: printed and recorded under `record`.
void report_hem_energy(const std::string& capture_name, const fc::ClothMaterial& material, nlohmann::json& record) {
    const ff::Capture capture = ff::read_capture(shared_capture(capture_name));
    fc::SwatchExperiment experiment = fc::experiment_from_capture(capture);
    experiment.frame_count = 1;
    for (fc::PinTrajectory& pin : experiment.pins) pin.positions_m.resize(1);
    const std::optional<ff::VertexAnimation> truth = ff::read_capture_truth_positions(capture);
    if (!truth || !truth->grid_rows || !truth->grid_cols) return;
    const int truth_rows = *truth->grid_rows, truth_cols = *truth->grid_cols;
    Eigen::MatrixX3d first(truth_rows * truth_cols, 3);
    for (int v = 0; v < truth_rows * truth_cols; ++v) first.row(v) = truth->position(0, v).cast<double>().transpose();
    const fc::SwatchOptions options = fit_settings().swatch;
    const fc::ClothMaterial weighed = fc::experiment_material(experiment, material);
    for (const int rows : {12, 24, 48}) {
        const fc::Swatch swatch = fc::build_swatch(experiment, rows, rows);
        const Eigen::MatrixX3d start_grid = resample(first, truth_rows, truth_cols, rows, rows);
        Eigen::VectorXd start(3 * rows * rows);
        for (int v = 0; v < rows * rows; ++v) start.segment<3>(3 * v) = start_grid.row(v).transpose();
        for (const fc::PinnedVertex& p : swatch.pins) start.segment<3>(3 * p.vertex) = p.path.position(0.0);
        fc::ClothModel model(swatch.mesh, weighed, options.environment);
        const int left = 0, right = rows - 1;  // the bottom corners (row 0 hangs lowest)
        const auto hem_mm = [&](const Eigen::VectorXd& x) { return 1e3 * (x.segment<3>(3 * right) - x.segment<3>(3 * left)).norm(); };
        Eigen::VectorXd free_x = start, held_x = start;
        std::vector<bool> held = swatch.pinned;
        held[static_cast<std::size_t>(left)] = held[static_cast<std::size_t>(right)] = true;
        const bool ok = fc::solve_static_equilibrium(model, swatch.pinned, free_x, options.equilibrium).converged &&
                        fc::solve_static_equilibrium(model, held, held_x, options.equilibrium).converged;
        if (!ok) {
            std::printf("|   hem energy, %s at %dx%d: a static solve did not converge |\n", capture_name.c_str(), rows, rows);
            continue;
        }
        const auto extra_J = [&](unsigned terms) {
            return model.potential_energy(held_x, terms) - model.potential_energy(free_x, terms);
        };
        const double total = model.potential_energy(free_x);
        std::printf("|   hem energy, %s at %dx%d: hem free %.1f mm, held %.1f mm; held above free %+.2e J (stretch %+.2e, shear %+.2e, "
                    "bending %+.2e, gravity %+.2e); the free drape's energy %.5e J |\n",
                    capture_name.c_str(), rows, rows, hem_mm(free_x), hem_mm(held_x), extra_J(fc::ForceTerm::conservative),
                    extra_J(fc::ForceTerm::stretch), extra_J(fc::ForceTerm::shear), extra_J(fc::ForceTerm::bending),
                    extra_J(fc::ForceTerm::gravity), total);
        record[std::to_string(rows)] = {{"hem_free_mm", hem_mm(free_x)},
                                        {"hem_held_mm", hem_mm(held_x)},
                                        {"held_above_free_J", extra_J(fc::ForceTerm::conservative)},
                                        {"stretch_J", extra_J(fc::ForceTerm::stretch)},
                                        {"shear_J", extra_J(fc::ForceTerm::shear)},
                                        {"bending_J", extra_J(fc::ForceTerm::bending)},
                                        {"gravity_J", extra_J(fc::ForceTerm::gravity)},
                                        {"free_energy_J", total}};
    }
}

void print_row(const std::string& label, const Windows& w) {
    std::printf("| %-46s | %s | %s | %s | %s | %s |\n", label.c_str(), cell(w.frame1).c_str(), cell(w.f1_10).c_str(),
                cell(w.f11_25).c_str(), cell(w.f26_end).c_str(), cell(w.all).c_str());
}

// One prediction's chaos ensemble (the unchanged run and its members):
// each window's range and mean over the runs, as "low-high (mean)".
std::string ensemble_summary(const std::vector<Windows>& runs) {
    std::string text;
    char buffer[64];
    for (double Windows::*window : {&Windows::frame1, &Windows::f1_10, &Windows::f11_25, &Windows::f26_end, &Windows::all}) {
        double low = INFINITY, high = -INFINITY, sum = 0;
        for (const Windows& w : runs) {
            low = std::min(low, w.*window);
            high = std::max(high, w.*window);
            sum += w.*window;
        }
        std::snprintf(buffer, sizeof buffer, "%s%.1f-%.1f (%.1f)", text.empty() ? "" : " / ", low, high,
                      sum / static_cast<double>(runs.size()));
        text += buffer;
    }
    return text;
}

nlohmann::json ensemble_json(const std::vector<Windows>& runs) {
    nlohmann::json members = nlohmann::json::array();
    for (const Windows& w : runs) members.push_back(windows_json(w));
    return members;
}

// With --chaos-members N: Blender's run of `preset_capture` on `capture_name`
// again with the preset's bending and air damping changed by +-k parts in a
// million, k = 1..N, as the fits' predictions are scored; prints each
// window's range and mean over the runs (`unchanged` first) and records them.
void blender_ensemble(const Options& o, const std::string& capture_name, const std::string& preset_capture, int grid,
                      const Windows& unchanged, const fs::path& scratch, nlohmann::json& record) {
    if (o.chaos_members <= 0) return;
    std::vector<Windows> runs{unchanged};
    for (int k = 1; k <= o.chaos_members; ++k)
        for (const int sign : {1, -1}) {
            const std::vector<double> rms = blender_rms(o, capture_name, preset_capture, grid, scratch, sign * k);
            if (!rms.empty()) runs.push_back(windows_of(rms));
        }
    std::printf("|   the same changed by up to %d parts in a million (%zu runs), low-high (mean): %s mm |\n", o.chaos_members,
                runs.size(), ensemble_summary(runs).c_str());
    std::fflush(stdout);
    record = ensemble_json(runs);
}

int usage(const char* message) {
    std::fprintf(stderr, "flowvid_bench_cloth_capacity: %s\n", message);
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : std::string(); };
        if (a == "--fabrics") o.fabrics = flowvid::bench::comma_list(value());
        else if (a == "--variants") o.variants = flowvid::bench::comma_list(value());
        else if (a == "--evaluations") {
            o.evaluations.clear();
            for (const std::string& e : flowvid::bench::comma_list(value())) o.evaluations.push_back(std::atoll(e.c_str()));
        } else if (a == "--threads") o.threads = std::atoi(value().c_str());
        else if (a == "--seed") o.seed = std::strtoull(value().c_str(), nullptr, 10);
        else if (a == "--scratch") o.scratch = value();
        else if (a == "--captures") captures_dir() = value();
        else if (a == "--nested-from") o.nested_from = value();
        else if (a == "--json") o.json = value();
        else if (a == "--blender") o.blender = value();
        else if (a == "--no-blender") o.run_blender = false;
        else if (a == "--no-resolution") o.check_resolution = false;
        else if (a == "--waving-frames") o.waving_frames = std::atoi(value().c_str());
        else if (a == "--half-life") o.half_life_frames = std::atof(value().c_str());
        else if (a == "--static-weight") o.static_weight = std::atof(value().c_str());
        else if (a == "--min-bending") o.min_bending_N_m = std::atof(value().c_str());
        else if (a == "--resolution-of") o.resolution_of = value();
        else if (a == "--hem-energy") o.hem_energy = true;
        else if (a == "--equilibrium-steps") {
            const std::string steps = value();
            if (steps != "cg" && steps != "factorised") return usage("--equilibrium-steps takes cg or factorised");
            cg_equilibrium_steps() = steps == "cg";
        }
        else if (a == "--second-drape-mesh") {
            const std::string text = value();
            const std::optional<std::pair<int, int>> mesh = fc::mesh_size_from_text(text);
            if (text == "none") o.second_drape_rows = o.second_drape_cols = 0;
            else if (mesh) std::tie(o.second_drape_rows, o.second_drape_cols) = *mesh;
            else return usage("--second-drape-mesh takes RxC or none");
        }
        else if (a == "--outside-band") o.outside_band_px = std::atof(value().c_str());
        else if (a == "--score") o.score = flowvid::bench::comma_list(value());
        else if (a == "--budget-seconds") o.budget_seconds = std::atof(value().c_str());
        else if (a == "--shear-cells") {
            o.shear_cells = std::atof(value().c_str());
            if (!(*o.shear_cells >= 0.0 && *o.shear_cells <= 1.0)) return usage("--shear-cells takes a share from 0 to 1");
        }
        else if (a == "--chaos-members") o.chaos_members = std::atoi(value().c_str());
        else if (a == "--score-from-measured-start") o.score_from_measured_start = true;
        else if (a == "--score-start-material") o.score_start_material = value();
        else if (a == "--start-from") o.start_from = value();
        else if (a == "--refine-rounds") o.refine_rounds = std::atoi(value().c_str());
        else if (a == "--search") {
            const std::optional<flowvid::optim::SearchMethod> search = flowvid::optim::search_method_from_name(value());
            if (!search) return usage("--search takes annealing or cmaes");
            o.search = *search;
        }
        else if (a == "--fit-to") {
            const std::optional<cf::FitTarget> target = cf::fit_target_from_name(value());
            if (!target) return usage("--fit-to takes tracks, scan or footage");
            o.fit_to = *target;
        }
        else if (a == "--blender-grids") {
            o.blender_grids.clear();
            for (const std::string& g : flowvid::bench::comma_list(value())) o.blender_grids.push_back(std::atoi(g.c_str()));
        } else if (a == "--help" || a == "-h") {
            std::printf("flowvid_bench_cloth_capacity [--fabrics cotton,silk]\n"
                        "  [--variants today,compression,linear-drag,hem,diagonal,all]\n"
                        "  [--evaluations 400[,800]] [--captures DIR (cloth-<fabric>-static-1, -waving-1, -waving-2)]\n"
                        "  [--threads 2] [--seed 1] [--scratch DIR] [--json FILE] [--blender PATH | --no-blender]\n"
                        "  [--blender-grids 12,24,48] [--no-resolution] [--nested-from EARLIER.json]\n"
                        "  [--waving-frames 20] [--half-life 5] [--static-weight W] (the waving trial's fitted frames,\n"
                        "   their weights' half-life after the first 10, the static drape's weight -- default: as much\n"
                        "   as the waving trial's frames together, as fit cloth's; predictions always cover the whole\n"
                        "   held-out trial)\n"
                        "  [--min-bending N_m] (a floor on the fitted bending stiffness; default: the fit's range)\n"
                        "  [--resolution-of PRESET] (check this preset on 12x12, 24x24, 48x48 instead of the last fit;\n"
                        "    with --variants \"\" nothing is fitted)\n"
                        "  [--hem-energy] (with the mesh check: each mesh's drape with its bottom corners held where the\n"
                        "    measured frame has them, and what that costs per term of the potential energy)\n"
                        "  [--equilibrium-steps factorised|cg] (how every static solve takes its definite steps;\n"
                        "    cg: as before factorised steps, to compare the two)\n"
                        "  [--outside-band 16] (scan fits: background pixels this near the swatch's outline count\n"
                        "   against a simulation covering them; 0: off)\n"
                        "  [--budget-seconds 600] (each fit also ends at this wall-clock time, as fit cloth's)\n"
                        "  [--shear-cells 0..1] (fit cloth --shear-cells; default 1 for tracks fits, else 0)\n"
                        "  [--refine-rounds N] (fit cloth --refine-rounds: searches again from the best fabric, its fold states picked again)\n"
                        "  [--score A.fabric.json,B.fabric.json] (instead of fitting: each preset's training objective\n"
                        "   under the fit's settings, its held-out waving-2 prediction and its drapes, first fabric only)\n"
                        "  [--score-from-measured-start] (with --score: the trials start from their measured first\n"
                        "   frames, a tracks fit's start, instead of the footage's own: how much the start decides)\n"
                        "  [--score-start-material P.fabric.json] (with --score: the footage's start is chosen with\n"
                        "   this preset's fabric instead of the middle of the ranges)\n"
                        "  [--start-from P.fabric.json] (the fits start from this preset, its fabric also picking\n"
                        "   the fold states, instead of the middle of the ranges: a second round of a fit)\n"
                        "  [--chaos-members 0] (with --score: the prediction again with bending and drag changed by\n"
                        "   +-k parts in a million, k = 1..N; Blender's waving rows likewise, its preset's bending\n"
                        "   and air damping changed: each window's range and mean over the runs, the spread chaos\n"
                        "   alone gives it)\n"
                        "  [--search annealing|cmaes] (the search after the design, as fit cloth --search)\n"
                        "  [--fit-to tracks|scan|footage] (scan: the footage's stripe scan, footage: its angle maps and\n"
                        "   silhouettes, instead of the tracks; the predictions are scored against truth the same way)\n");
            return 0;
        } else return usage(("unknown option " + a).c_str());
    }
    const fs::path scratch = o.scratch;
    fs::create_directories(scratch);
    if (o.fit_to == cf::FitTarget::tracks)
        std::printf("Model capacity study: each public capture's truth/positions.exr is handed to the fit as 3D tracks\n"
                    "in a scratch copy (%s); this is the one place truth reaches a fit, and it says nothing about\n"
                    "the footage fit, only about what the model can reach. RMS vertex error against truth, mm.\n",
                    (scratch / "tracks").string().c_str());
    else
        std::printf("Footage fit (--fit-to %s): the fit reads the shared captures' footage, never truth/; the\n"
                    "predictions start from each capture's measured first frame (truth handed over as tracks in\n"
                    "%s) and are scored against truth/, evaluation only. RMS vertex error, mm.\n",
                    cf::fit_target_name(o.fit_to), (scratch / "tracks").string().c_str());
    nlohmann::json record;
    for (const std::string& fabric : o.fabrics) {
        std::string other = fabric == "cotton" ? "silk" : "cotton";  // the wrong fabric of the bound rows
        for (const std::string& f : o.fabrics)
            if (f != fabric) other = f;
        const std::string static1 = "cloth-" + fabric + "-static-1", waving1 = "cloth-" + fabric + "-waving-1",
                          waving2 = "cloth-" + fabric + "-waving-2", static2 = "cloth-" + fabric + "-static-2";
        const bool has_static2 = fs::exists(shared_capture(static2));
        std::map<std::string, std::string> copies;
        for (const std::string& name : {static1, waving1, waving2})
            copies[name] = tracks_copy(name, scratch);
        if (has_static2) copies[static2] = tracks_copy(static2, scratch);
        // A tracks fit reads the scratch copies (truth as tracks); the others the shared footage.
        const auto training_captures = [&] {
            if (o.fit_to == cf::FitTarget::tracks)
                return std::vector<ff::Capture>{ff::read_capture(copies[static1]), ff::read_capture(copies[waving1])};
            return std::vector<ff::Capture>{ff::read_capture(shared_capture(static1)), ff::read_capture(shared_capture(waving1))};
        };

        std::printf("\n### %s: fit %s + %s to %s, predict %s%s\n\n", fabric.c_str(), static1.c_str(), waving1.c_str(),
                    cf::fit_target_name(o.fit_to), waving2.c_str(), has_static2 ? (" and " + static2).c_str() : "");
        if (!o.score.empty()) {
            const std::vector<ff::Capture> captures = training_captures();
            const cf::TrialLoadSettings load = training_load(o, captures);
            std::vector<cf::ClothTrial> trials = cf::load_trials(captures, load);
            const std::vector<cf::FittedParameter> parameters = cf::parameters_for(trials, cf::DragModel::nonlinear);
            cf::ClothFitSettings settings = fit_settings();
            settings.base = cf::middle_of_ranges(settings.base, parameters);  // as the fit's (its warm start)
            if (!o.score_start_material.empty()) {
                // The start chosen with this fabric instead (as a second round of a fit would).
                settings.base = fc::material_from_fabric(ff::read_fabric_preset(o.score_start_material).parameters);
                std::printf("(the footage's start chosen with %s's fabric)\n", o.score_start_material.c_str());
            }
            cf::ClothFitProblem problem(std::move(trials), parameters, settings);
            if (o.score_from_measured_start && o.fit_to != cf::FitTarget::tracks) {
                // Each trial starts where its tracks fit would: the measured
                // (truth's) first frame, instead of the footage's own start.
                cf::TrialLoadSettings tracks_load = load;
                tracks_load.target = cf::FitTarget::tracks;
                const cf::ClothFitProblem measured(
                    cf::load_trials({ff::read_capture(copies[static1]), ff::read_capture(copies[waving1])}, tracks_load),
                    parameters, settings);
                for (std::size_t t = 0; t < problem.trials().size(); ++t) problem.set_warm_start(t, measured.warm_start(t));
                std::printf("(each trial started from its measured first frame, as a tracks fit's)\n");
            }
            for (const std::string& path : o.score) {
                const fc::ClothMaterial m = fc::material_from_fabric(ff::read_fabric_preset(path).parameters);
                const cf::ClothEvaluation e = problem.evaluate(m, o.threads);
                std::printf("training objective of %s: %.1f (", path.c_str(), e.total);
                for (std::size_t t = 0; t < e.trials.size(); ++t)
                    std::printf("%s%s %.1f", t ? ", " : "", problem.trials()[t].name.c_str(), e.trials[t].error);
                std::printf(")\n");
                const Windows held_out = predict(copies[waving2], m, o.threads);
                std::printf("  %s held out (frame 1 / 1-10 / 11-25 / 26-end / all): %.1f / %.1f / %.1f / %.1f / %.1f mm\n",
                            waving2.c_str(), held_out.frame1, held_out.f1_10, held_out.f11_25, held_out.f26_end, held_out.all);
                // The drapes, as the fits' rows print them: static-1 (trained on) and static-2 (held out).
                std::printf("  static drape: %s %.1f mm", static1.c_str(), predict(copies[static1], m, o.threads).frame1);
                if (has_static2) std::printf(", %s (held out) %.1f mm", static2.c_str(), predict(copies[static2], m, o.threads).frame1);
                std::printf("\n");
                if (o.chaos_members > 0) {
                    // The member runs, the unchanged one first: each window's range and mean over them.
                    // The training objective too: how finely the fit can tell two presets apart.
                    std::vector<Windows> members{held_out};
                    double objective_low = e.total, objective_high = e.total, objective_sum = e.total;
                    for (int k = 1; k <= o.chaos_members; ++k)
                        for (const double sign : {1.0, -1.0}) {
                            fc::ClothMaterial changed = m;
                            const double factor = 1.0 + sign * 1e-6 * k;
                            changed.bend_N_m *= factor;
                            changed.drag_normal_kg_per_m3 *= factor;
                            changed.drag_linear_normal_kg_per_m2_s *= factor;
                            members.push_back(predict(copies[waving2], changed, o.threads));
                            const double objective = problem.evaluate(changed, o.threads).total;
                            objective_low = std::min(objective_low, objective);
                            objective_high = std::max(objective_high, objective);
                            objective_sum += objective;
                        }
                    std::printf("  the same changed by up to %d parts in a million (%zu runs), low-high (mean): %s mm; "
                                "training objective %.1f-%.1f (%.1f)\n",
                                o.chaos_members, members.size(), ensemble_summary(members).c_str(), objective_low, objective_high,
                                objective_sum / static_cast<double>(members.size()));
                }
                std::fflush(stdout);
            }
            break;
        }
        std::printf("| model (waving-2 held out) | frame 1 | 1-10 | 11-25 | 26-end | all |\n|---|---|---|---|---|---|\n");
        std::optional<fc::ClothMaterial> nested_start;  // the best fit of a smaller model so far
        if (!o.nested_from.empty()) {
            // The first variant and budget recorded for this fabric in an earlier run.
            std::ifstream in(o.nested_from);
            const nlohmann::json earlier = nlohmann::json::parse(in);
            if (earlier.contains(fabric)) {
                const nlohmann::json& variants = earlier[fabric];
                for (const char* name : {"today", "compression", "linear-drag", "hem", "diagonal", "all"})
                    if (variants.contains(name) && !nested_start) {
                        fc::ClothMaterial m;
                        for (const auto& [key, value] : variants[name].begin()->at("parameters").items())
                            cf::set_material_parameter(m, key, value.get<double>());
                        nested_start = m;
                        std::fprintf(stderr, "  [%s] larger models also start from %s's %s fit\n", fabric.c_str(),
                                     o.nested_from.c_str(), name);
                    }
            }
        }
        std::optional<fc::ClothMaterial> last_fitted;
        for (const std::string& variant : o.variants) {
            for (const long long evaluations : o.evaluations) {
                cf::ClothFitRequest request;
                request.name = fabric + " " + variant;
                request.captures = training_captures();
                request.load = training_load(o, request.captures);
                request.problem = fit_settings();
                // Without a time budget the study solves every candidate to
                // the simulator's limit: it measures the model, and soft
                // fabrics that need 400-2000 iterations rank truly (its
                // figures since stop 56; with fit cloth's 400 the cotton fit
                // drapes 29 mm apart on 12x12 and 24x24 instead of 19).
                if (o.budget_seconds <= 0.0) request.problem.evaluation_equilibrium_iterations = 0;
                request.shear_cell_fraction = o.shear_cells;
                request.problem.second_drape_rows = o.second_drape_rows;
                request.problem.second_drape_cols = o.second_drape_cols;
                request.parameters = variant_parameters(variant);
                request.min_bending_N_m = o.min_bending_N_m;
                request.search = o.search;
                request.evaluations = evaluations;
                request.budget_seconds = o.budget_seconds;
                if (!o.start_from.empty())
                    request.start = fc::material_from_fabric(ff::read_fabric_preset(o.start_from).parameters);
                request.refine_rounds = o.refine_rounds;
                request.variability_runs = 0;
                request.seed = o.seed;
                request.threads = o.threads;
                const std::string tag = fabric + "/" + variant + "/" + std::to_string(evaluations);
                auto last = std::make_shared<long long>(-1000);
                request.progress = [tag, last](const flowvid::ProgressReport& p) {
                    const long long percent = static_cast<long long>(100 * p.fraction);
                    if (percent - *last >= 10 || p.stage == "polish") {
                        std::fprintf(stderr, "  [%s] %s, %s\n", tag.c_str(), p.stage.c_str(), p.message.c_str());
                        *last = percent;
                    }
                    return true;
                };
                std::fprintf(stderr, "fitting %s\n", tag.c_str());
                cf::ClothFitOutcome fit = cf::fit_cloth(request);
                // Evaluations and the best training error so far, as the fit went.
                nlohmann::json curve = nlohmann::json::array();
                for (const flowvid::bench::CurvePoint& point : flowvid::bench::curve_of(fit))
                    curve.push_back({point.evaluations, point.best});
                nlohmann::json rounds = nlohmann::json::array();
                for (const cf::ClothFitRound& r : fit.rounds) {
                    std::fprintf(stderr, "  [%s] round %zu: %.4g -> %.4g, %lld evaluations, %.0f s\n", tag.c_str(), rounds.size() + 1,
                                 r.start_error, r.best_error, r.evaluations, r.seconds);
                    rounds.push_back({{"start_error", r.start_error}, {"best_error", r.best_error}, {"evaluations", r.evaluations},
                                      {"seconds", r.seconds}});
                }
                // A larger model nests the smaller one: also polish from the
                // best smaller fit so far (its new terms at their neutral
                // values, clamped into range), and keep whichever fits better.
                if (nested_start) {
                    cf::ClothFitSettings settings = request.problem;
                    settings.base = fit.start;
                    const cf::ClothFitProblem problem(fit.trials, fit.parameters, settings);
                    optim::LeastSquaresSettings polish;
                    polish.max_evaluations = 8LL * (static_cast<long long>(fit.parameters.size()) + 1);
                    polish.threads = o.threads;
                    const optim::LeastSquaresResult nested = optim::levenberg_marquardt(
                        [&problem](const Eigen::VectorXd& values, int threads) {
                            return problem.residuals(problem.material(values), threads);
                        },
                        problem.space(), problem.space().clamp_values(problem.values_of(*nested_start)), polish);
                    std::fprintf(stderr, "  [%s] polished from the smaller fit: %.4g (own search %.4g)\n", tag.c_str(),
                                 nested.best_value, fit.final_evaluation.total);
                    if (nested.best_value < fit.final_evaluation.total) {
                        fit.fitted = problem.material(nested.best_values);
                        fit.final_evaluation = problem.evaluate(fit.fitted, o.threads);
                    }
                    fit.evaluations += nested.evaluations;
                }
                if (!nested_start || variant == "today") nested_start = fit.fitted;
                if (fit.preset) {
                    // The fitted fabric as a preset (recognition, other meshes); the nested
                    // polish may have moved it, so its values are the final ones.
                    ff::FabricPreset preset = *fit.preset;
                    const ff::FabricParameters values =
                        fc::fabric_from_material(fc::experiment_material(fit.trials.front().experiment, fit.fitted));
                    for (const ff::FabricParameterInfo& info : ff::fabric_parameter_table())
                        (preset.parameters.*(info.member)).value = (values.*(info.member)).value;
                    ff::write_fabric_preset((scratch / (fabric + "-" + variant + "-" + std::to_string(evaluations) + ".fabric.json")).string(),
                                            preset);
                }
                last_fitted = fit.fitted;
                const Windows held_out = predict(copies[waving2], fit.fitted, o.threads);
                const Windows start = predict(copies[waving2], fit.start, o.threads);
                const Windows training_waving = predict(copies[waving1], fit.fitted, o.threads);
                const Windows training_static = predict(copies[static1], fit.fitted, o.threads);
                Windows held_static;
                if (has_static2) held_static = predict(copies[static2], fit.fitted, o.threads);
                const std::string label = variant + " (" + std::to_string(fit.parameters.size()) + " parameters, " +
                                          std::to_string(fit.evaluations) + " evaluations)";
                print_row(label, held_out);
                std::printf("|   its start (middle of the ranges)              | %s | %s | %s | %s | %s |\n", cell(start.frame1).c_str(),
                            cell(start.f1_10).c_str(), cell(start.f11_25).c_str(), cell(start.f26_end).c_str(), cell(start.all).c_str());
                std::printf("|   training: %-35s | %s | %s | %s | %s | %s |\n", waving1.c_str(), cell(training_waving.frame1).c_str(),
                            cell(training_waving.f1_10).c_str(), cell(training_waving.f11_25).c_str(),
                            cell(training_waving.f26_end).c_str(), cell(training_waving.all).c_str());
                std::printf("|   static drape: %s (fitted) %s%s   |\n", static1.c_str(), cell(training_static.frame1).c_str(),
                            has_static2 ? (", " + static2 + " (held out) " + cell(held_static.frame1)).c_str() : "");
                std::fflush(stdout);
                nlohmann::json parameters;
                for (const cf::FittedParameter& p : fit.parameters) parameters[p.key] = cf::material_parameter(fit.fitted, p.key);
                record[fabric][variant][std::to_string(evaluations)] = {
                    {"parameters", parameters},
                    {"parameter_count", fit.parameters.size()},
                    {"evaluations", fit.evaluations},
                    {"seconds", fit.seconds},
                    {"training_error", fit.final_evaluation.total},
                    {"rounds", rounds},
                    {"fit_to", cf::fit_target_name(o.fit_to)},
                    {"curve", curve},
                    {"held_out_waving", windows_json(held_out)},
                    {"start_waving", windows_json(start)},
                    {"training_waving", windows_json(training_waving)},
                    {"training_static_frame_1_mm", training_static.frame1},
                    {"held_out_static_frame_1_mm", has_static2 ? nlohmann::json(held_static.frame1) : nlohmann::json(nullptr)}};
                // After every fit, so that a long study that stops keeps its fits.
                if (!o.json.empty())
                    ff::write_file_atomically(o.json, [&](std::ostream& out) { out << record.dump(2) << '\n'; });
            }
        }
        if (!o.resolution_of.empty())
            last_fitted = fc::material_from_fabric(ff::read_fabric_preset(o.resolution_of).parameters);
        if (last_fitted && o.check_resolution) {
            // The fitted fabric must be the same fabric on other meshes: its
            // held-out prediction at 12 x 12 and 48 x 48 against 24 x 24.
            std::map<int, fc::GridFrames> runs;
            for (const int rows : {12, 24, 48}) runs[rows] = predict_at(copies[waving2], *last_fitted, rows, o.threads);
            auto compare = [&](int a, int b) {
                if (runs[a].empty() || runs[b].empty()) {
                    std::printf("|   resolution, %s: %dx%d vs %dx%d: a run failed (stderr says why) |\n", waving2.c_str(),
                                a, a, b, b);
                    return;
                }
                const std::vector<double> rms = fc::rms_distance_per_frame_m(runs[a], runs[b]);
                const double frame1_max = (runs[a].front() - runs[b].front()).rowwise().norm().maxCoeff();
                std::printf("|   resolution, %s: %dx%d vs %dx%d: frame 1 max %.1f mm, RMS frame 1 %.1f, 1-10 %.1f, all %.1f mm |\n",
                            waving2.c_str(), a, a, b, b, 1e3 * frame1_max, 1e3 * rms.front(), windows_of(rms).f1_10,
                            windows_of(rms).all);
                record[fabric]["resolution"][std::to_string(a) + "_" + std::to_string(b)] = {
                    {"frame_1_max_mm", 1e3 * frame1_max}, {"rms", windows_json(windows_of(rms))}};
            };
            compare(12, 24);
            compare(24, 48);
            // Each drape as a user's simulation makes it (from the hanging
            // start, no measured shape) and as a prediction starts (from the
            // measured shape), in the drape test's comparison: distances at
            // the 12 x 12 uv points; it allows 20 mm max between 12x12 and
            // 24x24.
            for (const std::string& drape : has_static2 ? std::vector<std::string>{static1, static2} : std::vector<std::string>{static1}) {
                std::map<int, std::optional<Eigen::MatrixX3d>> hanging, measured;
                for (const int rows : {12, 24, 48}) {
                    hanging[rows] = equilibrium_drape_at(drape, *last_fitted, rows);
                    // From the drape's measured shape, as a prediction starts.
                    const fc::GridFrames run = predict_at(copies[drape], *last_fitted, rows, o.threads);
                    if (!run.empty()) measured[rows] = resample(run.front(), 24, 24, 12, 12);
                }
                report_mesh_agreement("resolution, " + drape + " drape from the hanging start", hanging,
                                      record[fabric]["resolution_equilibrium"][drape]);
                report_mesh_agreement("resolution, " + drape + " drape from its measured first frame", measured,
                                      record[fabric]["resolution_measured"][drape]);
                if (o.hem_energy) report_hem_energy(drape, *last_fitted, record[fabric]["hem_energy"][drape]);
                if (const std::optional<ff::VertexAnimation> shape = ff::read_capture_tracks(ff::read_capture(copies[drape]));
                    shape && shape->grid_cols) {
                    const double width = hem_width_mm(fc::grid_frames_of(*shape).front(), *shape->grid_cols);
                    std::printf("|   resolution, %s: the measured first frame's hem width %s mm |\n", drape.c_str(), cell(width).c_str());
                    record[fabric]["resolution_measured"][drape]["measured_hem_width_mm"] = width;
                }
                // What the 12 x 12 mesh cannot be given: the start's detail
                // finer than its grid. The 24 x 24 mesh started from the
                // measured shape as a 12 x 12 mesh holds it: how far the
                // drape moves for that alone (the same mesh, the same fabric),
                // beside how far the 12 x 12 drape is from it.
                const fc::GridFrames coarse_start =
                    predict_at(tracks_copy(drape, scratch, 12), *last_fitted, 24, o.threads);
                if (!coarse_start.empty() && measured[24] && measured[12]) {
                    const std::optional<Eigen::MatrixX3d> held = resample(coarse_start.front(), 24, 24, 12, 12);
                    const double max_24 = max_distance_mm(held, measured[24]), rms_24 = rms_distance_mm(held, measured[24]);
                    const double max_12 = max_distance_mm(held, measured[12]), rms_12 = rms_distance_mm(held, measured[12]);
                    const double held_hem_mm = hem_width_mm(held, 12);
                    std::printf("|   resolution, %s: the 24x24 drape from the measured shape as a 12x12 mesh holds it, at the 12x12 "
                                "uv points, max / RMS: %s / %s mm from the 24x24 drape from the full shape, %s / %s mm from the "
                                "12x12 drape; hem width %s mm |\n",
                                drape.c_str(), cell(max_24).c_str(), cell(rms_24).c_str(), cell(max_12).c_str(), cell(rms_12).c_str(),
                                cell(held_hem_mm).c_str());
                    record[fabric]["resolution_start_through_12"][drape] = {{"max_vs_24_mm", max_24},
                                                                            {"rms_vs_24_mm", rms_24},
                                                                            {"max_vs_12_mm", max_12},
                                                                            {"rms_vs_12_mm", rms_12},
                                                                            {"hem_width_mm", held_hem_mm}};
                }
            }
        }
        if (o.run_blender) {
            std::printf("|   *Blender itself, from the measured first frame* |  |  |  |  |  |\n");
            for (const int grid : o.blender_grids) {
                const std::vector<double> rms = blender_rms(o, waving2, waving2, grid, scratch);
                if (rms.empty()) continue;
                const Windows w = windows_of(rms);
                print_row("Blender " + fabric + " preset, " + std::to_string(grid) + "x" + std::to_string(grid) + " mesh", w);
                record[fabric]["blender"][std::to_string(grid)] = windows_json(w);
                blender_ensemble(o, waving2, waving2, grid, w, scratch, record[fabric]["blender_chaos"][std::to_string(grid)]);
                const std::string drape = has_static2 ? static2 : static1;
                const std::vector<double> drape_rms = blender_rms(o, drape, drape, grid, scratch);
                if (!drape_rms.empty()) {
                    std::printf("|   static drape %s: frame 1 %s   |\n", drape.c_str(), cell(1e3 * drape_rms.front()).c_str());
                    record[fabric]["blender_static"][std::to_string(grid)] = 1e3 * drape_rms.front();
                }
            }
            // Blender's own fabric on other meshes, in the drape test's
            // measure: the bound on how alike a preset fitted to it can be.
            for (const std::string& drape : has_static2 ? std::vector<std::string>{static1, static2} : std::vector<std::string>{static1})
                for (const bool measured : {false, true})
                    for (const bool held : {false, true}) {
                        std::map<int, std::optional<Eigen::MatrixX3d>> shapes;
                        for (const int grid : {12, 24, 48}) shapes[grid] = blender_drape_at(o, drape, grid, measured, held, scratch);
                        report_mesh_agreement("Blender's own " + drape + " drape from the " +
                                                  (measured ? "measured first frame" : "hanging start") + ", " +
                                                  (held ? "total mass held" : "preset mass per vertex"),
                                              shapes,
                                              record[fabric]["blender_resolution"][drape][std::string(measured ? "measured" : "hanging") +
                                                                                         (held ? "_held_mass" : "")]);
                    }
            const std::string wrong_preset = "cloth-" + other + "-waving-2";
            const std::vector<double> wrong =
                fs::exists(shared_capture(wrong_preset)) ? blender_rms(o, waving2, wrong_preset, 24, scratch) : std::vector<double>{};
            if (!wrong.empty()) {
                const Windows w = windows_of(wrong);
                print_row("Blender " + other + " preset (wrong fabric), 24x24", w);
                record[fabric]["blender_wrong_fabric"] = windows_json(w);
                blender_ensemble(o, waving2, wrong_preset, 24, w, scratch, record[fabric]["blender_wrong_fabric_chaos"]);
            }
        }
    }
    if (!o.json.empty())
        ff::write_file_atomically(o.json, [&](std::ostream& out) { out << record.dump(2) << '\n'; });
    return 0;
}
