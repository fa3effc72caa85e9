// flowvid bench gap: sealed cases for the gap diagnosis, the diagnosis of
// each, and the score (top-1 accuracy per effect and per effect-to-noise bin,
// false alarms on effect-free cases, median share of the held-out gap closed).
//
//   flowvid bench gap --cases N --seed S --out DIR --scene CAPTURE... --fabric PRESET...
//   flowvid bench gap --diagnose DIR      (resumable: diagnosed cases are kept)
//   flowvid bench gap --score DIR
// DIR/cases/case-NNN/ hold captures and base.fabric.json (what the
// diagnoser gets); DIR/labels.json holds the hidden effects (never read by
// the diagnoser: only --score reads it; format flowvid.gap_bench_labels,
// formats/specs/gap_bench_labels.md); DIR/results/case-NNN/diagnosis.json
// the diagnoses (flowvid.diagnosis, formats/specs/diagnosis.md).

#include "commands/diagnose.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/gap/bench.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

namespace flowvid::cli {
namespace {

namespace fs = std::filesystem;

struct BenchGapOptions {
    int cases = 24;
    std::uint64_t seed = 1;
    std::string out;
    std::vector<std::string> scenes;
    std::vector<std::string> rigid_scenes;
    std::vector<std::string> fabrics;
    std::vector<std::string> effects;
    FrameOptions frame_selection;  // resolved into bench.frames
    std::string diagnose_dir;
    std::string score_dir;
    DiagnoseClothOptions diagnose;
    gap::BenchSettings bench;
    std::string footage_integrator = "implicit";
    std::string footage_resolution = "24x24";
    bool oracle = false;  // score: also the gap the true effect closes in the diagnoser's model
    int threads = 0;
};

int generate(const BenchGapOptions& options, const GlobalOptions& global) {
    gap::BenchMakeRequest request;
    request.out_dir = options.out;
    request.cases = options.cases;
    request.seed = options.seed;
    request.scene_paths = options.scenes;
    request.rigid_scene_paths = options.rigid_scenes;
    request.fabric_paths = options.fabrics;
    request.settings = options.bench;
    request.settings.effects = options.effects;
    request.footage_integrator_name = options.footage_integrator;
    request.threads = options.threads;
    TerminalProgress progress(global, "bench gap");
    const formats::GapBenchLabels labels = gap::make_bench_cases(request, progress.callback());
    progress.finish();
    std::cout << "wrote " << labels.cases.size() << " cases to " << (fs::path(options.out) / "cases").string()
              << " and their labels to " << (fs::path(options.out) / "labels.json").string() << '\n';
    return kExitOk;
}

int diagnose_all(const BenchGapOptions& options, const gap::ClothGapRequest& cloth, const GlobalOptions& global) {
    const std::vector<std::string> folders = gap::bench_case_folders(options.diagnose_dir);
    if (folders.empty()) {
        log_message(options.diagnose_dir + ": no cases/*/capture.json (make them with flowvid bench gap --out)");
        return kExitIoError;
    }
    TerminalProgress progress(global, "bench gap");
    const flowvid::Progress report = progress.callback();
    for (std::size_t i = 0; i < folders.size(); ++i) {
        const std::string id = fs::path(folders[i]).filename().string();
        const std::string out = (fs::path(options.diagnose_dir) / "results" / id).string();
        if (fs::exists(fs::path(out) / "diagnosis.json")) continue;  // resumable
        if (!report({"diagnosing", static_cast<double>(i) / folders.size(), id})) return kExitInterrupted;
        const gap::OpenedGapModel opened = gap::open_bench_case(folders[i], cloth, options.threads);
        gap::DiagnoseSettings settings;
        settings.progress = [&](const ProgressReport&) { return !progress.interrupted(); };
        write_diagnosis(out, gap::diagnosis_document(gap::diagnose(*opened.model, settings), opened.description));
    }
    return kExitOk;
}

int score(const std::string& dir, const BenchGapOptions& options, const gap::ClothGapRequest& cloth) {
    gap::BenchScoreRequest request;
    request.dir = dir;
    request.oracle = options.oracle;
    request.cloth = cloth;
    request.threads = options.threads;
    const gap::BenchScore s = gap::score_bench(request);
    print_problems(s.warnings);
    const auto percent = [](const gap::BenchTally& t) { return t.cases ? 100.0 * t.correct / t.cases : std::nan(""); };
    std::printf("top-1 accuracy per effect\n");
    for (const auto& [effect, t] : s.per_effect)
        std::printf("  %-16s %3d / %-3d  %5.1f %%\n", effect.c_str(), t.correct, t.cases, percent(t));
    std::printf("top-1 accuracy per effect-to-noise bin\n");
    for (const std::string& bin : gap::effect_to_noise_bins()) {
        const auto found = s.per_bin.find(bin);
        const gap::BenchTally t = found == s.per_bin.end() ? gap::BenchTally{} : found->second;
        std::printf("  %-6s %3d / %-3d  %5.1f %%\n", bin.c_str(), t.correct, t.cases, percent(t));
    }
    std::printf("effect >= 4x noise: top-1 %d / %d = %.1f %% (goal >= 90 %%)\n", s.strong.correct, s.strong.cases,
                percent(s.strong));
    std::printf("false alarms (an effect named on an effect-free case): %d / %d = %.1f %% (goal <= 5 %%)\n",
                s.false_alarms.correct, s.false_alarms.cases, percent(s.false_alarms));
    std::printf("gap detected on effect-free cases: %d / %d\n", s.gap_detected_on_none, s.false_alarms.cases);
    std::printf("median held-out gap closed: %.2f over effects >= 4x noise (0 when not named; goal >= 0.80), %.2f over "
                "correctly named cases\n",
                s.median_gap_closed_strong, s.median_gap_closed_named);
    if (options.oracle)
        std::printf("median held-out gap the true effect closes in the diagnoser's model (the most a diagnosis can close): "
                    "%.2f over effects >= 4x noise\n",
                    s.median_oracle_gap_closed_strong);
    return kExitOk;
}

int run_bench_gap(const BenchGapOptions& options, const GlobalOptions& global) {
    const int modes = (!options.out.empty()) + (!options.diagnose_dir.empty()) + (!options.score_dir.empty());
    if (modes != 1) {
        log_message("flowvid bench gap: give exactly one of --out DIR (make cases), --diagnose DIR, --score DIR");
        return kExitUsage;
    }
    if (!options.out.empty()) return generate(options, global);
    const std::optional<gap::ClothGapRequest> cloth = cloth_gap_request(options.diagnose);
    if (!cloth) return kExitUsage;
    if (!options.diagnose_dir.empty()) {
        const int status = diagnose_all(options, *cloth, global);
        if (status != kExitOk) return status;
        return score(options.diagnose_dir, options, *cloth);
    }
    return score(options.score_dir, options, *cloth);
}

}  // namespace

// `flowvid bench <what>`: benchmarks that are commands (the speed benchmarks are bench/ executables).
const RegisterCommand bench_registration{Command{
    "bench", "benchmarks with sealed cases: `flowvid bench gap ...`", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<BenchGapOptions>();
        options->diagnose.run.resolution = diagnoser_resolution();
        app.require_subcommand(1);
        CLI::App* gap = app.add_subcommand("gap", "sealed cases for flowvid diagnose, and its score");
        gap->footer(
            "Makes cloth captures with this project's simulator at a finer mesh (24x24) and smaller time step\n"
            "(10 substeps per frame) than the diagnoser uses (20x20, 5), each with one hidden effect or none\n"
            "(about a quarter), strengths drawn log-uniformly, filmed with stripes and sensor noise; with\n"
            "--rigid-scene also rigid tosses (RK4 at 1/960 s against the diagnoser's 1/240 s) with air drag or\n"
            "an inertia error. Labels go to DIR/labels.json, which only --score reads. A label's effect-to-noise\n"
            "is the effect alone (the exact effect-free model at the footage's own mesh) in units of the\n"
            "repeatability floor the diagnoser uses; --strength scales every drawn magnitude to fill the bins.\n\n"
            "Examples:\n"
            "  flowvid bench gap --cases 40 --seed 7 --out gapbench \\\n"
            "      --scene ../shared/captures/cloth-cotton-waving-1 --scene ../shared/captures/cloth-silk-waving-2 \\\n"
            "      --fabric cotton.fabric.json --fabric silk.fabric.json\n"
            "  flowvid bench gap --cases 12 --strength 4 --out strong ...   # effects four times as strong\n"
            "  flowvid bench gap --diagnose gapbench     # diagnoses every case (resumable), then scores\n"
            "  flowvid bench gap --score gapbench");
        gap->add_option("--cases", options->cases, "cases to make")->check(CLI::Range(1, 10000))->capture_default_str();
        gap->add_option("--seed", options->seed, "seed of the draw")->capture_default_str();
        gap->add_option("--out", options->out, "folder for the cases and labels");
        gap->add_option("--scene", options->scenes, "cloth.waving capture whose camera, projector and pins a case uses (repeat)");
        gap->add_option("--fabric", options->fabrics, "fabric preset a case uses (repeat)");
        gap->add_option("--rigid-scene", options->rigid_scenes,
                        "rigid.toss capture whose body and camera rigid cases use (repeat; adds air_drag and inertia_error)");
        gap->add_option("--effects", options->effects, "effects to draw from (default: every cloth and camera effect)")->delimiter(',');
        add_frame_options(*gap, options->frame_selection, "frames 1 to B of each case (cases start at frame 1)",
                          "frames per case", "30");
        std::vector<std::string> integrator_names;
        for (const auto& [name, value] : cloth::integrators_by_short_name()) integrator_names.push_back(name);
        gap->add_option("--footage-integrator", options->footage_integrator, "integrator the cases are made with")
            ->check(CLI::IsMember(integrator_names))
            ->capture_default_str();
        gap->add_option("--footage-resolution", options->footage_resolution, "the footage's mesh, RxC (finer than the diagnoser's)")
            ->capture_default_str();
        gap->add_option("--footage-substeps", options->bench.implicit_substeps, "the footage's steps per frame (implicit integrators)")
            ->check(CLI::Range(1, 1000))
            ->capture_default_str();
        gap->add_option("--strength", options->bench.strength,
                        "multiplies every drawn effect magnitude (1: log-uniform over what a swatch test meets)")
            ->check(CLI::Range(0.01, 100.0))
            ->capture_default_str();
        gap->add_option("--none-share", options->bench.none_share, "share of effect-free cases")
            ->check(CLI::Range(0.0, 1.0))
            ->capture_default_str();
        gap->add_option("--integrator", options->diagnose.run.integrator, "the diagnoser's integrator (with --diagnose)")
            ->check(CLI::IsMember(integrator_names))
            ->capture_default_str();
        gap->add_option("--resolution", options->diagnose.run.resolution, "the diagnoser's mesh, RxC (with --diagnose)")
            ->capture_default_str();
        gap->add_option("--silhouette-weight", options->diagnose.silhouette_weight,
                        "the diagnoser's silhouette weight (with --diagnose or --oracle; labels are measured with the default)")
            ->check(CLI::NonNegativeNumber)
            ->capture_default_str();
        gap->add_option("--substeps", options->diagnose.substeps_per_frame, "the diagnoser's steps per frame (implicit integrators)")
            ->check(CLI::Range(1, 1000))
            ->capture_default_str();
        gap->add_option("--diagnose", options->diagnose_dir, "diagnose every case of a bench folder, then score");
        gap->add_option("--score", options->score_dir, "score a diagnosed bench folder");
        gap->add_flag("--oracle", options->oracle,
                      "with --score: also simulate each strong case's true effect in the diagnoser's model (the share of "
                      "the gap any diagnosis could close; the rest is discretisation)");
        gap->add_option("--threads", options->threads, "threads (0 = all cores)")->capture_default_str();
        return [options](const GlobalOptions& global) {
            options->diagnose.run.threads = options->threads;
            if (const std::optional<int> count = resolve_frame_count(options->frame_selection, 1, "cases start at frame 1"))
                options->bench.frames = *count;
            if (options->bench.frames < 4 || options->bench.frames > 1000)
                throw UsageError("", "", "a case has 4 to 1000 frames", "give --frame-count 4 to 1000");
            options->diagnose.frames = options->bench.frames;
            options->bench.integrator = cloth::integrators_by_short_name().at(options->footage_integrator);
            const std::optional<std::pair<int, int>> footage = parse_grid(options->footage_resolution, "--footage-resolution");
            if (!footage) return static_cast<int>(kExitUsage);
            options->bench.rows = footage->first;
            options->bench.cols = footage->second;
            return run_bench_gap(*options, global);
        };
    }}};

}  // namespace flowvid::cli
