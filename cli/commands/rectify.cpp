// flowvid rectify: warp footage so that gravity points straight down (thesis fig. 2.8).

#include "command.hpp"
#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/formats/rectification.hpp"
#include "flowvid/rigid/fit_file.hpp"
#include "flowvid/rigid/rectify.hpp"

#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

namespace fs = std::filesystem;

struct RectifyOptions {
    std::string fit;
    std::string capture;
    std::string out;
    FrameOptions frames;
    bool json = false;
};

std::string numbered(const fs::path& folder, int frame) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    return (folder / name).string();
}

nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
        nlohmann::json row = nlohmann::json::array();
        for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
        rows.push_back(row);
    }
    return rows;
}

void make_folder(const fs::path& folder) {
    std::error_code error;
    fs::create_directories(folder, error);
    if (error) throw IoError(folder.string(), "", "cannot create the folder: " + error.message(), "choose a writable --out folder");
}

int run_rectify(const RectifyOptions& options, const GlobalOptions& global) {
    const rigid::RigidFitRecord record = rigid::read_rigid_fit(options.fit);
    const formats::Capture capture = formats::read_capture(options.capture);
    if (!capture.camera)
        throw ValidationError({Problem{Problem::Severity::error, capture.json_path, "/camera",
                                       "rectification needs the camera calibration", "add the \"camera\" block"}});
    const std::pair<int, int> frames = resolve_capture_frames(options.frames, capture);
    const rigid::Rectification rectification = rigid::roll_rectification(*capture.camera, record.initial.gravity);

    const fs::path out(options.out);
    make_folder(out / "frames");
    formats::FrameSource source(capture);
    if (source.has_masks()) make_folder(out / "masks");
    ProgressBar progress(global, "rectify");
    const int count = frames.second - frames.first + 1;
    for (int f = frames.first; f <= frames.second; ++f) {
        rigid::write_png(numbered(out / "frames", f), rigid::rectify_image(source.frame(f), rectification));
        if (source.has_masks()) rigid::write_png(numbered(out / "masks", f), rigid::rectify_image(source.mask(f), rectification, true));
        progress.update(static_cast<double>(f - frames.first + 1) / count);
    }
    progress.done();

    // The rectified footage as a capture of its own: same intrinsics, camera rolled about its axis.
    nlohmann::json document = formats::capture_to_json(capture);
    document["frames"] = {{"pattern", "frames/%06d.png"}, {"first", frames.first}, {"count", count}};
    if (source.has_masks()) document["masks"] = "masks/%06d.png";
    if (source.has_background()) {
        rigid::write_png((out / "background.png").string(), rigid::rectify_image(source.background(), rectification));
        document["background"] = "background.png";
    }
    Eigen::Matrix4d rolled = Eigen::Matrix4d::Identity();
    rolled.topLeftCorner<3, 3>() = rectification.rotation;
    document["camera"]["camera_from_world"] = matrix_json(rolled * capture.camera->camera_from_world);
    if (capture.rigid) {
        const fs::path mesh = capture.resolve(capture.rigid->mesh);
        const std::string bytes = formats::read_text_file(mesh.string());
        formats::write_file_atomically((out / mesh.filename()).string(), [&](std::ostream& s) { s << bytes; });
        document["rigid"]["mesh"] = mesh.filename().string();
    }
    const std::string capture_text = formats::dump_json(document);
    formats::write_file_atomically((out / "capture.json").string(), [&](std::ostream& s) { s << capture_text; });
    // What was done, as a flowvid.rectification file (formats/specs/rectification.md).
    formats::write_rectification((out / "rectify.json").string(),
                                 rigid::rectification_file(rectification, record.initial.gravity, options.fit));

    const nlohmann::json summary = {{"out", options.out},
                                    {"frames", std::to_string(frames.first) + ":" + std::to_string(frames.second)},
                                    {"roll_deg", rectification.roll_rad * 180.0 / M_PI}};
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterCommand registration{Command{
    "rectify", "straighten footage so that gravity points down, using a rigid fit", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<RectifyOptions>();
        app.footer(
            "Rotates every frame (and mask and background) about the principal point by the gravity roll\n"
            "angle of a `flowvid fit rigid` result, so that gravity points straight down the image\n"
            "(thesis fig. 2.8). Tilt (pitch) is not corrected. Writes OUT/frames/NNNNNN.png, OUT/masks/,\n"
            "OUT/background.png, OUT/capture.json (the rectified footage as a capture: same intrinsics,\n"
            "camera rolled) and OUT/rectify.json (the roll angle and the pixel homography; format\n"
            "flowvid.rectification, formats/specs/rectification.md).\n\n"
            "Examples:\n"
            "  flowvid rectify --fit fit.json --capture ../shared/captures/rigid-toss-major --out straight/\n"
            "  flowvid rectify --fit fit.json --capture rolled-shot/ --out straight/ --frames 1:120");
        app.add_option("--fit", options->fit, "a fit file written by `flowvid fit rigid`")->required();
        app.add_option("--capture", options->capture, "the capture folder to straighten (same camera)")->required();
        app.add_option("--out", options->out, "output folder")->required();
        add_frame_options(app, options->frames, "frames A to B to straighten (inclusive, numbered as in capture.json)", "the first N frames", "all");
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_rectify(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
