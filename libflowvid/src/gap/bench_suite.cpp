// The gap benchmark as a whole (gap/bench.hpp, second part): making the
// sealed cases with their labels, opening a case as the diagnoser sees it,
// and scoring the diagnoses against the labels.

#include "flowvid/gap/bench.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/gap/rigid_model.hpp"
#include "flowvid/threads.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace flowvid::gap {

namespace fs = std::filesystem;

namespace {

std::map<std::string, double> label_values(const EffectValues& values) {
    std::map<std::string, double> out;
    for (const auto& [name, v] : values) {
        const Effect& effect = find_effect(name);
        for (std::size_t i = 0; i < effect.parameters.size(); ++i) out[effect.parameters[i].key] = v(static_cast<Eigen::Index>(i));
    }
    return out;
}

EffectValues values_from_label(const std::string& name, const std::map<std::string, double>& values) {
    const Effect& effect = find_effect(name);
    Eigen::VectorXd v = neutral_values(effect);
    for (std::size_t i = 0; i < effect.parameters.size(); ++i)
        if (values.count(effect.parameters[i].key)) v(static_cast<Eigen::Index>(i)) = values.at(effect.parameters[i].key);
    return {{name, v}};
}

// The mean error/floor of the effect-free rigid model fitted to a rigid case.
double rigid_effect_to_noise(const std::string& folder, int threads) {
    RigidGapRequest request;
    request.capture_paths = {folder};
    request.threads = threads;
    const Residuals r = open_rigid_model(request).model->evaluate({});
    double sum = 0.0;
    for (const FrameResidual& f : r.frames) sum += f.error / f.floor;
    return r.frames.empty() ? 0.0 : sum / static_cast<double>(r.frames.size());
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

// The labels' effects and values against the catalogue (the format's reader
// checks their form only): every problem, named by file and field.
void check_labels_against_catalogue(const std::string& path, const formats::GapBenchLabels& labels) {
    std::vector<Problem> problems;
    const auto problem = [&](std::string field, std::string message, std::string fix) {
        problems.push_back(Problem{Problem::Severity::error, path, std::move(field), std::move(message), std::move(fix)});
    };
    std::string known = "\"none\"";
    for (const Effect& effect : effect_catalogue()) known += ", " + effect.name;
    for (std::size_t i = 0; i < labels.cases.size(); ++i) {
        const formats::GapBenchLabel& label = labels.cases[i];
        const std::string at = "/cases/" + std::to_string(i);
        if (label.effect == "none") continue;  // the reader has checked that it has no values
        const auto effect = std::find_if(effect_catalogue().begin(), effect_catalogue().end(),
                                         [&](const Effect& e) { return e.name == label.effect; });
        if (effect == effect_catalogue().end()) {
            problem(at + "/effect", "\"" + label.effect + "\" is not an effect of the catalogue", "use one of " + known);
            continue;
        }
        std::string keys;
        for (const EffectParameter& p : effect->parameters) keys += (keys.empty() ? "" : ", ") + p.key;
        for (const auto& [key, value] : label.values) {
            const bool known_key = std::any_of(effect->parameters.begin(), effect->parameters.end(),
                                               [&](const EffectParameter& p) { return p.key == key; });
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
                         const BenchScoreRequest& request) {
    const OpenedGapModel opened = open_bench_case(folder, request.cloth, request.threads);
    return held_out_gap_closed(opened.model->evaluate({}), opened.model->evaluate(values_from_label(effect, values)));
}

}  // namespace

formats::GapBenchLabels make_bench_cases(const BenchMakeRequest& request, const Progress& progress) {
    if (request.scene_paths.empty() || request.fabric_paths.empty())
        throw UsageError("", "", "no scenes or no fabrics to make cases from",
                         "give --scene (cloth.waving capture folders: camera, projector, pins) and --fabric presets");
    std::vector<formats::Capture> scenes;
    for (const std::string& s : request.scene_paths) scenes.push_back(formats::read_capture(s));
    std::vector<formats::FabricPreset> fabrics;
    for (const std::string& f : request.fabric_paths) fabrics.push_back(formats::read_fabric_preset(f));
    const BenchSettings& settings = request.settings;
    for (const std::string& e : settings.effects) find_effect(e);
    std::vector<formats::Capture> rigid_scenes;
    for (const std::string& s : request.rigid_scene_paths)
        rigid_scenes.push_back(formats::read_capture_of_kind(s, {"rigid.toss"}, "flowvid bench gap"));
    std::vector<BenchCase> cases =
        draw_bench_cases(request.cases, request.seed, static_cast<int>(scenes.size()), static_cast<int>(fabrics.size()),
                         settings, static_cast<int>(rigid_scenes.size()));
    fs::create_directories(fs::path(request.out_dir) / "cases");
    const int threads = resolve_thread_count(request.threads);
    formats::GapBenchLabels labels;
    for (std::size_t i = 0; i < cases.size(); ++i) {
        BenchCase& c = cases[i];
        if (progress && !progress({"making cases", static_cast<double>(i) / cases.size(), c.id + " (" + c.effect + ")"}))
            throw Cancelled();
        const std::string folder = (fs::path(request.out_dir) / "cases" / c.id).string();
        formats::GapBenchLabel label;
        label.id = c.id;
        label.effect = c.effect;
        if (c.rigid) {
            RigidCaseSettings rigid;
            rigid.threads = threads;
            write_rigid_case(folder, rigid_scenes[static_cast<std::size_t>(c.scene)], c.values,
                             request.seed * 1000003ULL + i, rigid);
            c.effect_to_noise = rigid_effect_to_noise(folder, threads);
            label.kind = "rigid";
            label.values = label_values(c.values);
            label.scene = request.rigid_scene_paths[static_cast<std::size_t>(c.scene)];
            label.effect_to_noise = c.effect_to_noise;
            labels.cases.push_back(std::move(label));
            continue;
        }
        const cloth::ClothMaterial fabric = cloth::material_from_fabric(fabrics[static_cast<std::size_t>(c.fabric)].parameters);
        // Too strong an effect can leave no footage to make (no equilibrium,
        // a blow-up): halve it, at most three times, and say so in the labels.
        int weakened_times = 0;
        for (;; ++weakened_times) {
            try {
                write_cloth_case(folder, c, scenes[static_cast<std::size_t>(c.scene)], fabric, settings, threads);
                break;
            } catch (const std::runtime_error& e) {
                if (c.effect == "none" || c.effect == "drag_nonlinear" || weakened_times == 3) throw;
                report_message(progress, "making cases", std::string(e.what()) + ": halving the effect");
                c.values = weakened(c.values);
            }
        }
        // A drag_nonlinear case's hidden values are the fabric's own nonlinear drag.
        if (c.effect == "drag_nonlinear")
            c.values["drag_nonlinear"] =
                (Eigen::VectorXd(2) << fabric.drag_normal_kg_per_m3, fabric.drag_degradation_s2_per_m2).finished();
        formats::FabricPreset base = fabrics[static_cast<std::size_t>(c.fabric)];
        base.parameters = cloth::fabric_from_material(bench_base_material(c, fabric));
        base.adapters.clear();
        formats::write_fabric_preset(folder + "/base.fabric.json", base);
        c.effect_to_noise = measure_effect_to_noise(folder, c, fabric, settings, threads);
        label.kind = "cloth";
        label.values = label_values(c.values);
        label.scene = request.scene_paths[static_cast<std::size_t>(c.scene)];
        label.fabric = request.fabric_paths[static_cast<std::size_t>(c.fabric)];
        label.effect_to_noise = c.effect_to_noise;
        label.weakened = weakened_times;
        labels.cases.push_back(std::move(label));
    }
    report_progress(progress, "making cases", 1.0);
    labels.seed = request.seed;
    labels.footage_mesh = std::to_string(settings.rows) + "x" + std::to_string(settings.cols);
    labels.footage_integrator = request.footage_integrator_name;
    labels.footage_substeps_per_frame = settings.implicit_substeps;
    labels.frames = settings.frames;
    labels.strength = settings.strength;
    formats::write_gap_bench_labels((fs::path(request.out_dir) / "labels.json").string(), labels);
    return labels;
}

std::vector<std::string> bench_case_folders(const std::string& dir) {
    std::vector<std::string> out;
    const fs::path cases = fs::path(dir) / "cases";
    if (!fs::is_directory(cases)) return out;
    for (const fs::directory_entry& e : fs::directory_iterator(cases))
        if (e.is_directory() && fs::exists(e.path() / "capture.json")) out.push_back(e.path().string());
    std::sort(out.begin(), out.end());
    return out;
}

OpenedGapModel open_bench_case(const std::string& case_folder, const ClothGapRequest& cloth, int threads) {
    ClothGapRequest request = cloth;
    request.threads = threads;
    return open_gap_model({case_folder}, case_folder + "/base.fabric.json", "", request);
}

const std::vector<std::string>& effect_to_noise_bins() {
    static const std::vector<std::string> bins = {"<1", "1-2", "2-4", "4-8", ">=8"};
    return bins;
}

BenchScore score_bench(const BenchScoreRequest& request) {
    const std::string& dir = request.dir;
    BenchScore score;
    const std::string labels_path = (fs::path(dir) / "labels.json").string();
    const formats::GapBenchLabels labels = formats::read_gap_bench_labels(labels_path, &score.warnings);
    check_labels_against_catalogue(labels_path, labels);
    std::map<std::string, formats::Diagnosis> diagnoses;
    std::vector<Problem> problems;
    for (const formats::GapBenchLabel& label : labels.cases) {
        const fs::path result = fs::path(dir) / "results" / label.id / "diagnosis.json";
        if (!fs::exists(result)) continue;
        try {
            diagnoses.emplace(label.id, formats::read_diagnosis(result.string(), &score.warnings));
        } catch (const ValidationError& error) {
            problems.insert(problems.end(), error.problems().begin(), error.problems().end());
        }
    }
    if (!problems.empty()) throw ValidationError(std::move(problems));
    std::vector<double> closed_named, closed_strong, oracle_strong;
    for (const formats::GapBenchLabel& label : labels.cases) {
        const std::string& id = label.id;
        // The oracle needs no diagnosis: the ceiling of a diagnoser setting
        // can be measured before (or instead of) running it.
        if (request.oracle && label.effect != "none" && label.effect_to_noise >= 4.0) {
            const double oracle = oracle_gap_closed((fs::path(dir) / "cases" / id).string(), label.effect, label.values, request);
            if (std::isfinite(oracle)) oracle_strong.push_back(oracle);
            score.oracle_by_case[id] = oracle;
        }
        const auto found = diagnoses.find(id);
        if (found == diagnoses.end()) {
            ++score.missing;
            continue;
        }
        const formats::Diagnosis& d = found->second;
        const std::string& effect = label.effect;
        const std::vector<std::string>& named = d.verdict.effects;
        if (effect == "none") {
            ++score.false_alarms.cases;
            score.false_alarms.correct += d.verdict.status == "named" ? 1 : 0;
            score.gap_detected_on_none += d.gap.detected ? 1 : 0;
            continue;
        }
        // Top-1: the first named effect, or the class it belongs to.
        const bool correct =
            !named.empty() && (named.front() == effect || d.verdict.effect_class.find(effect) != std::string::npos);
        const double ratio = label.effect_to_noise;
        BenchTally& by_effect = score.per_effect[effect];
        BenchTally& by_bin = score.per_bin[bin_of(ratio)];
        for (BenchTally* t : {&by_effect, &by_bin}) {
            t->cases++;
            t->correct += correct ? 1 : 0;
        }
        const double gap_closed = correct && d.verdict.gap_closed ? *d.verdict.gap_closed : 0.0;
        if (correct) closed_named.push_back(gap_closed);
        if (ratio >= 4.0) {
            score.strong.cases++;
            score.strong.correct += correct ? 1 : 0;
            closed_strong.push_back(gap_closed);
        }
    }
    score.cases_scored = static_cast<int>(labels.cases.size()) - score.missing;
    score.median_gap_closed_strong = median(closed_strong);
    score.median_gap_closed_named = median(closed_named);
    score.median_oracle_gap_closed_strong = median(oracle_strong);
    const nlohmann::json document = bench_score_json(score, request.oracle);
    formats::write_file_atomically((fs::path(dir) / "score.json").string(),
                                   [&](std::ostream& o) { o << document.dump(2) << '\n'; });
    return score;
}

nlohmann::json bench_score_json(const BenchScore& score, bool oracle) {
    const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
    nlohmann::json out = {{"cases_scored", score.cases_scored}, {"missing", score.missing}};
    for (const auto& [effect, t] : score.per_effect) out["per_effect"][effect] = {{"correct", t.correct}, {"cases", t.cases}};
    for (const std::string& bin : effect_to_noise_bins()) {
        const auto found = score.per_bin.find(bin);
        const BenchTally t = found == score.per_bin.end() ? BenchTally{} : found->second;
        out["per_bin"][bin] = {{"correct", t.correct}, {"cases", t.cases}};
    }
    if (oracle) {
        nlohmann::json by_case = nlohmann::json::object();
        for (const auto& [id, value] : score.oracle_by_case) by_case[id] = number(value);
        out["oracle_gap_closed_strong"] = by_case;
        out["median_oracle_gap_closed_strong"] = number(score.median_oracle_gap_closed_strong);
    }
    out["strong"] = {{"correct", score.strong.correct}, {"cases", score.strong.cases}};
    out["false_alarms"] = {{"named", score.false_alarms.correct},
                           {"cases", score.false_alarms.cases},
                           {"gap_detected", score.gap_detected_on_none}};
    out["median_gap_closed_strong"] = number(score.median_gap_closed_strong);
    out["median_gap_closed_named"] = number(score.median_gap_closed_named);
    return out;
}

}  // namespace flowvid::gap
