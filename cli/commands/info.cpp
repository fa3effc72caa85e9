// flowvid info FILE: what a file holds, for people or (--json) for machines.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"

#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct InfoOptions {
    std::string path;
    bool json = false;
};

int run_info(const InfoOptions& options) {
    // A preset's summary would look like a preset without being one (units
    // beside the values, no version): for machines it prints as the preset
    // itself, as flowvid reads it, which `flowvid validate` accepts and any
    // preset reader takes. Its units are in its key names.
    if (options.json && formats::detect_file_kind(options.path) == formats::FileKind::fabric_preset) {
        std::cout << formats::fabric_preset_to_json(formats::read_fabric_preset(options.path)).dump(2) << '\n';
        return kExitOk;
    }
    const nlohmann::json summary = formats::summarize_any_file(options.path);
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "info", "summarise a flowvid file or capture folder", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<InfoOptions>();
        app.footer(
            "Prints what FILE holds: a fabric preset's parameters with units and uncertainty and its\n"
            "provenance; a flow-line set's lines; a bank's particles and patch size; a capture's kind,\n"
            "camera, frame count and experiment. An invalid file is refused with its problems (exit 3).\n"
            "With --json a summary with \"kind\" and \"path\"; a fabric preset prints as the preset itself\n"
            "(normalised: `flowvid validate` accepts it; units are in its key names, SI).\n\n"
            "Examples:\n"
            "  flowvid info cotton.fabric.json\n"
            "  flowvid info --json ../shared/captures/rigid-toss-major > summary.json");
        app.add_option("FILE", options->path, "file or capture folder")->required();
        app.add_flag("--json", options->json, "print the summary as JSON (stable keys, for scripts)");
        return [options](const GlobalOptions&) { return run_info(*options); };
    }}};

}  // namespace
}  // namespace flowvid::cli
