// flowvid info FILE: what a file holds, for people or (--json) for machines.

#include "command.hpp"
#include "commands/cloth_options.hpp"
#include "output.hpp"
#include "report_html.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace flowvid::cli {
namespace {

struct InfoOptions {
    std::string path;
    bool json = false;
    double mesh_edge_mm = 0.0;  // 0: not asked
};

// Where the fitting swatch did not hold the folds either, the preset
// reproduces the filmed drape on meshes like it (docs/cloth_model.md).
std::string fitted_mesh_line(const std::optional<cloth::FoldCheck>& fitted) {
    if (!fitted || fitted->holds_folds) return "";
    return "fitted on: a swatch with " + html::format_number(1e3 * fitted->edge_m, 3) +
           " mm edges, which do not hold them either: meshes with edges near " + html::format_number(1e3 * fitted->edge_m, 3) +
           " mm reproduce the filmed drape most closely\n";
}

// What a preset's fold length means for meshes (cloth::check_folds); with
// an edge, for that mesh. The fold rule is the library's, not restated here.
std::string fold_lines(const cloth::FoldCheck& folds, bool edge_given) {
    if (!(folds.fold_length_m > 0.0)) return "folds: none (no bending or no mass): any mesh shows the same fabric\n";
    std::string text = "folds: about " + html::format_number(1e3 * folds.fold_length_m, 3) +
                       " mm when hung (its elastogravity length); meshes with edges up to " +
                       html::format_number(1e3 * folds.longest_edge_m, 3) + " mm hold them\n";
    if (edge_given)
        text += folds.holds_folds
                    ? "mesh: edges of " + html::format_number(1e3 * folds.edge_m, 3) + " mm hold the fabric's folds\n"
                    : "mesh: edges of " + html::format_number(1e3 * folds.edge_m, 3) +
                          " mm are too long: the cloth folds at the mesh's scale and a finer mesh drapes differently; "
                          "subdivide to edges of at most " + html::format_number(1e3 * folds.longest_edge_m, 3) +
                          " mm to see the fabric's own folds\n";
    return text;
}

int run_info(const InfoOptions& options) {
    const bool is_preset = formats::detect_file_kind(options.path) == formats::FileKind::fabric_preset;
    if (options.mesh_edge_mm > 0.0) {
        if (!is_preset && std::filesystem::exists(options.path))  // a missing file: the reader says so
            throw UsageError(options.path, "--mesh-edge-mm", "applies to fabric presets only",
                             "give a *.fabric.json, or leave --mesh-edge-mm out");
        const formats::FabricPreset preset = formats::read_fabric_preset(options.path);
        const cloth::FoldCheck folds =
            cloth::check_folds(cloth::material_from_fabric(preset.parameters), 1e-3 * options.mesh_edge_mm);
        const std::optional<cloth::FoldCheck> fitted = fitting_swatch_folds(preset);
        if (options.json) {
            nlohmann::json summary = {{"kind", "fold check"},
                                      {"path", options.path},
                                      {"fold_length_mm", 1e3 * folds.fold_length_m},
                                      {"mesh_edge_mm", options.mesh_edge_mm},
                                      {"longest_edge_mm", 1e3 * folds.longest_edge_m},
                                      {"mesh_holds_folds", folds.holds_folds},
                                      {"fitted_edge_mm", nullptr},
                                      {"fitted_mesh_holds_folds", nullptr}};
            if (fitted) {
                summary["fitted_edge_mm"] = 1e3 * fitted->edge_m;
                summary["fitted_mesh_holds_folds"] = fitted->holds_folds;
            }
            std::cout << summary.dump(2) << '\n';
        } else {
            std::cout << fold_lines(folds, true) << fitted_mesh_line(fitted);
        }
        return kExitOk;
    }
    // A preset's summary would look like a preset without being one (units
    // beside the values, no version): for machines it prints as the preset
    // itself, as flowvid reads it, which `flowvid validate` accepts and any
    // preset reader takes. Its units are in its key names.
    if (options.json && is_preset) {
        std::cout << formats::fabric_preset_to_json(formats::read_fabric_preset(options.path)).dump(2) << '\n';
        return kExitOk;
    }
    const nlohmann::json summary = formats::summarize_any_file(options.path);
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    if (!options.json && is_preset) {
        const formats::FabricPreset preset = formats::read_fabric_preset(options.path);
        std::cout << fold_lines(cloth::check_folds(cloth::material_from_fabric(preset.parameters), 0.0), false)
                  << fitted_mesh_line(fitting_swatch_folds(preset));
    }
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
            "(normalised: `flowvid validate` accepts it; units are in its key names, SI).\n"
            "A preset's summary ends with the length its fabric folds at when hung, (B / rho g)^(1/3),\n"
            "and the longest mesh edge that holds those folds; with --mesh-edge-mm, whether a mesh\n"
            "with that edge (a garment's mean edge) does (JSON: fold_length_mm, longest_edge_mm,\n"
            "mesh_holds_folds). A coarser mesh folds at its own scale: its drape is the mesh's, and\n"
            "a finer mesh drapes differently. A fitted preset whose fitting swatch was itself too\n"
            "coarse for its folds reproduces the filmed drape best on meshes with edges like that\n"
            "swatch's (JSON: fitted_edge_mm, fitted_mesh_holds_folds; null when not recorded).\n\n"
            "Examples:\n"
            "  flowvid info cotton.fabric.json\n"
            "  flowvid info --json --mesh-edge-mm 12 silk.fabric.json\n"
            "  flowvid info --json ../shared/captures/rigid-toss-major > summary.json");
        app.add_option("FILE", options->path, "file or capture folder")->required();
        app.add_flag("--json", options->json, "print the summary as JSON (stable keys, for scripts)");
        app.add_option("--mesh-edge-mm", options->mesh_edge_mm,
                       "fabric presets: whether a mesh with edges this long (mm; a garment's mean edge) holds the "
                       "fabric's folds")
            ->check(CLI::PositiveNumber);
        return [options](const GlobalOptions&) { return run_info(*options); };
    }}};

}  // namespace
}  // namespace flowvid::cli
