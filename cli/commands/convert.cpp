// flowvid convert IN OUT: flow lines between SVG (what artists draw) and
// *.flowlines.json (what flowvid reads), in both directions; fabric presets to
// U3M, OpenUSD and Blender cloth settings for a mesh, and back. The formats
// live in formats/ (fabric_u3m, fabric_usda, polygon_mesh, blender_cloth_settings),
// the Blender mapping in cloth/blender_cloth: this command only picks them by file type.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/cloth/blender_cloth.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/blender_cloth_settings.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fabric_u3m.hpp"
#include "flowvid/formats/fabric_usda.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct ConvertOptions {
    std::string input;
    std::string output;
    std::string background;
    std::string mesh;
    cloth::BlenderClothOptions blender;
};

bool ends_with(const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool is_preset_kind(formats::FileKind kind) {
    return kind == formats::FileKind::fabric_preset || kind == formats::FileKind::fabric_u3m ||
           kind == formats::FileKind::fabric_usda;
}

int convert_flowlines(const ConvertOptions& options, formats::FileKind input_kind) {
    std::vector<Problem> warnings;
    formats::FlowLineSet lines = input_kind == formats::FileKind::flowline_svg
                                     ? formats::import_flowlines_svg(options.input, &warnings)
                                     : formats::read_flowline_set(options.input, &warnings);
    print_problems(warnings);
    if (ends_with(options.output, ".svg")) formats::write_flowlines_svg(options.output, lines, options.background);
    else if (ends_with(options.output, ".json")) formats::write_flowline_set(options.output, lines);
    else {
        log_message("error: " + options.output + ": unknown output type for flow lines; end the name with "
                    ".flowlines.json or .svg");
        return kExitUsage;
    }
    std::cout << options.output << ": " << lines.inputs.size() << " input and " << lines.outputs.size()
              << " output lines\n";
    return kExitOk;
}

int convert_preset(const ConvertOptions& options, formats::FileKind input_kind) {
    const std::string& out = options.output;
    const bool blender = ends_with(out, ".blender.json");
    if (!blender && !options.mesh.empty()) {
        log_message("error: --mesh is for Blender cloth settings: end OUT with .blender.json");
        return kExitUsage;
    }
    if (blender && options.mesh.empty()) {
        log_message("error: " + out + ": Blender cloth settings depend on the garment's mesh; add --mesh garment.obj "
                    "(or .glb)");
        return kExitUsage;
    }
    if (!blender && !ends_with(out, ".u3m") && !ends_with(out, ".usda") && !ends_with(out, ".json")) {
        log_message("error: " + out + ": unknown output type for a fabric preset; end the name with .u3m, .usda, "
                    ".blender.json (with --mesh) or .fabric.json");
        return kExitUsage;
    }
    std::vector<Problem> warnings;
    formats::FabricPreset preset;
    if (input_kind == formats::FileKind::fabric_u3m) preset = formats::read_fabric_u3m(options.input, &warnings);
    else if (input_kind == formats::FileKind::fabric_usda) preset = formats::read_fabric_usda(options.input, &warnings);
    else preset = formats::read_fabric_preset(options.input, &warnings);
    print_problems(warnings);

    if (blender) {
        std::vector<Problem> mesh_warnings;
        const formats::BlenderClothSettings settings =
            cloth::blender_cloth_settings_for_mesh(preset, options.mesh, options.blender, &mesh_warnings);
        print_problems(mesh_warnings);
        formats::write_blender_cloth_settings(out, settings);
        std::cout << out << ": Blender cloth settings for \"" << preset.name << "\" on " << options.mesh << " ("
                  << settings.mesh.vertex_count << " vertices, mean edge " << settings.mesh.mean_edge_length_m * 1000.0
                  << " mm) at " << settings.scene.fps << " fps; " << settings.not_represented.size()
                  << " notes on what Blender cannot express\n";
        return kExitOk;
    }
    if (ends_with(out, ".u3m")) formats::write_fabric_u3m(out, preset);
    else if (ends_with(out, ".usda")) formats::write_fabric_usda(out, preset);
    else formats::write_fabric_preset(out, preset);
    std::cout << out << ": fabric preset \"" << preset.name << "\" (" << formats::fabric_parameter_table().size()
              << " parameters, SI)\n";
    return kExitOk;
}

int run_convert(const ConvertOptions& options) {
    const formats::FileKind input_kind = formats::detect_file_kind(options.input);
    if (input_kind == formats::FileKind::flowline_svg || input_kind == formats::FileKind::flowline_set) {
        if (!options.mesh.empty()) {
            log_message("error: --mesh is for fabric presets; flow lines need no mesh");
            return kExitUsage;
        }
        return convert_flowlines(options, input_kind);
    }
    if (is_preset_kind(input_kind)) return convert_preset(options, input_kind);
    log_message("error: " + options.input + ": is a " + formats::file_kind_name(input_kind) +
                "; convert reads flow lines (SVG or *.flowlines.json) or a fabric preset (*.fabric.json, or a .u3m or "
                ".usda that flowvid convert wrote)");
    return kExitInvalidInput;
}

const RegisterCommand registration{Command{
    "convert", "convert flow lines (SVG <-> JSON) and fabric presets (U3M, OpenUSD, Blender cloth settings)",
    [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<ConvertOptions>();
        app.footer(
            "Flow lines: reads lines drawn in any vector editor (SVG: paths or polylines in the\n"
            "groups id=\"input\" and id=\"output\", output paths naming their input with\n"
            "data-from=\"ID\", transforms honoured, curves flattened to 0.1 px) or a\n"
            "*.flowlines.json, and writes the other form (.flowlines.json or .svg).\n\n"
            "Fabric presets (IN: *.fabric.json, or a .u3m/.usda written by convert), by OUT's name:\n"
            "  .u3m            U3M 1.1 material (JSON) for garment tools: weight in g/m^2 in its\n"
            "                  physics section, every parameter in SI with its uncertainty under\n"
            "                  custom.flowvid\n"
            "  .usda           OpenUSD material with the deformables proposal's surface stretch,\n"
            "                  shear and bend stiffness and density (metersPerUnit = kilogramsPerUnit\n"
            "                  = 1); damping, drag and uncertainties under flowvid:\n"
            "  .blender.json   Blender cloth settings for the mesh given with --mesh (.obj in\n"
            "                  metres, or .glb), the add-on's mapping, with what Blender cannot express\n"
            "  .fabric.json    the preset again (reading a .u3m or .usda back)\n\n"
            "Examples:\n"
            "  flowvid convert flowlines.svg waterfall.flowlines.json\n"
            "  flowvid convert waterfall.flowlines.json edit.svg --background frame0001.png\n"
            "  flowvid convert cotton.fabric.json cotton.u3m\n"
            "  flowvid convert cotton.fabric.json cotton.usda\n"
            "  flowvid convert cotton.fabric.json shirt.blender.json --mesh shirt.obj --fps 25\n"
            "  flowvid convert cotton.u3m back.fabric.json");
        app.add_option("IN", options->input, "flow lines (.svg, .flowlines.json) or a fabric preset (.fabric.json, .u3m, .usda)")
            ->required();
        app.add_option("OUT", options->output, "file to write: .flowlines.json, .svg, .u3m, .usda, .blender.json, .fabric.json")
            ->required();
        app.add_option("--background", options->background,
                       "image to show under the lines in the written SVG (a path or URL, stored as given)");
        app.add_option("--mesh", options->mesh, "the garment for .blender.json: Wavefront .obj (metres) or glTF .glb");
        app.add_option("--fps", options->blender.fps, "scene frames per second for .blender.json")
            ->default_val(24.0)
            ->check(CLI::PositiveNumber);
        app.add_option("--quality", options->blender.quality,
                       "the cloth's current substeps per frame (raised to at least 10) for .blender.json")
            ->default_val(0)
            ->check(CLI::NonNegativeNumber);
        return [options](const GlobalOptions&) { return run_convert(*options); };
    }}};

}  // namespace
}  // namespace flowvid::cli
