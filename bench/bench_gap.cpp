// Cloth gap diagnosis on the public Blender captures: the pipeline as it was
// before 2026-11-28 (the world's effects only, one evaluation at a time)
// against today's (the model's own terms first, candidates screened and
// refitted side by side), both in this process on the same threads. Prints
// each case's verdict and wall time and the ratio of the medians.
//
//   flowvid_bench_gap                       # the four labelled public cases
//   flowvid_bench_gap --cases c1,pinlag     # a subset (c1 wind s1 pinlag)
//   flowvid_bench_gap --threads 2 --json out.json

#include "flowvid/gap/diagnose.hpp"
#include "flowvid/gap/effects.hpp"
#include "flowvid/gap/open_model.hpp"
#include "flowvid/threads.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace flowvid;

namespace {

struct Case {
    std::string tag;
    std::string capture;  // under ../shared/captures
    std::string preset;   // under tests/data/cloth
    std::string hidden;   // the capture's README label ("none": effect-free)
};

const std::vector<Case>& public_cases() {
    static const std::vector<Case> cases = {
        {"c1", "cloth-cotton-waving-1", "cotton", "none"},
        {"wind", "cloth-cotton-waving-wind", "cotton", "wind"},
        {"s1", "cloth-silk-waving-1", "silk", "none"},
        {"pinlag", "cloth-silk-waving-pinlag", "silk", "pin_lag"},
    };
    return cases;
}

struct Run {
    gap::Diagnosis diagnosis;
    double seconds = 0.0;
};

Run run(const Case& c, bool today, int threads) {
    gap::ClothGapRequest request;
    request.capture_paths = {std::string(FLOWVID_SHARED_DIR) + "/captures/" + c.capture};
    request.preset_path = std::string(FLOWVID_SOURCE_DIR) + "/tests/data/cloth/" + c.preset + ".fabric.json";
    request.threads = threads;
    request.swatch.simulation.threads = threads;
    const auto started = std::chrono::steady_clock::now();
    const gap::OpenedGapModel opened = gap::open_cloth_model(request);
    gap::DiagnoseSettings settings;
    if (!today) {
        settings.concurrent_evaluations = 1;
        for (const std::string& name : opened.model->candidate_effects())
            if (gap::find_effect(name).domain != gap::EffectDomain::model) settings.effects.push_back(name);
    }
    Run out;
    out.diagnosis = gap::diagnose(*opened.model, settings);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return out;
}

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string verdict(const gap::Diagnosis& d) {
    std::string out = d.status;
    for (const std::string& t : d.model_terms) out += " model:" + t;
    for (const std::string& e : d.named) out += " " + e;
    return out;
}

}  // namespace

int main(int argc, char** argv) {
    std::string only, json_path;
    int threads = 0;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--cases") && i + 1 < argc) only = argv[++i];
        else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
        else {
            std::fprintf(stderr, "usage: flowvid_bench_gap [--cases c1,wind,s1,pinlag] [--threads N] [--json OUT]\n");
            return 2;
        }
    }
    threads = resolve_thread_count(threads);
    std::vector<double> before_s, today_s;
    nlohmann::json rows = nlohmann::json::array();
    std::printf("%-7s %-8s | %-28s %7s | %-52s %7s\n", "case", "hidden", "before: verdict", "s", "today: verdict", "s");
    for (const Case& c : public_cases()) {
        if (!only.empty() && ("," + only + ",").find("," + c.tag + ",") == std::string::npos) continue;
        const Run before = run(c, false, threads);
        const Run today = run(c, true, threads);
        before_s.push_back(before.seconds);
        today_s.push_back(today.seconds);
        std::printf("%-7s %-8s | %-28s %7.1f | %-52s %7.1f\n", c.tag.c_str(), c.hidden.c_str(), verdict(before.diagnosis).c_str(),
                    before.seconds, verdict(today.diagnosis).c_str(), today.seconds);
        std::printf("        today: %s\n", today.diagnosis.message.c_str());
        std::fflush(stdout);
        rows.push_back({{"case", c.tag},
                        {"capture", c.capture},
                        {"hidden", c.hidden},
                        {"before", {{"verdict", verdict(before.diagnosis)}, {"seconds", before.seconds},
                                    {"evaluations", before.diagnosis.evaluations}}},
                        {"today", {{"verdict", verdict(today.diagnosis)}, {"seconds", today.seconds},
                                   {"evaluations", today.diagnosis.evaluations}, {"message", today.diagnosis.message}}}});
    }
    const double b = median(before_s), t = median(today_s);
    std::printf("median wall time on %d threads: before %.1f s, today %.1f s (ratio today/before %.2f)\n", threads, b, t,
                b > 0.0 ? t / b : 0.0);
    if (!json_path.empty()) {
        std::ofstream(json_path) << nlohmann::json{{"threads", threads}, {"cases", rows}, {"median_before_s", b},
                                                   {"median_today_s", t}}
                                        .dump(2)
                                 << '\n';
    }
    return 0;
}
