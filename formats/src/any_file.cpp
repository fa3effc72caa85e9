#include "flowvid/formats/any_file.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/blender_cloth_settings.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fabric_u3m.hpp"
#include "flowvid/formats/fabric_usda.hpp"
#include "flowvid/formats/fit_shard.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/gap_bench_labels.hpp"
#include "flowvid/formats/motion_gltf.hpp"
#include "flowvid/formats/particle_bank.hpp"
#include "flowvid/formats/rectification.hpp"
#include "flowvid/formats/rigid_fit.hpp"
#include "flowvid/formats/swatch_experiment.hpp"
#include "flowvid/formats/swatch_frames.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace flowvid::formats {
namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string read_head(const std::string& path, std::size_t bytes) {
    std::ifstream in(path, std::ios::binary);
    std::string head(bytes, '\0');
    in.read(head.data(), static_cast<std::streamsize>(bytes));
    head.resize(static_cast<std::size_t>(in.gcount()));
    return head;
}

FileKind kind_from_json_format(const std::string& format) {
    if (format == "flowvid.fabric") return FileKind::fabric_preset;
    if (format == "flowvid.flowlines") return FileKind::flowline_set;
    if (format == "flowvid.capture") return FileKind::capture_folder;
    if (format == kFitShardFormatName) return FileKind::fit_shard;
    if (format == kDiagnosisFormatName) return FileKind::diagnosis;
    if (format == kGapBenchLabelsFormatName) return FileKind::gap_bench_labels;
    if (format == kRigidFitFormatName) return FileKind::rigid_fit;
    if (format == kRectificationFormatName) return FileKind::rectification;
    if (format == kSwatchExperimentFormatName) return FileKind::swatch_experiment;
    if (format == kSwatchFramesFormatName) return FileKind::swatch_frames;
    if (format == kBlenderClothSettingsFormatName) return FileKind::blender_cloth_settings;
    return FileKind::unknown;
}

// The "format" a JSON file declares near its start ("" when none).
std::string declared_json_format(const std::string& head) {
    const std::size_t format_key = head.find("\"format\"");
    if (format_key == std::string::npos) return {};
    const std::size_t colon = head.find(':', format_key);
    const std::size_t open = colon == std::string::npos ? colon : head.find('"', colon);
    const std::size_t close = open == std::string::npos ? open : head.find('"', open + 1);
    return close == std::string::npos ? std::string() : head.substr(open + 1, close - open - 1);
}

// Files that write their keys sorted (diagnosis.json, labels.json) may
// declare their "format" after a long first array: when the head holds no
// "format" key, a JSON object is searched further (up to 64 MiB).
std::string declared_json_format_anywhere(const std::string& path, const std::string& head) {
    std::string format = declared_json_format(head);
    if (!format.empty() || head.size() < 4096) return format;
    const std::size_t start = head.find_first_not_of(" \t\r\n");
    if (start == std::string::npos || head[start] != '{') return format;
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec || size <= head.size()) return format;
    return declared_json_format(read_head(path, static_cast<std::size_t>(std::min<std::uintmax_t>(size, std::uintmax_t{64} << 20))));
}

// Why a file is not one flowvid reads: a JSON file declaring a format flowvid
// does not know is told which formats it does know.
Problem unrecognised_file(const std::string& path, const std::string& fix) {
    std::string format;
    std::error_code ec;
    if (!fs::is_directory(path, ec)) format = declared_json_format(read_head(path, 4096));
    if (!format.empty())
        return Problem{Problem::Severity::error, path, "/format", "\"" + format + "\" is not a format flowvid reads",
                       "flowvid's JSON formats are flowvid.fabric (fabric presets), flowvid.flowlines, "
                       "flowvid.capture (a capture folder's capture.json), flowvid.fit_shard, flowvid.diagnosis, "
                       "flowvid.gap_bench_labels, flowvid.rigid_fit, flowvid.rectification, flowvid.blender_cloth "
                       "(Blender cloth settings), flowvid.swatch_experiment and flowvid.swatch_frames"};
    return Problem{Problem::Severity::error, path, "", "not a flowvid file (unrecognised content)", fix};
}

}  // namespace

const char* file_kind_name(FileKind kind) {
    switch (kind) {
        case FileKind::fabric_preset: return "fabric preset";
        case FileKind::flowline_set: return "flow-line set";
        case FileKind::flowline_svg: return "flow lines (SVG)";
        case FileKind::particle_bank: return "particle texture bank";
        case FileKind::vertex_animation: return "vertex-animation EXR";
        case FileKind::motion_gltf: return "motion (glTF binary)";
        case FileKind::capture_folder: return "capture folder";
        case FileKind::fit_shard: return "fit shard";
        case FileKind::diagnosis: return "gap diagnosis";
        case FileKind::gap_bench_labels: return "gap-bench labels";
        case FileKind::rigid_fit: return "rigid fit";
        case FileKind::rectification: return "rectification";
        case FileKind::fabric_u3m: return "fabric preset (U3M)";
        case FileKind::fabric_usda: return "fabric preset (OpenUSD)";
        case FileKind::swatch_experiment: return "swatch experiment";
        case FileKind::swatch_frames: return "swatch frames";
        case FileKind::blender_cloth_settings: return "Blender cloth settings";
        case FileKind::unknown: break;
    }
    return "unknown";
}

FileKind detect_file_kind(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        return fs::exists(fs::path(path) / "capture.json") ? FileKind::capture_folder : FileKind::unknown;
    }
    if (!fs::exists(path, ec)) throw IoError(path, "", "no such file or folder", "check the path");
    const std::string head = read_head(path, 4096);
    if (head.size() >= 4 && static_cast<unsigned char>(head[0]) == 0x76 && static_cast<unsigned char>(head[1]) == 0x2f &&
        static_cast<unsigned char>(head[2]) == 0x31 && static_cast<unsigned char>(head[3]) == 0x01) {
        // OpenEXR magic: the bank is multi-part and says so in its attributes.
        return head.find("flowvid.particle_bank") != std::string::npos ? FileKind::particle_bank
                                                                       : FileKind::vertex_animation;
    }
    if (head.rfind("glTF", 0) == 0) return FileKind::motion_gltf;
    if (head.find("<svg") != std::string::npos || ends_with(path, ".svg")) return FileKind::flowline_svg;
    if (head.rfind("#usda 1.0", 0) == 0) return FileKind::fabric_usda;  // the only usda flowvid reads
    if (ends_with(path, ".u3m")) return FileKind::fabric_u3m;
    const FileKind declared = kind_from_json_format(declared_json_format_anywhere(path, head));
    if (declared != FileKind::unknown) return declared;
    if (ends_with(path, ".fabric.json")) return FileKind::fabric_preset;
    if (ends_with(path, ".flowlines.json")) return FileKind::flowline_set;
    if (ends_with(path, "capture.json")) return FileKind::capture_folder;
    if (ends_with(path, "diagnosis.json")) return FileKind::diagnosis;
    if (ends_with(path, "labels.json")) return FileKind::gap_bench_labels;
    if (ends_with(path, ".rigid_fit.json")) return FileKind::rigid_fit;
    if (ends_with(path, ".swatch_experiment.json")) return FileKind::swatch_experiment;
    if (ends_with(path, ".swatch_frames.json")) return FileKind::swatch_frames;
    if (ends_with(path, "rectify.json") || ends_with(path, ".rectification.json")) return FileKind::rectification;
    if (ends_with(path, ".blender.json")) return FileKind::blender_cloth_settings;
    if (ends_with(path, ".glb")) return FileKind::motion_gltf;
    return FileKind::unknown;
}

std::vector<Problem> validate_any_file(const std::string& path, Strictness strictness) {
    FileKind kind = FileKind::unknown;
    try {
        kind = detect_file_kind(path);
    } catch (const Error& error) {
        return {Problem{Problem::Severity::error, path, error.field(), "cannot read: " + error.message(), error.fix()}};
    }
    switch (kind) {
        case FileKind::fabric_preset: return validate_fabric_preset_file(path, strictness);
        case FileKind::fit_shard: return validate_fit_shard_file(path, strictness);
        case FileKind::flowline_set:
        case FileKind::flowline_svg: return validate_flowline_set_file(path, strictness);
        case FileKind::particle_bank: return validate_particle_bank_file(path, strictness);
        case FileKind::vertex_animation: return validate_vertex_animation_file(path, strictness);
        case FileKind::motion_gltf: return validate_motion_gltf_file(path, strictness);
        case FileKind::capture_folder: return validate_capture_folder(path, strictness);
        case FileKind::diagnosis: return validate_diagnosis_file(path, strictness);
        case FileKind::gap_bench_labels: return validate_gap_bench_labels_file(path, strictness);
        case FileKind::rigid_fit: return validate_rigid_fit_file(path, strictness);
        case FileKind::rectification: return validate_rectification_file(path, strictness);
        case FileKind::fabric_u3m: return validate_fabric_u3m_file(path, strictness);
        case FileKind::fabric_usda: return validate_fabric_usda_file(path, strictness);
        case FileKind::swatch_experiment: return validate_swatch_experiment_file(path, strictness);
        case FileKind::swatch_frames: return validate_swatch_frames_file(path, strictness);
        case FileKind::blender_cloth_settings: return validate_blender_cloth_settings_file(path, strictness);
        case FileKind::unknown: break;
    }
    return {unrecognised_file(path, "give a *.fabric.json, *.flowlines.json, flow-line SVG, bank or vertex-animation "
                                    "EXR, .glb, a capture folder, a fit shard, diagnosis.json, labels.json, a rigid fit, "
                                    "rectify.json, a fabric preset as .u3m or .usda, Blender "
                                    "cloth settings (*.blender.json), or a swatch experiment or its frames "
                                    "(*.swatch_experiment.json, *.swatch_frames.json)")};
}

nlohmann::json summarize_any_file(const std::string& path) {
    const FileKind kind = detect_file_kind(path);
    nlohmann::json summary;
    switch (kind) {
        case FileKind::fabric_preset: summary = summarize_fabric_preset(read_fabric_preset(path)); break;
        case FileKind::flowline_set: summary = summarize_flowline_set(read_flowline_set(path)); break;
        case FileKind::flowline_svg: summary = summarize_flowline_set(import_flowlines_svg(path)); break;
        case FileKind::particle_bank: summary = summarize_particle_bank(read_particle_bank(path)); break;
        case FileKind::vertex_animation: summary = summarize_vertex_animation(read_vertex_animation(path)); break;
        case FileKind::motion_gltf: summary = summarize_motion_gltf(read_motion_gltf(path)); break;
        case FileKind::capture_folder: summary = summarize_capture(read_capture(path)); break;
        case FileKind::fit_shard: summary = summarize_fit_shard(read_fit_shard(path)); break;
        case FileKind::diagnosis: summary = summarize_diagnosis(read_diagnosis(path)); break;
        case FileKind::gap_bench_labels: summary = summarize_gap_bench_labels(read_gap_bench_labels(path)); break;
        case FileKind::rigid_fit: summary = summarize_rigid_fit(read_rigid_fit(path)); break;
        case FileKind::rectification: summary = summarize_rectification(read_rectification(path)); break;
        case FileKind::fabric_u3m: summary = summarize_fabric_preset(read_fabric_u3m(path)); break;
        case FileKind::fabric_usda: summary = summarize_fabric_preset(read_fabric_usda(path)); break;
        case FileKind::swatch_experiment: summary = summarize_swatch_experiment(read_swatch_experiment(path)); break;
        case FileKind::swatch_frames: summary = summarize_swatch_frames(read_swatch_frames(path)); break;
        case FileKind::blender_cloth_settings:
            summary = summarize_blender_cloth_settings(read_blender_cloth_settings(path));
            break;
        case FileKind::unknown:
            throw ValidationError({unrecognised_file(path, "run 'flowvid validate' on it for details")});
    }
    summary["path"] = path;
    summary["kind"] = file_kind_name(kind);
    return summary;
}

FlowLineSet read_flowline_drawing(const std::string& path, std::vector<Problem>* warnings) {
    if (detect_file_kind(path) == FileKind::flowline_svg) return import_flowlines_svg(path, warnings);
    return read_flowline_set(path, warnings);
}

}  // namespace flowvid::formats
