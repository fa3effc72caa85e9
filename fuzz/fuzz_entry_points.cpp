#include "fuzz_entry_points.hpp"

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/blender_cloth_settings.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/diagnosis.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fit_shard.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/gap_bench_labels.hpp"
#include "flowvid/formats/rectification.hpp"
#include "flowvid/formats/rigid_fit.hpp"
#include "flowvid/formats/rigid_mesh.hpp"
#include "flowvid/formats/swatch_experiment.hpp"
#include "flowvid/formats/swatch_frames.hpp"
#include "flowvid/formats/vertex_animation.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <unistd.h>

#ifndef FLOWVID_FUZZ_FIXTURE_DIR
#define FLOWVID_FUZZ_FIXTURE_DIR ""
#endif

namespace flowvid::fuzz {
namespace fs = std::filesystem;

const std::vector<FuzzTarget>& fuzz_targets() {
    static const std::vector<FuzzTarget> targets = {
        {"fabric_json", "input.fabric.json", InputKind::json, "fabric preset (*.fabric.json)"},
        {"flowlines_json", "input.flowlines.json", InputKind::json, "flow-line set (*.flowlines.json)"},
        {"flowlines_svg", "input.svg", InputKind::svg, "flow lines drawn in SVG"},
        {"capture_json", "capture.json", InputKind::json, "capture folder (capture.json, files checked)"},
        {"particle_bank", "input.bank.exr", InputKind::exr, "particle texture bank (multi-part EXR)"},
        {"vertex_animation", "input.exr", InputKind::exr, "vertex-animation EXR (also a capture's truth/tracks)"},
        {"motion_gltf", "input.glb", InputKind::glb, "motion glTF binary (.glb)"},
        {"fit_shard", "input.fit_shard.json", InputKind::json, "fit shard (flowvid merge)"},
        {"truth_json", "truth.json", InputKind::json, "a capture's truth/truth.json (cloth grid; rigid state as a guess)"},
        {"rigid_mesh", "body.glb", InputKind::glb, "a rigid capture's mesh (.glb)"},
        {"rigid_fit", "input.rigid_fit.json", InputKind::json, "rigid fit (fit.json) and --guess files"},
        {"rectification", "rectify.json", InputKind::json, "rectification (rectify.json)"},
        {"diagnosis_json", "diagnosis.json", InputKind::json, "gap diagnosis (diagnosis.json)"},
        {"gap_bench_labels", "labels.json", InputKind::json, "gap-bench labels (labels.json)"},
        {"swatch_experiment", "input.swatch_experiment.json", InputKind::json, "swatch experiment (flowvid swatch --experiment)"},
        {"swatch_frames", "input.swatch_frames.json", InputKind::json, "swatch frames (flowvid swatch --out)"},
        {"blender_cloth", "input.blender.json", InputKind::json, "Blender cloth settings (*.blender.json, flowvid convert)"},
    };
    return targets;
}

const FuzzTarget* find_fuzz_target(const std::string& name) {
    for (const FuzzTarget& target : fuzz_targets())
        if (target.name == name) return &target;
    return nullptr;
}

namespace {

// One private folder per process (libFuzzer's -jobs and parallel ctest runs
// each get their own), removed at exit.
const fs::path& scratch_root() {
    static const fs::path root = [] {
        const fs::path path = fs::temp_directory_path() / ("flowvid-fuzz-" + std::to_string(::getpid()));
        fs::create_directories(path);
        std::atexit([] {
            std::error_code ec;
            fs::remove_all(fs::temp_directory_path() / ("flowvid-fuzz-" + std::to_string(::getpid())), ec);
        });
        return path;
    }();
    return root;
}

void write_bytes(const fs::path& path, const std::uint8_t* data, std::size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
}

// The truth every truth.json input goes with: 3 frames of a 2 x 3 grid.
formats::VertexAnimation fixture_animation() {
    formats::VertexAnimation animation;
    animation.frame_count = 3;
    animation.vertex_count = 6;
    for (int f = 0; f < 3; ++f)
        for (int v = 0; v < 6; ++v)
            animation.positions_m.emplace_back(0.1f * static_cast<float>(v % 3), 0.0f, 1.0f - 0.1f * static_cast<float>(v / 3) - 0.01f * f);
    return animation;
}

// A capture folder holding the files capture.json inputs refer to (those of
// tests/data/formats/capture/*: frames, masks, background, mesh, clip, SVG),
// plus truth/positions.exr and tracks.exr, so that content checks run.
fs::path capture_folder() {
    static const fs::path folder = [] {
        const fs::path path = scratch_root() / "capture";
        fs::create_directories(path / "truth");
        std::error_code ec;
        const fs::path fixtures = FLOWVID_FUZZ_FIXTURE_DIR;
        if (!fixtures.empty()) {
            for (const char* sub : {"tiny-cloth", "tiny-rigid", "tiny-video"}) {
                for (const auto& entry : fs::directory_iterator(fixtures / sub, ec)) {
                    if (entry.path().filename() == "capture.json") continue;
                    fs::copy(entry.path(), path / entry.path().filename(),
                             fs::copy_options::recursive | fs::copy_options::skip_existing, ec);
                }
            }
        }
        formats::write_vertex_animation((path / "truth" / "positions.exr").string(), fixture_animation());
        formats::write_vertex_animation((path / "tracks.exr").string(), fixture_animation());
        return path;
    }();
    return folder;
}

template <typename Function>
void tolerate_flowvid_errors(Function&& function) {
    try {
        function();
    } catch (const Error&) {
        // The documented way to refuse an input.
    }
}

// What a successful read leads to elsewhere in flowvid.
void use_flowlines(const formats::FlowLineSet& set) {
    formats::flowline_set_to_json(set);
    formats::flowline_set_to_text(set);
    formats::flowline_set_to_svg(set);
    formats::summarize_flowline_set(set);
    std::size_t lookups = 0;
    for (const std::vector<formats::FlowLine>* lines : {&set.inputs, &set.outputs}) {
        for (const formats::FlowLine& line : *lines) {
            const std::vector<Eigen::Vector2d> points =
                line.is_time_varying() ? formats::points_at_frame(line, line.keys.front().frame + 0.5) : line.points;
            const double length = formats::polyline_length(points);
            formats::cumulative_arc_lengths(points);
            if (!points.empty()) formats::point_at_arc_length(points, 0.5 * length);
            // find_input_line is a linear search (fine for what one drawing holds): a few
            // lookups, not one per output line, or the harness itself would be quadratic.
            if (!line.from.empty() && ++lookups <= 16) formats::find_input_line(set, line.from);
        }
    }
}

std::size_t run_any_file(const std::string& subject) {
    const std::size_t problems = formats::validate_any_file(subject, formats::Strictness::strict).size();
    tolerate_flowvid_errors([&] { formats::summarize_any_file(subject); });
    return problems;
}

std::size_t run_target(const FuzzTarget& target, const std::uint8_t* data, std::size_t size) {
    const fs::path folder = target.name == "capture_json" ? capture_folder() : scratch_root() / target.name;
    fs::create_directories(folder);
    const fs::path path = folder / target.file_name;
    const std::string file = path.string();

    if (target.name == "truth_json") {
        // read_capture_truth_positions reads truth/truth.json beside truth/positions.exr.
        static const fs::path capture = [&] {
            fs::create_directories(folder / "truth");
            formats::write_vertex_animation((folder / "truth" / "positions.exr").string(), fixture_animation());
            return folder;
        }();
        write_bytes(capture / "truth" / "truth.json", data, size);
        formats::Capture fixture;
        fixture.folder = capture.string();
        fixture.json_path = (capture / "capture.json").string();
        fixture.kind = "cloth.static";
        fixture.fps = 30.0;
        fixture.frames.pattern = "frames/%06d.png";
        fixture.frames.count = 3;
        std::size_t problems = 0;
        try {
            formats::read_capture_truth_positions(fixture);
        } catch (const Error&) {
            problems = 1;
        }
        // A rigid.toss capture's truth.json is what `flowvid fit rigid --guess` reads.
        tolerate_flowvid_errors([&] { formats::read_rigid_fit_guess((capture / "truth" / "truth.json").string()); });
        return problems;
    }

    write_bytes(path, data, size);
    if (target.name == "capture_json") {
        // A capture.json is validated as its folder, the way users name captures.
        const std::size_t problems = run_any_file(folder.string());
        tolerate_flowvid_errors([&] {
            const formats::Capture capture = formats::read_capture(folder.string());
            formats::capture_to_json(capture);
            tolerate_flowvid_errors([&] { formats::read_capture_tracks(capture); });
            tolerate_flowvid_errors([&] { formats::read_capture_truth_positions(capture); });
        });
        return problems;
    }
    if (target.name == "fit_shard") {
        // Told apart by its "format" only: fuzz the reader itself too.
        const std::size_t problems = formats::validate_fit_shard_file(file, formats::Strictness::strict).size();
        run_any_file(file);
        tolerate_flowvid_errors([&] {
            const formats::FitShard shard = formats::read_fit_shard(file);
            formats::fit_shard_to_json(shard);
            formats::summarize_fit_shard(shard);
            // `flowvid merge` of this shard with itself as the other shards.
            std::vector<formats::FitShardFile> set = {{file, shard}};
            for (int index = 1; index <= shard.count && index <= 4; ++index) {
                if (index == shard.index) continue;
                formats::FitShard other = shard;
                other.index = index;
                set.push_back({file + "#" + std::to_string(index), other});
            }
            formats::check_fit_shard_set(set);
        });
        return problems;
    }
    if (target.name == "rigid_mesh") {
        // A .glb is a motion file to validate_any_file; a capture reads it as a mesh.
        const std::size_t problems = formats::validate_rigid_mesh_file(file, formats::Strictness::strict).size();
        tolerate_flowvid_errors([&] {
            const formats::TriangleMesh mesh = formats::read_rigid_mesh(file);
            formats::mesh_volume(mesh);
            formats::summarize_rigid_mesh(mesh);
        });
        return problems;
    }

    const std::size_t problems = run_any_file(file);
    if (target.name == "flowlines_json" || target.name == "flowlines_svg") {
        // flowvid.flow.read_flowline_set (Python) and the flow tools read this way.
        tolerate_flowvid_errors([&] { use_flowlines(formats::read_flowline_drawing(file)); });
    } else if (target.name == "fabric_json") {
        // flowvid.formats.read_fabric_preset (Python) returns this.
        tolerate_flowvid_errors([&] { formats::fabric_preset_to_json(formats::read_fabric_preset(file)); });
    } else if (target.name == "rigid_fit") {
        // `flowvid predict rigid` and `flowvid rectify` read it; `fit rigid --guess` reads it as a guess.
        tolerate_flowvid_errors([&] { formats::rigid_fit_to_json(formats::read_rigid_fit(file)); });
        tolerate_flowvid_errors([&] { formats::read_rigid_fit_guess(file); });
    } else if (target.name == "rectification") {
        tolerate_flowvid_errors([&] { formats::rectification_to_json(formats::read_rectification(file)); });
    } else if (target.name == "gap_bench_labels") {
        tolerate_flowvid_errors([&] { formats::gap_bench_labels_to_json(formats::read_gap_bench_labels(file)); });
    } else if (target.name == "swatch_experiment") {
        // What was read is written back the way the writer writes it (validated, strictly).
        tolerate_flowvid_errors([&] {
            const formats::SwatchExperimentFile experiment = formats::read_swatch_experiment(file);
            formats::summarize_swatch_experiment(experiment);
            formats::write_swatch_experiment((folder / "written.swatch_experiment.json").string(), experiment);
        });
    } else if (target.name == "swatch_frames") {
        tolerate_flowvid_errors([&] {
            const formats::SwatchFramesFile frames = formats::read_swatch_frames(file);
            formats::summarize_swatch_frames(frames);
            formats::write_swatch_frames((folder / "written.swatch_frames.json").string(), frames);
        });
    } else if (target.name == "blender_cloth") {
        // What was read is written back the way `flowvid convert` writes it (validated, strictly).
        tolerate_flowvid_errors([&] {
            const formats::BlenderClothSettings settings = formats::read_blender_cloth_settings(file);
            formats::blender_cloth_settings_to_json(settings);
            formats::summarize_blender_cloth_settings(settings);
            formats::write_blender_cloth_settings((folder / "written.blender.json").string(), settings);
        });
    }
    return problems;
}

}  // namespace

std::size_t fuzz_one_input(const FuzzTarget& target, const std::uint8_t* data, std::size_t size) {
    return run_target(target, data, size);
}

}  // namespace flowvid::fuzz
