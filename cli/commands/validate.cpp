// flowvid validate FILE...: check files against their format specs.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/formats/any_file.hpp"

#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct ValidateOptions {
    std::vector<std::string> paths;
    bool lenient = false;
};

int run_validate(const ValidateOptions& options) {
    const formats::Strictness strictness = options.lenient ? formats::Strictness::lenient : formats::Strictness::strict;
    int invalid = 0, unreadable = 0;
    for (const std::string& path : options.paths) {
        std::error_code error;
        if (!std::filesystem::exists(path, error)) {  // an I/O error (exit 4), not an invalid file
            print_problems({{Problem::Severity::error, path, "", "no such file or folder", "check the path"}});
            std::cout << path << ": missing\n";
            ++unreadable;
            continue;
        }
        const std::vector<Problem> problems = formats::validate_any_file(path, strictness);
        print_problems(problems);
        bool has_error = false;
        for (const Problem& problem : problems) has_error = has_error || problem.severity == Problem::Severity::error;
        std::cout << path << ": " << (has_error ? "invalid" : "valid") << '\n';
        if (has_error) ++invalid;
    }
    return unreadable ? kExitIoError : invalid ? kExitInvalidInput : kExitOk;
}

const RegisterCommand registration{Command{
    "validate", "check flowvid files and capture folders; lists every problem", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<ValidateOptions>();
        app.footer(
            "Checks each FILE against its format spec (formats/specs/): fabric presets, flow-line sets\n"
            "(JSON or SVG), particle banks and vertex-animation EXRs, motion .glb files, and capture\n"
            "folders (give the folder). Prints every problem on stderr with the file, the field and\n"
            "how to fix it, and 'PATH: valid' or 'PATH: invalid' on stdout.\n\n"
            "Examples:\n"
            "  flowvid validate cotton.fabric.json\n"
            "  flowvid validate ../shared/captures/cloth-cotton-waving-1 lines.flowlines.json\n\n"
            "Exit code 0 when all are valid, 3 when any is invalid, 4 when any is missing.");
        app.add_option("FILE", options->paths, "files or capture folders to check")->required();
        app.add_flag("--lenient", options->lenient,
                     "accept unknown keys with a warning, as readers do (default: unknown keys are errors)");
        return [options](const GlobalOptions&) { return run_validate(*options); };
    }}};

}  // namespace
}  // namespace flowvid::cli
