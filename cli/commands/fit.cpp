// flowvid fit <kind> / flowvid predict <kind>: dispatch to the registered kinds.

#include "commands/fit.hpp"

#include "output.hpp"

#include <algorithm>
#include <memory>

namespace flowvid::cli {

std::vector<FitKind>& fit_kinds() {
    static std::vector<FitKind> kinds;
    return kinds;
}

std::vector<FitKind>& predict_kinds() {
    static std::vector<FitKind> kinds;
    return kinds;
}

RegisterFitKind::RegisterFitKind(FitKind kind) { fit_kinds().push_back(std::move(kind)); }
std::vector<FitKind>& eval_kinds() {
    static std::vector<FitKind> kinds;
    return kinds;
}

RegisterPredictKind::RegisterPredictKind(FitKind kind) { predict_kinds().push_back(std::move(kind)); }
RegisterEvalKind::RegisterEvalKind(FitKind kind) { eval_kinds().push_back(std::move(kind)); }

namespace {

// One command whose CLI11 sub-subcommands are the registered kinds.
CommandRunner setup_kinds(CLI::App& app, std::vector<FitKind>& kinds) {
    std::sort(kinds.begin(), kinds.end(), [](const FitKind& a, const FitKind& b) { return a.name < b.name; });
    app.require_subcommand(1);
    auto runners = std::make_shared<std::vector<std::pair<CLI::App*, CommandRunner>>>();
    for (const FitKind& kind : kinds) {
        CLI::App* sub = app.add_subcommand(kind.name, kind.summary);
        runners->emplace_back(sub, kind.setup(*sub));
    }
    return [runners](const GlobalOptions& options) {
        for (const auto& [sub, run] : *runners)
            if (sub->parsed()) return run(options);
        return static_cast<int>(kExitUsage);
    };
}

const RegisterCommand fit_registration{Command{
    "fit", "fit a simulator to captures: `flowvid fit cloth|rigid ...`", [](CLI::App& app) -> CommandRunner {
        app.footer("Run 'flowvid fit <kind> --help' for a kind's options.\n\n"
                   "Examples:\n"
                   "  flowvid fit cloth --capture cloth-cotton-static-1 --capture cloth-cotton-waving-1 --out cotton.fabric.json\n"
                   "  flowvid fit rigid --capture ../shared/captures/rigid-toss-major --out fit.json\n"
                   "  flowvid fit rigid --capture toss/ --out fit.json --frames 1:18 --guess guess.json");
        return setup_kinds(app, fit_kinds());
    }}};

const RegisterCommand predict_registration{Command{
    "predict", "what a fit predicts: `flowvid predict cloth|rigid ...`", [](CLI::App& app) -> CommandRunner {
        app.footer("Run 'flowvid predict <kind> --help' for a kind's options.\n\n"
                   "Examples:\n"
                   "  flowvid predict cloth --preset cotton.fabric.json --capture wave2/ --grid 24x24 --out pred.exr\n"
                   "  flowvid predict rigid --fit fit.json --capture toss/ --out predicted/ --frames 19:36");
        return setup_kinds(app, predict_kinds());
    }}};

const RegisterCommand eval_registration{Command{
    "eval", "how well a fitted model matches a capture: `flowvid eval cloth ...`", [](CLI::App& app) -> CommandRunner {
        app.footer("Run 'flowvid eval <kind> --help' for a kind's options.\n\n"
                   "Examples:\n"
                   "  flowvid eval cloth --preset cotton.fabric.json --capture ../shared/captures/cloth-cotton-waving-2");
        return setup_kinds(app, eval_kinds());
    }}};

}  // namespace
}  // namespace flowvid::cli
