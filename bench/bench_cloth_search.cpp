// Which search reaches a cloth fit's error in fewer simulations: the
// thesis's annealing or CMA-ES (`fit cloth --search`), in one run on one
// machine. The fit is issue 29's: one static drape and two 50-frame waving
// trials of one fabric, 24x24, the capacity model's parameters (14, a scan
// fit: the footage's projector stripes give the depth), a 600 s budget on
// 2 threads. Both searches get the same request; each fit's curve is its
// best error after every design point, annealing stage or CMA-ES
// generation and polish step. Reported: each fit's final error and wall
// time, and the evaluations CMA-ES needs to reach the annealing's best
// error before the polish (the ratio to the annealing's own count).
//
// Fits never read truth/. Environment: FLOWVID_SEARCH_FABRIC (cotton),
// FLOWVID_SEARCH_BUDGET_S (600; 0: no time limit), FLOWVID_SEARCH_EVALUATIONS
// (400, the main search's cap), FLOWVID_SEARCH_FIT_TO (scan; footage, tracks),
// FLOWVID_SEARCH_FRAMES (50), FLOWVID_SEARCH_THREADS (2), FLOWVID_SEARCH_OUT
// (./cloth_search: curves.csv, search.json, curves.svg),
// FLOWVID_SEARCH_METHODS (annealing,cmaes), FLOWVID_SEARCH_VARIABILITY_RUNS
// (4, fit cloth's), FLOWVID_SEARCH_POLISH (-1: fit cloth's default),
// FLOWVID_SEARCH_DESIGN_POINTS (0: fit cloth's default for each search),
// FLOWVID_SEARCH_PLOT=DIR (only draw DIR/curves.svg again from its CSV).

#include "flowvid/cloth/simulator.hpp"
#include "flowvid/formats/capture.hpp"
#include "fit_curve.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace cf = flowvid::cloth_fit;
namespace fs = std::filesystem;
namespace optim = flowvid::optim;
using flowvid::bench::CurvePoint;
using flowvid::bench::curve_of;

namespace {

std::string env_text(const char* name, const std::string& fallback) {
    const char* text = std::getenv(name);
    return text && *text ? text : fallback;
}
double env_number(const char* name, double fallback) {
    const char* text = std::getenv(name);
    return text && *text ? std::atof(text) : fallback;
}

// Evaluations until the curve first reaches `target` (-1: never).
long long evaluations_to_reach(const std::vector<CurvePoint>& curve, double target) {
    for (const CurvePoint& p : curve)
        if (p.best <= target) return p.evaluations;
    return -1;
}

// A small line plot of the curves (log error axis), readable at a glance.
std::string curves_svg(const std::vector<std::pair<std::string, std::vector<CurvePoint>>>& curves, const std::string& title) {
    const double width = 660, height = 360, left = 90, right = 20, top = 40, bottom = 50;
    long long max_evaluations = 1;
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    // The top of the axis is the second-worst point of each curve: the first
    // design point is often far off and would flatten everything after it
    // (points above the top are drawn at the top).
    for (const auto& [name, curve] : curves)
        for (std::size_t k = 0; k < curve.size(); ++k) {
            const CurvePoint& p = curve[k];
            if (!std::isfinite(p.best)) continue;
            max_evaluations = std::max(max_evaluations, p.evaluations);
            lo = std::min(lo, p.best);
            if (k > 0 || curve.size() == 1) hi = std::max(hi, p.best);
        }
    if (!(lo > 0.0) || !(hi > lo)) {
        lo = 1.0;
        hi = 10.0;
    }
    const double log_lo = std::log10(lo) - 0.05, log_hi = std::log10(hi) + 0.05;
    const auto x_of = [&](double e) { return left + (width - left - right) * e / double(max_evaluations); };
    const auto y_of = [&](double v) {
        return top + (height - top - bottom) * std::max(0.0, log_hi - std::log10(v)) / (log_hi - log_lo);
    };
    std::ostringstream svg;
    svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
        << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n"
        << "<text x='" << left << "' y='22' font-size='14'>" << title << "</text>\n"
        << "<line x1='" << left << "' y1='" << height - bottom << "' x2='" << width - right << "' y2='" << height - bottom
        << "' stroke='black'/>\n<line x1='" << left << "' y1='" << top << "' x2='" << left << "' y2='" << height - bottom
        << "' stroke='black'/>\n"
        << "<text x='" << (left + width - right) / 2 << "' y='" << height - 12
        << "' text-anchor='middle'>evaluations (each simulates every trial)</text>\n"
        << "<text x='16' y='" << (top + height - bottom) / 2 << "' transform='rotate(-90 16 " << (top + height - bottom) / 2
        << ")' text-anchor='middle'>best error (log)</text>\n";
    for (int k = 0; k <= 4; ++k) {
        const double e = max_evaluations * k / 4.0;
        svg << "<text x='" << x_of(e) << "' y='" << height - bottom + 16 << "' text-anchor='middle'>" << std::lround(e)
            << "</text>\n";
        const double v = std::pow(10.0, log_lo + (log_hi - log_lo) * k / 4.0);
        char label[32];
        std::snprintf(label, sizeof label, "%.3g", v);
        svg << "<text x='" << left - 6 << "' y='" << y_of(v) + 4 << "' text-anchor='end'>" << label << "</text>\n";
    }
    const char* colours[] = {"#c0392b", "#2471a3", "#239b56", "#7d3c98"};
    int index = 0;
    for (const auto& [name, curve] : curves) {
        const char* colour = colours[index % 4];
        svg << "<polyline fill='none' stroke='" << colour << "' stroke-width='2' points='";
        double previous = std::numeric_limits<double>::quiet_NaN();
        for (const CurvePoint& p : curve) {
            if (!std::isfinite(p.best)) continue;
            if (std::isfinite(previous)) svg << x_of(double(p.evaluations)) << ',' << y_of(previous) << ' ';
            svg << x_of(double(p.evaluations)) << ',' << y_of(p.best) << ' ';
            previous = p.best;
        }
        svg << "'/>\n<text x='" << width - right - 150 << "' y='" << top + 16 * (index + 1) << "' fill='" << colour << "'>"
            << name << "</text>\n";
        ++index;
    }
    svg << "</svg>\n";
    return svg.str();
}

}  // namespace

// FLOWVID_SEARCH_PLOT=DIR: draw DIR/curves.svg again from DIR/curves.csv
// (and DIR/search.json's fabric and target), without fitting.
int replot(const fs::path& dir) {
    std::vector<std::pair<std::string, std::vector<CurvePoint>>> curves;
    std::ifstream csv((dir / "curves.csv").string());
    std::string line;
    std::getline(csv, line);  // header
    while (std::getline(csv, line)) {
        std::stringstream fields(line);
        std::string method, evaluations, best;
        if (!std::getline(fields, method, ',') || !std::getline(fields, evaluations, ',') || !std::getline(fields, best)) continue;
        if (curves.empty() || curves.back().first != method) curves.emplace_back(method, std::vector<CurvePoint>{});
        curves.back().second.push_back({std::atoll(evaluations.c_str()), std::atof(best.c_str())});
    }
    if (curves.empty()) {
        std::fprintf(stderr, "%s: no curves to draw\n", (dir / "curves.csv").string().c_str());
        return 1;
    }
    const nlohmann::json record = nlohmann::json::parse(std::ifstream((dir / "search.json").string()));
    char title[160];
    std::snprintf(title, sizeof title, "%s: best error against evaluations (%s fit, %.0f s, %d threads)",
                  record.value("fabric", std::string("?")).c_str(), record.value("fit_to", std::string("?")).c_str(),
                  record.value("budget_seconds", 0.0), record.value("threads", 0));
    std::ofstream((dir / "curves.svg").string()) << curves_svg(curves, title);
    return 0;
}

int main() {
    if (const char* plot = std::getenv("FLOWVID_SEARCH_PLOT")) return replot(plot);
    const std::string fabric = env_text("FLOWVID_SEARCH_FABRIC", "cotton");
    const fs::path out = env_text("FLOWVID_SEARCH_OUT", "cloth_search");
    fs::create_directories(out);
    const std::string fit_to = env_text("FLOWVID_SEARCH_FIT_TO", "scan");
    std::vector<std::string> methods;
    {
        std::stringstream list(env_text("FLOWVID_SEARCH_METHODS", "annealing,cmaes"));
        for (std::string m; std::getline(list, m, ',');) methods.push_back(m);
    }

    cf::ClothFitRequest base;
    for (const char* trial : {"static-1", "waving-1", "waving-2"})
        base.captures.push_back(flowvid::formats::read_capture(std::string(FLOWVID_SHARED_DIR) + "/captures/cloth-" + fabric + "-" + trial));
    base.name = fabric;
    base.load.target = cf::fit_target_from_name(fit_to).value_or(cf::FitTarget::scan);
    base.load.waving_frames = static_cast<int>(env_number("FLOWVID_SEARCH_FRAMES", 50));
    // The shape targets' predictability weighting (fit cloth's defaults for them).
    base.load.half_life_frames = base.load.target == cf::FitTarget::footage ? 10.0 : 5.0;
    base.evaluations = static_cast<long long>(env_number("FLOWVID_SEARCH_EVALUATIONS", 400));
    base.budget_seconds = env_number("FLOWVID_SEARCH_BUDGET_S", 600);
    base.threads = static_cast<int>(env_number("FLOWVID_SEARCH_THREADS", 2));
    base.seed = 1;
    // fit cloth's default integrator (backward Euler), as a user's fit runs.
    base.problem.swatch.simulation.integrator = flowvid::cloth::Integrator::implicit_euler;
    base.variability_runs = static_cast<int>(env_number("FLOWVID_SEARCH_VARIABILITY_RUNS", base.variability_runs));
    base.polish_evaluations = static_cast<long long>(env_number("FLOWVID_SEARCH_POLISH", -1));
    base.design_points = static_cast<int>(env_number("FLOWVID_SEARCH_DESIGN_POINTS", 0));

    nlohmann::json record = {{"fabric", fabric}, {"fit_to", fit_to}, {"waving_frames", base.load.waving_frames},
                             {"budget_seconds", base.budget_seconds}, {"evaluations_cap", base.evaluations},
                             {"threads", base.threads}};
    std::vector<std::pair<std::string, std::vector<CurvePoint>>> curves;
    std::ofstream csv((out / "curves.csv").string());
    csv << "search,evaluations,best_error\n";
    for (const std::string& method : methods) {
        cf::ClothFitRequest request = base;
        const std::optional<optim::SearchMethod> search = optim::search_method_from_name(method);
        if (!search) {
            std::fprintf(stderr, "FLOWVID_SEARCH_METHODS: \"%s\" is not annealing or cmaes\n", method.c_str());
            return 2;
        }
        request.search = *search;
        long long last = -1000;
        std::string phase;
        request.progress = [&](const flowvid::ProgressReport& p) {
            const long long percent = static_cast<long long>(100 * p.fraction);
            if (percent - last >= 5 || p.stage != phase) {
                phase = p.stage;
                std::fprintf(stderr, "  [%s] %s %lld%%, %s\n", method.c_str(), p.stage.c_str(), percent, p.message.c_str());
                last = percent;
            }
            return true;
        };
        std::fprintf(stderr, "fitting %s with %s\n", fabric.c_str(), method.c_str());
        const cf::ClothFitOutcome outcome = cf::fit_cloth(request);
        const std::vector<CurvePoint> curve = curve_of(outcome);
        for (const CurvePoint& p : curve) csv << method << ',' << p.evaluations << ',' << p.best << '\n';
        curves.emplace_back(method, curve);
        record["fits"][method] = {{"parameters", outcome.parameters.size()},
                                  {"design_points", outcome.search.design.points.size()},
                                  {"search_evaluations", outcome.search.evaluations},
                                  {"search_best_error", outcome.search.annealing.best_value},
                                  {"search_status", optim::status_name(outcome.search.annealing.status)},
                                  {"polish_evaluations", outcome.polish ? outcome.polish->evaluations : 0},
                                  {"evaluations", outcome.evaluations},
                                  {"simulations", outcome.simulations},
                                  {"start_error", outcome.start_evaluation.total},
                                  {"final_error", outcome.final_evaluation.total},
                                  {"variability_runs", outcome.variability_runs_planned},
                                  {"seconds", outcome.seconds}};
        std::fflush(stdout);
    }

    std::printf("\n### Search: %s, static-1 + waving-1 + waving-2 (%d frames), --fit-to %s, budget %.0f s, %d threads\n\n",
                fabric.c_str(), base.load.waving_frames, fit_to.c_str(), base.budget_seconds, base.threads);
    std::printf("| search | parameters | design | search evaluations | best after search and polish | final error | evaluations (all phases) | wall s |\n"
                "|---|---|---|---|---|---|---|---|\n");
    for (const std::string& method : methods) {
        const nlohmann::json& f = record["fits"][method];
        std::printf("| %s | %d | %d | %lld | %.1f | %.1f | %lld | %.0f |\n", method.c_str(), f["parameters"].get<int>(),
                    f["design_points"].get<int>(), f["search_evaluations"].get<long long>(), f["search_best_error"].get<double>(),
                    f["final_error"].get<double>(), f["evaluations"].get<long long>(), f["seconds"].get<double>());
    }
    if (record["fits"].contains("annealing") && record["fits"].contains("cmaes")) {
        const double target = record["fits"]["annealing"]["search_best_error"].get<double>();
        const long long annealing_count = evaluations_to_reach(curves.front().second, target);
        const long long cmaes_count = evaluations_to_reach(curves.back().second, target);
        record["annealing_best_error"] = target;
        record["annealing_evaluations_to_best"] = annealing_count;
        record["cmaes_evaluations_to_annealing_best"] = cmaes_count;
        if (cmaes_count > 0) {
            record["ratio"] = double(annealing_count) / double(cmaes_count);
            std::printf("\nCMA-ES reaches the annealing's best error (%.1f) after %lld evaluations; the annealing after %lld: %.2fx fewer\n",
                        target, cmaes_count, annealing_count, double(annealing_count) / double(cmaes_count));
        } else {
            std::printf("\nCMA-ES does not reach the annealing's best error (%.1f) in its budget\n", target);
        }
    }
    std::ofstream((out / "search.json").string()) << record.dump(2) << '\n';
    return replot(out);
}
