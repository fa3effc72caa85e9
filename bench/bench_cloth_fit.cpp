// The cloth-fitting study of issue 4 on footage from another simulator
// (../shared/captures/cloth-{cotton,silk}-*, made by Blender's cloth solver):
//
//  1. per fabric, fit static-1 + waving-1 jointly (nonlinear drag, 9
//     parameters) and the linear-drag comparison model (8), then predict the
//     held-out waving-2: RMS vertex error against truth/positions.exr per
//     time window, next to the starting guess and the predictability floor;
//  2. recognition: both fitted presets on every held-out capture;
//  3. speed: a 9-parameter fit of two 50-frame waving trials at 24x24.
//
// Fits never read truth/ (the assessment does, for evaluation only).
// Environment: FLOWVID_FIT_EVALUATIONS (default 300), FLOWVID_FIT_BUDGET_S
// (wall cap per fit, default 600), FLOWVID_FIT_OUT (presets and JSON, default
// ./cloth_fit_study), FLOWVID_FIT_SKIP_SPEED=1 skips part 3,
// FLOWVID_FIT_HALF_LIFE (frames; default 0 = every frame weighs the same, 10
// = the predictability-aware weighting `flowvid fit cloth` uses by default),
// FLOWVID_FIT_NONLINEAR_ONLY=1 skips the linear-drag fits and recognition
// (to compare weightings).

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/cloth_fit/cloth_eval.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>

namespace cf = flowvid::cloth_fit;
namespace fs = std::filesystem;

namespace {

std::string capture_path(const std::string& name) { return std::string(FLOWVID_SHARED_DIR) + "/captures/" + name; }

double env_number(const char* name, double fallback) {
    const char* text = std::getenv(name);
    return text ? std::atof(text) : fallback;
}

cf::ClothFitRequest request_for(const std::string& name, const std::vector<std::string>& captures, cf::DragModel drag) {
    cf::ClothFitRequest request;
    request.name = name;
    for (const std::string& c : captures) request.captures.push_back(flowvid::formats::read_capture(capture_path(c)));
    request.drag = drag;
    request.load.half_life_frames = env_number("FLOWVID_FIT_HALF_LIFE", 0.0);
    request.evaluations = static_cast<long long>(env_number("FLOWVID_FIT_EVALUATIONS", 300));
    request.variability_runs = 2;
    request.variability_evaluations = 24;
    request.budget_seconds = env_number("FLOWVID_FIT_BUDGET_S", 600);
    request.problem.swatch.simulation.integrator = flowvid::cloth::Integrator::implicit_euler;
    request.seed = 1;
    request.threads = 2;
    auto last_print = std::make_shared<long long>(-1000);
    auto last_stage = std::make_shared<std::string>();
    request.progress = [last_print, last_stage, name](const flowvid::ProgressReport& p) {
        // A line every 5 % of the fit, and at every change of stage.
        const long long percent = static_cast<long long>(100 * p.fraction);
        if (percent - *last_print >= 5 || p.stage != *last_stage) {
            std::fprintf(stderr, "  [%s] %s %lld%%, %s\n", name.c_str(), p.stage.c_str(), percent, p.message.c_str());
            *last_print = percent;
            *last_stage = p.stage;
        }
        return true;
    };
    return request;
}

struct Assessed {
    std::vector<cf::WindowSummary> windows;
    double all_frames_mm = 0.0;
    double weighted_error = 0.0;
};

Assessed assess(const std::string& capture_name, const flowvid::cloth::ClothMaterial& material, bool floor) {
    const flowvid::formats::Capture capture = flowvid::formats::read_capture(capture_path(capture_name));
    const cf::ClothTrial trial = cf::load_trial(capture, {});
    cf::ClothFitSettings settings;
    settings.swatch.simulation.integrator = flowvid::cloth::Integrator::implicit_euler;
    cf::FloorSettings floor_settings;
    const cf::TrialAssessment a = cf::assess_trial(trial, material, settings, flowvid::formats::read_capture_truth_positions(capture),
                                                   floor ? &floor_settings : nullptr, 2);
    Assessed out;
    out.windows = cf::summarize_windows(a, cf::standard_windows(static_cast<int>(trial.frames.size())));
    out.all_frames_mm = 1e3 * cf::pooled_rms(a.vertex_rms_m, {1, static_cast<int>(a.vertex_rms_m.size())});
    out.weighted_error = a.weighted_error;
    return out;
}

void print_row(const char* label, const Assessed& a, bool floor) {
    std::printf("| %-28s |", label);
    for (const auto& w : a.windows) std::printf(" %5.1f |", 1e3 * w.vertex_rms_m);
    std::printf(" %5.1f |", a.all_frames_mm);
    if (floor) {
        for (const auto& w : a.windows) std::printf(" %4.1f", 1e3 * w.vertex_floor_m);
        std::printf(" |");
    }
    std::printf("\n");
}

}  // namespace

int main() {
    const fs::path out = std::getenv("FLOWVID_FIT_OUT") ? std::getenv("FLOWVID_FIT_OUT") : "cloth_fit_study";
    fs::create_directories(out);
    nlohmann::json record;
    std::map<std::string, flowvid::cloth::ClothMaterial> fitted;
    for (const std::string fabric : {"cotton", "silk"}) {
        const std::vector<std::string> training = {"cloth-" + fabric + "-static-1", "cloth-" + fabric + "-waving-1"};
        const std::string held_out = "cloth-" + fabric + "-waving-2";
        std::fprintf(stderr, "fitting %s (nonlinear drag)\n", fabric.c_str());
        const cf::ClothFitOutcome nonlinear = cf::fit_cloth(request_for(fabric, training, cf::DragModel::nonlinear));
        const bool nonlinear_only = std::getenv("FLOWVID_FIT_NONLINEAR_ONLY") != nullptr;
        std::fprintf(stderr, "fitting %s (linear drag only)\n", fabric.c_str());
        const cf::ClothFitOutcome linear =
            nonlinear_only ? nonlinear : cf::fit_cloth(request_for(fabric + "-linear", training, cf::DragModel::linear));
        fitted[fabric] = nonlinear.fitted;
        if (nonlinear.preset) flowvid::formats::write_fabric_preset((out / (fabric + ".fabric.json")).string(), *nonlinear.preset);

        const Assessed start = assess(held_out, nonlinear.start, false);
        const Assessed lin = assess(held_out, linear.fitted, false);
        const Assessed ours = assess(held_out, nonlinear.fitted, true);
        std::printf("\n### %s: fit %s + %s (frame weight half-life %g frames), predict held-out %s (RMS vertex error vs truth, mm)\n\n",
                    fabric.c_str(), training[0].c_str(), training[1].c_str(), env_number("FLOWVID_FIT_HALF_LIFE", 0.0),
                    held_out.c_str());
        std::printf("| model | frames 1-10 | 11-25 | 26-50 | all | floor (1-10, 11-25, 26-50) |\n|---|---|---|---|---|---|\n");
        print_row("starting guess", start, false);
        if (!nonlinear_only) print_row("linear drag only, fitted", lin, false);
        print_row("nonlinear drag, fitted", ours, true);
        std::printf("\nfit: %lld evaluations (%lld simulations), %.0f s; training error %.1f -> %.1f (linear: %.1f)\n",
                    nonlinear.evaluations, nonlinear.simulations, nonlinear.seconds, nonlinear.start_evaluation.total,
                    nonlinear.final_evaluation.total, linear.final_evaluation.total);
        record[fabric] = {{"start_mm", start.all_frames_mm}, {"linear_mm", lin.all_frames_mm}, {"fitted_mm", ours.all_frames_mm},
                          {"fitted_1_10_mm", 1e3 * ours.windows[0].vertex_rms_m},
                          {"linear_1_10_mm", 1e3 * lin.windows[0].vertex_rms_m},
                          {"start_1_10_mm", 1e3 * start.windows[0].vertex_rms_m},
                          {"floor_1_10_mm", 1e3 * ours.windows[0].vertex_floor_m},
                          {"seconds", nonlinear.seconds}, {"simulations", nonlinear.simulations}};
        std::fflush(stdout);
    }

    if (std::getenv("FLOWVID_FIT_NONLINEAR_ONLY") != nullptr) {
        std::ofstream((out / "study.json").string()) << record.dump(2) << '\n';
        return 0;
    }
    std::printf("\n### Recognition: weighted metric error of each fitted preset on held-out captures (* = lowest)\n\n");
    std::printf("| capture | cotton preset | silk preset |\n|---|---|---|\n");
    int correct = 0, total = 0;
    for (const std::string capture : {"cloth-cotton-waving-2", "cloth-cotton-static-2", "cloth-silk-waving-2"}) {
        const double cotton = assess(capture, fitted["cotton"], false).weighted_error;
        const double silk = assess(capture, fitted["silk"], false).weighted_error;
        const bool is_cotton = capture.find("cotton") != std::string::npos;
        correct += (is_cotton ? cotton < silk : silk < cotton);
        ++total;
        std::printf("| %s | %.1f%s | %.1f%s |\n", capture.c_str(), cotton, cotton < silk ? "*" : "", silk, silk < cotton ? "*" : "");
    }
    std::printf("\nrecognised %d of %d\n", correct, total);
    record["recognised"] = correct;
    record["recognition_cases"] = total;

    if (std::getenv("FLOWVID_FIT_SKIP_SPEED") == nullptr) {
        std::fprintf(stderr, "speed: 9 parameters, two 50-frame waving trials\n");
        cf::ClothFitRequest speed = request_for("cotton-two-waving", {"cloth-cotton-waving-1", "cloth-cotton-waving-2"},
                                                cf::DragModel::nonlinear);
        speed.budget_seconds = 600.0;  // the 10 minutes
        const cf::ClothFitOutcome r = cf::fit_cloth(speed);
        std::printf("\n### Speed: 9-parameter fit of cotton waving-1 + waving-2 (50 frames each, 24x24, 2 threads)\n\n"
                    "%.0f s wall, %lld evaluations = %lld simulations, annealing %s\n", r.seconds, r.evaluations,
                    r.simulations, flowvid::optim::status_name(r.search.annealing.status));
        record["speed_seconds"] = r.seconds;
        record["speed_simulations"] = r.simulations;
    }
    std::ofstream((out / "study.json").string()) << record.dump(2) << '\n';
    return 0;
}
