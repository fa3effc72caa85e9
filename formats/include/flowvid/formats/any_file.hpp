#pragma once
// One entry point over every flowvid format: recognise a file by its content,
// validate it, summarise it. Used by `flowvid validate`, `flowvid info` and the
// fuzz targets, so all three judge a file the same way.

#include "flowvid/error.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace flowvid::formats {

enum class FileKind {
    unknown,
    fabric_preset,      // *.fabric.json
    flowline_set,       // *.flowlines.json
    flowline_svg,       // flow lines drawn in SVG
    particle_bank,      // multi-part EXR
    vertex_animation,   // EXR, one row per frame
    motion_gltf,        // .glb
    capture_folder,     // folder with capture.json (or the capture.json itself)
    fit_shard,          // *.fit_shard.json: one shard of a split fit (flowvid merge)
    diagnosis,          // diagnosis.json, *.diagnosis.json: flowvid diagnose's result
    gap_bench_labels,   // labels.json, *.labels.json: flowvid bench gap's hidden labels
    rigid_fit,          // *.rigid_fit.json (and fit.json by content): flowvid fit rigid's result
    rectification,      // rectify.json, *.rectify.json: what flowvid rectify did
    fabric_u3m,         // *.u3m: a fabric preset as a U3M 1.1 material (flowvid convert)
    fabric_usda,        // *.usda: a fabric preset as an OpenUSD physics material (flowvid convert)
    swatch_experiment,  // *.swatch_experiment.json: a swatch experiment (flowvid swatch, the Blender add-on)
    swatch_frames,      // *.swatch_frames.json: a swatch experiment's simulated frames (flowvid swatch)
    blender_cloth_settings,  // *.blender.json: a preset's Blender cloth settings for a mesh (flowvid convert)
};

const char* file_kind_name(FileKind kind);

// Looks at the content (JSON "format", EXR attributes, glTF magic, SVG root),
// falling back to the file name (patterns above). Throws IoError when the
// path cannot be read.
FileKind detect_file_kind(const std::string& path);

// Every problem of the file; never throws on bad content (an unreadable or
// unrecognised file is reported as a problem too).
std::vector<Problem> validate_any_file(const std::string& path, Strictness strictness = Strictness::strict);

// A summary for `flowvid info` (throws ValidationError / IoError when invalid).
nlohmann::json summarize_any_file(const std::string& path);

// Flow lines from either form an artist or a tool gives them: an SVG drawing
// or a *.flowlines.json, told apart by content.
FlowLineSet read_flowline_drawing(const std::string& path, std::vector<Problem>* warnings = nullptr);

}  // namespace flowvid::formats
