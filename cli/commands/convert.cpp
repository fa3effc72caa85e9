// flowvid convert IN OUT: flow lines between SVG (what artists draw) and
// *.flowlines.json (what flowvid reads), in both directions.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct ConvertOptions {
    std::string input;
    std::string output;
    std::string background;
};

bool ends_with(const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int run_convert(const ConvertOptions& options) {
    const formats::FileKind input_kind = formats::detect_file_kind(options.input);
    std::vector<Problem> warnings;
    formats::FlowLineSet lines;
    if (input_kind == formats::FileKind::flowline_svg) lines = formats::import_flowlines_svg(options.input, &warnings);
    else if (input_kind == formats::FileKind::flowline_set) lines = formats::read_flowline_set(options.input, &warnings);
    else {
        log_message("error: " + options.input + ": is a " + formats::file_kind_name(input_kind) +
                    "; convert reads flow lines (SVG or *.flowlines.json)");
        return kExitInvalidInput;
    }
    print_problems(warnings);

    if (ends_with(options.output, ".svg")) formats::write_flowlines_svg(options.output, lines, options.background);
    else if (ends_with(options.output, ".json")) formats::write_flowline_set(options.output, lines);
    else {
        log_message("error: " + options.output + ": unknown output type; end the name with .flowlines.json or .svg");
        return kExitUsage;
    }
    std::cout << options.output << ": " << lines.inputs.size() << " input and " << lines.outputs.size()
              << " output lines\n";
    return kExitOk;
}

const RegisterCommand registration{Command{
    "convert", "convert flow lines between SVG and *.flowlines.json", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<ConvertOptions>();
        app.footer(
            "Reads flow lines drawn in any vector editor (SVG: paths or polylines in the groups\n"
            "id=\"input\" and id=\"output\", output paths naming their input with data-from=\"ID\",\n"
            "transforms honoured, curves flattened to 0.1 px) or a *.flowlines.json, and writes the\n"
            "other form. The output type follows OUT's name: .flowlines.json or .svg.\n\n"
            "Examples:\n"
            "  flowvid convert flowlines.svg waterfall.flowlines.json\n"
            "  flowvid convert waterfall.flowlines.json edit.svg --background frame0001.png");
        app.add_option("IN", options->input, "flow lines to read (.svg or .flowlines.json)")->required();
        app.add_option("OUT", options->output, "file to write (.flowlines.json or .svg)")->required();
        app.add_option("--background", options->background,
                       "image to show under the lines in the written SVG (a path or URL, stored as given)");
        return [options](const GlobalOptions&) { return run_convert(*options); };
    }}};

}  // namespace
}  // namespace flowvid::cli
