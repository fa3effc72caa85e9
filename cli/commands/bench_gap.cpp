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
#include "commands/fit.hpp"
#include "output.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/gap_bench_labels.hpp"
#include "flowvid/gap/bench.hpp"
#include "flowvid/gap/rigid_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

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
    std::string diagnose_dir;
    std::string score_dir;
    DiagnoseClothOptions diagnose;
    gap::BenchSettings bench;
    std::string footage_integrator = "implicit";
    std::string footage_resolution = "24x24";
    bool oracle = false;  // score: also the gap the true effect closes in the diagnoser's model
    int threads = 0;
};

std::map<std::string, double> label_values(const gap::EffectValues& values) {
    std::map<std::string, double> out;
    for (const auto& [name, v] : values) {
        const gap::Effect& effect = gap::find_effect(name);
        for (std::size_t i = 0; i < effect.parameters.size(); ++i) out[effect.parameters[i].key] = v(static_cast<Eigen::Index>(i));
    }
    return out;
}

int generate(const BenchGapOptions& options, const GlobalOptions& global) {
    if (options.scenes.empty() || options.fabrics.empty()) {
        log_message("flowvid bench gap: give --scene (cloth.waving capture folders: camera, projector, pins) and --fabric presets");
        return kExitUsage;
    }
    std::vector<formats::Capture> scenes;
    for (const std::string& s : options.scenes) scenes.push_back(formats::read_capture(s));
    std::vector<formats::FabricPreset> fabrics;
    for (const std::string& f : options.fabrics) fabrics.push_back(formats::read_fabric_preset(f));
    gap::BenchSettings settings = options.bench;
    settings.effects = options.effects;
    for (const std::string& e : settings.effects) gap::find_effect(e);
    std::vector<formats::Capture> rigid_scenes;
    for (const std::string& s : options.rigid_scenes) rigid_scenes.push_back(read_capture_of_kind(s, {"rigid.toss"}, "flowvid bench gap"));
    std::vector<gap::BenchCase> cases =
        gap::draw_bench_cases(options.cases, options.seed, static_cast<int>(scenes.size()), static_cast<int>(fabrics.size()),
                              settings, static_cast<int>(rigid_scenes.size()));
    fs::create_directories(fs::path(options.out) / "cases");
    Progress progress(global, "bench gap: making cases");
    const InterruptWatch interrupt;
    const int threads = thread_count(options.threads);
    formats::GapBenchLabels labels;
    for (std::size_t i = 0; i < cases.size(); ++i) {
        if (interrupt.requested()) return kExitInterrupted;
        gap::BenchCase& c = cases[i];
        progress.update(static_cast<double>(i) / cases.size(), c.id + " (" + c.effect + ")");
        const std::string folder = (fs::path(options.out) / "cases" / c.id).string();
        if (c.rigid) {
            gap::RigidCaseSettings rigid;
            rigid.threads = threads;
            gap::write_rigid_case(folder, rigid_scenes[static_cast<std::size_t>(c.scene)], c.values,
                                  options.seed * 1000003ULL + i, rigid);
            // Effect size: the mean error/floor of the effect-free model fitted to the case.
            nlohmann::json ignored;
            const std::unique_ptr<gap::GapModel> model = rigid_gap_model({folder}, "", threads, ignored);
            const gap::Residuals r = model->evaluate({});
            double sum = 0.0;
            for (const gap::FrameResidual& f : r.frames) sum += f.error / f.floor;
            c.effect_to_noise = r.frames.empty() ? 0.0 : sum / static_cast<double>(r.frames.size());
            formats::GapBenchLabel label;
            label.id = c.id;
            label.kind = "rigid";
            label.effect = c.effect;
            label.values = label_values(c.values);
            label.scene = options.rigid_scenes[static_cast<std::size_t>(c.scene)];
            label.effect_to_noise = c.effect_to_noise;
            labels.cases.push_back(std::move(label));
            continue;
        }
        const cloth::ClothMaterial fabric = cloth::material_from_fabric(fabrics[static_cast<std::size_t>(c.fabric)].parameters);
        // Too strong an effect can leave no footage to make (no equilibrium,
        // a blow-up): halve it, at most three times, and say so in the labels.
        int weakened = 0;
        for (;; ++weakened) {
            try {
                gap::write_cloth_case(folder, c, scenes[static_cast<std::size_t>(c.scene)], fabric, settings, threads);
                break;
            } catch (const std::runtime_error& e) {
                if (c.effect == "none" || c.effect == "drag_nonlinear" || weakened == 3) throw;
                log_message(std::string(e.what()) + ": halving the effect");
                c.values = gap::weakened(c.values);
            }
        }
        // A drag_nonlinear case's hidden values are the fabric's own nonlinear drag.
        if (c.effect == "drag_nonlinear")
            c.values["drag_nonlinear"] =
                (Eigen::VectorXd(2) << fabric.drag_normal_kg_per_m3, fabric.drag_degradation_s2_per_m2).finished();
        formats::FabricPreset base = fabrics[static_cast<std::size_t>(c.fabric)];
        base.parameters = cloth::fabric_from_material(gap::bench_base_material(c, fabric));
        base.adapters.clear();
        formats::write_fabric_preset(folder + "/base.fabric.json", base);
        c.effect_to_noise = gap::measure_effect_to_noise(folder, c, fabric, settings, threads);
        formats::GapBenchLabel label;
        label.id = c.id;
        label.kind = "cloth";
        label.effect = c.effect;
        label.values = label_values(c.values);
        label.scene = options.scenes[static_cast<std::size_t>(c.scene)];
        label.fabric = options.fabrics[static_cast<std::size_t>(c.fabric)];
        label.effect_to_noise = c.effect_to_noise;
        label.weakened = weakened;
        labels.cases.push_back(std::move(label));
    }
    progress.done();
    labels.seed = options.seed;
    labels.footage_mesh = std::to_string(settings.rows) + "x" + std::to_string(settings.cols);
    labels.footage_integrator = options.footage_integrator;
    labels.footage_substeps_per_frame = settings.implicit_substeps;
    labels.frames = settings.frames;
    labels.strength = settings.strength;
    formats::write_gap_bench_labels((fs::path(options.out) / "labels.json").string(), labels);
    std::cout << "wrote " << cases.size() << " cases to " << (fs::path(options.out) / "cases").string()
              << " and their labels to " << (fs::path(options.out) / "labels.json").string() << '\n';
    return kExitOk;
}

std::vector<std::string> case_folders(const std::string& dir) {
    std::vector<std::string> out;
    const fs::path cases = fs::path(dir) / "cases";
    if (!fs::is_directory(cases)) return out;
    for (const fs::directory_entry& e : fs::directory_iterator(cases))
        if (e.is_directory() && fs::exists(e.path() / "capture.json")) out.push_back(e.path().string());
    std::sort(out.begin(), out.end());
    return out;
}

int diagnose_all(const BenchGapOptions& options, const GlobalOptions& global) {
    const std::vector<std::string> folders = case_folders(options.diagnose_dir);
    if (folders.empty()) {
        log_message(options.diagnose_dir + ": no cases/*/capture.json (make them with flowvid bench gap --out)");
        return kExitIoError;
    }
    Progress progress(global, "bench gap: diagnosing");
    const InterruptWatch interrupt;
    for (std::size_t i = 0; i < folders.size(); ++i) {
        const std::string id = fs::path(folders[i]).filename().string();
        const std::string out = (fs::path(options.diagnose_dir) / "results" / id).string();
        if (fs::exists(fs::path(out) / "diagnosis.json")) continue;  // resumable
        if (interrupt.requested()) return kExitInterrupted;
        progress.update(static_cast<double>(i) / folders.size(), id);
        nlohmann::json model_summary;
        const bool rigid = formats::read_capture(folders[i]).is_rigid();
        const std::unique_ptr<gap::GapModel> model =
            rigid ? rigid_gap_model({folders[i]}, "", thread_count(options.threads), model_summary)
                  : cloth_gap_model({folders[i]}, folders[i] + "/base.fabric.json", options.diagnose, model_summary);
        if (!model) return kExitUsage;
        gap::DiagnoseSettings settings;
        settings.progress = [&](const std::string&, double) { return !interrupt.requested(); };
        try {
            const gap::Diagnosis d = gap::diagnose(*model, settings);
            write_diagnosis(out, diagnosis_to_json(d, model_summary));
        } catch (const gap::Cancelled&) {
            return kExitInterrupted;
        }
    }
    progress.done();
    return kExitOk;
}

const char* bin_of(double ratio) {
    if (ratio < 1.0) return "<1";
    if (ratio < 2.0) return "1-2";
    if (ratio < 4.0) return "2-4";
    if (ratio < 8.0) return "4-8";
    return ">=8";
}

double median(std::vector<double> v) {
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

gap::EffectValues values_from_label(const std::string& name, const std::map<std::string, double>& values) {
    const gap::Effect& effect = gap::find_effect(name);
    Eigen::VectorXd v = gap::neutral_values(effect);
    for (std::size_t i = 0; i < effect.parameters.size(); ++i)
        if (values.count(effect.parameters[i].key)) v(static_cast<Eigen::Index>(i)) = values.at(effect.parameters[i].key);
    return {{name, v}};
}

// The labels' effects and values against the catalogue (the format's reader
// checks their form only): every problem, named by file and field.
void check_labels_against_catalogue(const std::string& path, const formats::GapBenchLabels& labels) {
    std::vector<Problem> problems;
    const auto problem = [&](std::string field, std::string message, std::string fix) {
        problems.push_back(Problem{Problem::Severity::error, path, std::move(field), std::move(message), std::move(fix)});
    };
    std::string known = "\"none\"";
    for (const gap::Effect& effect : gap::effect_catalogue()) known += ", " + effect.name;
    for (std::size_t i = 0; i < labels.cases.size(); ++i) {
        const formats::GapBenchLabel& label = labels.cases[i];
        const std::string at = "/cases/" + std::to_string(i);
        if (label.effect == "none") continue;  // the reader has checked that it has no values
        const auto effect = std::find_if(gap::effect_catalogue().begin(), gap::effect_catalogue().end(),
                                         [&](const gap::Effect& e) { return e.name == label.effect; });
        if (effect == gap::effect_catalogue().end()) {
            problem(at + "/effect", "\"" + label.effect + "\" is not an effect of the catalogue", "use one of " + known);
            continue;
        }
        std::string keys;
        for (const gap::EffectParameter& p : effect->parameters) keys += (keys.empty() ? "" : ", ") + p.key;
        for (const auto& [key, value] : label.values) {
            const bool known_key = std::any_of(effect->parameters.begin(), effect->parameters.end(),
                                               [&](const gap::EffectParameter& p) { return p.key == key; });
            if (!known_key)
                problem(formats::json_pointer_child(at + "/values", key), "not a parameter of " + label.effect,
                        "use the effect's parameters (" + keys + ")");
        }
    }
    if (!problems.empty()) throw ValidationError(std::move(problems));
}

// The share of the held-out gap the hidden effect itself, at its true values,
// closes in the diagnoser's model: the most any diagnosis could close, the
// rest being the model's own discretisation against the footage's.
double oracle_gap_closed(const std::string& folder, const std::string& effect, const std::map<std::string, double>& values,
                         const BenchGapOptions& options) {
    nlohmann::json ignored;
    const bool rigid = formats::read_capture(folder).is_rigid();
    const std::unique_ptr<gap::GapModel> model =
        rigid ? rigid_gap_model({folder}, "", thread_count(options.threads), ignored)
              : cloth_gap_model({folder}, folder + "/base.fabric.json", options.diagnose, ignored);
    if (!model) return std::nan("");
    return gap::held_out_gap_closed(model->evaluate({}), model->evaluate(values_from_label(effect, values)));
}

// Reads labels.json and every diagnosis.json there is, validated (each
// problem named by file and field: an invalid file stops the score before
// any work, exit 3); cases without a diagnosis count as missing.
int score(const std::string& dir, const BenchGapOptions& options) {
    const std::string labels_path = (fs::path(dir) / "labels.json").string();
    std::vector<Problem> warnings;
    const formats::GapBenchLabels labels = formats::read_gap_bench_labels(labels_path, &warnings);
    print_problems(warnings);
    check_labels_against_catalogue(labels_path, labels);
    std::map<std::string, formats::Diagnosis> diagnoses;
    std::vector<Problem> problems;
    for (const formats::GapBenchLabel& label : labels.cases) {
        const fs::path result = fs::path(dir) / "results" / label.id / "diagnosis.json";
        if (!fs::exists(result)) continue;
        try {
            diagnoses.emplace(label.id, formats::read_diagnosis(result.string(), &warnings));
            print_problems(warnings);
        } catch (const ValidationError& error) {
            problems.insert(problems.end(), error.problems().begin(), error.problems().end());
        }
    }
    if (!problems.empty()) throw ValidationError(std::move(problems));
    struct Tally {
        int cases = 0, correct = 0;
    };
    std::map<std::string, Tally> by_effect, by_bin;
    Tally strong, none, any_gap_on_none;
    std::vector<double> closed_named, closed_strong, oracle_strong;
    nlohmann::json oracle_by_case = nlohmann::json::object();
    int missing = 0;
    for (const formats::GapBenchLabel& label : labels.cases) {
        const std::string& id = label.id;
        // The oracle needs no diagnosis: the ceiling of a diagnoser setting
        // can be measured before (or instead of) running it.
        if (options.oracle && label.effect != "none" && label.effect_to_noise >= 4.0) {
            const double oracle = oracle_gap_closed((fs::path(dir) / "cases" / id).string(), label.effect, label.values, options);
            if (std::isfinite(oracle)) oracle_strong.push_back(oracle);
            oracle_by_case[id] = std::isfinite(oracle) ? nlohmann::json(oracle) : nlohmann::json();
        }
        const auto found = diagnoses.find(id);
        if (found == diagnoses.end()) {
            ++missing;
            continue;
        }
        const formats::Diagnosis& d = found->second;
        const std::string& effect = label.effect;
        const std::string& status = d.verdict.status;
        const std::vector<std::string>& named = d.verdict.effects;
        const std::string& named_class = d.verdict.effect_class;
        if (effect == "none") {
            ++none.cases;
            none.correct += status == "named" ? 1 : 0;  // a false alarm
            any_gap_on_none.cases++;
            any_gap_on_none.correct += d.gap.detected ? 1 : 0;
            continue;
        }
        // Top-1: the first named effect, or the class it belongs to.
        const bool correct = !named.empty() && (named.front() == effect || named_class.find(effect) != std::string::npos);
        const double ratio = label.effect_to_noise;
        by_effect[effect].cases++;
        by_effect[effect].correct += correct ? 1 : 0;
        by_bin[bin_of(ratio)].cases++;
        by_bin[bin_of(ratio)].correct += correct ? 1 : 0;
        const double gap_closed = correct && d.verdict.gap_closed ? *d.verdict.gap_closed : 0.0;
        if (correct) closed_named.push_back(gap_closed);
        if (ratio >= 4.0) {
            strong.cases++;
            strong.correct += correct ? 1 : 0;
            closed_strong.push_back(gap_closed);
        }
    }
    const auto percent = [](const Tally& t) { return t.cases ? 100.0 * t.correct / t.cases : std::nan(""); };
    nlohmann::json out = {{"cases_scored", static_cast<int>(labels.cases.size()) - missing}, {"missing", missing}};
    std::printf("top-1 accuracy per effect\n");
    for (const auto& [effect, t] : by_effect) {
        std::printf("  %-16s %3d / %-3d  %5.1f %%\n", effect.c_str(), t.correct, t.cases, percent(t));
        out["per_effect"][effect] = {{"correct", t.correct}, {"cases", t.cases}};
    }
    std::printf("top-1 accuracy per effect-to-noise bin\n");
    for (const char* bin : {"<1", "1-2", "2-4", "4-8", ">=8"}) {
        const Tally t = by_bin.count(bin) ? by_bin[bin] : Tally{};
        std::printf("  %-6s %3d / %-3d  %5.1f %%\n", bin, t.correct, t.cases, percent(t));
        out["per_bin"][bin] = {{"correct", t.correct}, {"cases", t.cases}};
    }
    std::printf("effect >= 4x noise: top-1 %d / %d = %.1f %% (goal >= 90 %%)\n", strong.correct, strong.cases, percent(strong));
    std::printf("false alarms (an effect named on an effect-free case): %d / %d = %.1f %% (goal <= 5 %%)\n", none.correct,
                none.cases, percent(none));
    std::printf("gap detected on effect-free cases: %d / %d\n", any_gap_on_none.correct, any_gap_on_none.cases);
    std::printf("median held-out gap closed: %.2f over effects >= 4x noise (0 when not named; goal >= 0.80), %.2f over "
                "correctly named cases\n",
                median(closed_strong), median(closed_named));
    if (options.oracle) {
        std::printf("median held-out gap the true effect closes in the diagnoser's model (the most a diagnosis can close): "
                    "%.2f over effects >= 4x noise\n",
                    median(oracle_strong));
        out["oracle_gap_closed_strong"] = oracle_by_case;
        out["median_oracle_gap_closed_strong"] = std::isfinite(median(oracle_strong)) ? nlohmann::json(median(oracle_strong)) : nlohmann::json();
    }
    out["strong"] = {{"correct", strong.correct}, {"cases", strong.cases}};
    out["false_alarms"] = {{"named", none.correct}, {"cases", none.cases}, {"gap_detected", any_gap_on_none.correct}};
    out["median_gap_closed_strong"] = std::isfinite(median(closed_strong)) ? nlohmann::json(median(closed_strong)) : nlohmann::json();
    out["median_gap_closed_named"] = std::isfinite(median(closed_named)) ? nlohmann::json(median(closed_named)) : nlohmann::json();
    formats::write_file_atomically((fs::path(dir) / "score.json").string(), [&](std::ostream& o) { o << out.dump(2) << '\n'; });
    return kExitOk;
}

int run_bench_gap(const BenchGapOptions& options, const GlobalOptions& global) {
    const int modes = (!options.out.empty()) + (!options.diagnose_dir.empty()) + (!options.score_dir.empty());
    if (modes != 1) {
        log_message("flowvid bench gap: give exactly one of --out DIR (make cases), --diagnose DIR, --score DIR");
        return kExitUsage;
    }
    if (!options.out.empty()) return generate(options, global);
    if (!options.diagnose_dir.empty()) {
        const int status = diagnose_all(options, global);
        if (status != kExitOk) return status;
        return score(options.diagnose_dir, options);
    }
    return score(options.score_dir, options);
}

}  // namespace

// `flowvid bench <what>`: benchmarks that are commands (the speed benchmarks are bench/ executables).
const RegisterCommand bench_registration{Command{
    "bench", "benchmarks with sealed cases: `flowvid bench gap ...`", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<BenchGapOptions>();
        options->diagnose.run.resolution = kDiagnoserResolution;
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
        gap->add_option("--frames", options->bench.frames, "frames per case")->check(CLI::Range(4, 1000))->capture_default_str();
        std::vector<std::string> integrator_names;
        for (const auto& [name, value] : integrators()) integrator_names.push_back(name);
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
            options->diagnose.frames = options->bench.frames;
            options->bench.integrator = integrators().at(options->footage_integrator);
            const std::optional<std::pair<int, int>> footage = parse_grid(options->footage_resolution, "--footage-resolution");
            if (!footage) return static_cast<int>(kExitUsage);
            options->bench.rows = footage->first;
            options->bench.cols = footage->second;
            return run_bench_gap(*options, global);
        };
    }}};

}  // namespace flowvid::cli
