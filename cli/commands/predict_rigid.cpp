// flowvid predict rigid: render the silhouettes a rigid fit predicts (thesis fig. 2.6-2.7).

#include "commands/fit.hpp"
#include "output.hpp"

#include "flowvid/formats/capture.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/rigid/fit.hpp"
#include "flowvid/rigid/fit_file.hpp"
#include "flowvid/rigid/rectify.hpp"

#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct PredictRigidOptions {
    std::string fit;
    std::string capture;
    std::string out;
    std::string frames;
    bool json = false;
};

std::string numbered(const std::string& folder, int frame) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    return (std::filesystem::path(folder) / name).string();
}

int run_predict_rigid(const PredictRigidOptions& options, const GlobalOptions& global) {
    const rigid::RigidFitRecord record = rigid::read_rigid_fit(options.fit);
    const formats::Capture capture = formats::read_capture_of_kind(options.capture, {"rigid.toss"}, "flowvid predict rigid");
    if (!record.capture_json_sha256.empty() && record.capture_json_sha256 != capture.capture_json_sha256 && !global.quiet)
        log_message("warning: " + options.fit + ": fitted to a capture.json with other content than " + capture.json_path);
    const std::optional<std::pair<int, int>> frames = resolve_frames(options.frames, capture);
    if (!frames) return kExitUsage;
    std::error_code error;
    std::filesystem::create_directories(options.out, error);
    if (error) throw IoError(options.out, "", "cannot create the folder: " + error.message(), "choose a writable --out folder");

    const rigid::RigidBody body = rigid::RigidBody::from_capture(*capture.rigid);
    std::vector<int> numbers;
    for (int f = frames->first; f <= frames->second; ++f) numbers.push_back(f);
    const std::vector<metrics::Silhouette> predicted =
        rigid::predict_silhouettes(body, *capture.camera, record.as_fit_result(), numbers);

    ProgressBar progress(global, "predict rigid");
    std::unique_ptr<formats::FrameSource> source;
    if (!capture.masks.empty()) source = std::make_unique<formats::FrameSource>(capture);
    nlohmann::json per_frame = nlohmann::json::array();
    double mean_iou = 0.0, min_iou = 1.0;
    long long both = 0, either = 0;
    for (std::size_t i = 0; i < numbers.size(); ++i) {
        rigid::write_png(numbered(options.out, numbers[i]), metrics::silhouette_to_image(predicted[i]));
        if (source) {
            const metrics::Silhouette observed = metrics::silhouette_from_image(source->mask(numbers[i]));
            const double iou = metrics::silhouette_iou(predicted[i], observed);
            for (std::size_t p = 0; p < observed.pixels.size(); ++p) {
                both += observed.pixels[p] && predicted[i].pixels[p];
                either += observed.pixels[p] || predicted[i].pixels[p];
            }
            mean_iou += iou / static_cast<double>(numbers.size());
            min_iou = std::min(min_iou, iou);
            per_frame.push_back({{"frame", numbers[i]}, {"iou", iou}, {"xor_px", metrics::silhouette_xor(predicted[i], observed)}});
        }
        progress.update(static_cast<double>(i + 1) / static_cast<double>(numbers.size()));
    }
    progress.done();
    nlohmann::json summary = {{"masks", options.out},
                              {"frames", std::to_string(frames->first) + ":" + std::to_string(frames->second)},
                              {"fitted_frames", std::to_string(record.first_fitted_frame) + ":" + std::to_string(record.last_fitted_frame)}};
    if (source) {
        summary["iou_mean"] = mean_iou;
        summary["iou_min"] = min_iou;
        summary["iou_pooled"] = either ? static_cast<double>(both) / static_cast<double>(either) : 1.0;
        if (options.json) summary["per_frame"] = per_frame;
    }
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterPredictKind registration{FitKind{
    "rigid", "silhouettes of a fitted rigid-body motion at any frames", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<PredictRigidOptions>();
        app.footer(
            "Simulates the motion of a `flowvid fit rigid` result (forwards or backwards in time) and\n"
            "writes the predicted silhouette of each frame as OUT/NNNNNN.png (255 = object). When the\n"
            "capture has masks, prints the intersection over union with them per frame (--json) and\n"
            "overall: fit on the first frames, predict the rest to see how far the fit carries.\n\n"
            "Examples:\n"
            "  flowvid predict rigid --fit half.json --capture ../shared/captures/rigid-toss-major --out predicted/\n"
            "  flowvid predict rigid --fit half.json --capture toss/ --out predicted/ --frames 19:36 --json");
        app.add_option("--fit", options->fit, "a fit file written by `flowvid fit rigid`")->required();
        app.add_option("--capture", options->capture, "the capture folder (camera and body)")->required();
        app.add_option("--out", options->out, "folder for the predicted masks")->required();
        app.add_option("--frames", options->frames, "frames A:B to predict (inclusive; default all)");
        app.add_flag("--json", options->json, "print the summary as JSON, with per-frame IoU");
        return [options](const GlobalOptions& global) { return run_predict_rigid(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
