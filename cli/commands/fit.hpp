#pragma once
// `flowvid fit <kind>` and `flowvid predict <kind>`: the two commands are
// owned by fit.cpp; each kind (rigid, cloth, ...) plugs in from its own file
// with a static RegisterFitKind / RegisterPredictKind, e.g.
//
//   const RegisterFitKind registration{FitKind{
//       "cloth", "fit fabric parameters to a cloth capture",
//       [](CLI::App& app) -> CommandRunner { ...add options...; return runner; }}};
//
// Kinds register during static initialisation and are read when main() sets
// up the commands, so their order of registration does not matter.

#include "command.hpp"

#include "flowvid/formats/capture.hpp"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace flowvid::cli {

struct FitKind {
    std::string name;     // the sub-subcommand: `flowvid fit <name>`
    std::string summary;  // one line for `flowvid help fit`
    // Adds the kind's options (and footer with examples) to its
    // sub-subcommand and returns the function that runs it.
    std::function<CommandRunner(CLI::App&)> setup;
};

std::vector<FitKind>& fit_kinds();
std::vector<FitKind>& predict_kinds();
std::vector<FitKind>& eval_kinds();
struct RegisterFitKind {
    explicit RegisterFitKind(FitKind kind);
};
struct RegisterPredictKind {
    explicit RegisterPredictKind(FitKind kind);
};
struct RegisterEvalKind {
    explicit RegisterEvalKind(FitKind kind);
};

}  // namespace flowvid::cli
