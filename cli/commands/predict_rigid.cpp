// flowvid predict rigid: render the silhouettes a rigid fit predicts (thesis fig. 2.6-2.7).

#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/formats/capture.hpp"
#include "flowvid/rigid/predict.hpp"

#include <iostream>
#include <optional>

namespace flowvid::cli {
namespace {

struct PredictRigidOptions {
    std::string fit;
    std::string capture;
    std::string out;
    FrameOptions frames;
    bool json = false;
};

int run_predict_rigid(const PredictRigidOptions& options, const GlobalOptions& global) {
    const formats::Capture capture = formats::read_capture_of_kind(options.capture, {"rigid.toss"}, "flowvid predict rigid");
    const std::pair<int, int> frames = resolve_capture_frames(options.frames, capture);
    rigid::PredictRequest request;
    request.fit_path = options.fit;
    request.capture_path = options.capture;
    request.first_frame = frames.first;
    request.last_frame = frames.second;
    request.masks_folder = options.out;
    std::optional<TerminalProgress> progress;
    progress.emplace(global, "predict rigid");
    const rigid::PredictOutcome outcome = rigid::predict_toss(request, progress->callback());
    progress.reset();
    if (!global.quiet) print_problems(outcome.warnings);
    nlohmann::json summary = {{"masks", options.out},
                              {"frames", std::to_string(frames.first) + ":" + std::to_string(frames.second)},
                              {"fitted_frames", std::to_string(outcome.first_fitted_frame) + ":" +
                                                    std::to_string(outcome.last_fitted_frame)}};
    if (outcome.compared) {
        summary["iou_mean"] = outcome.iou_mean;
        summary["iou_min"] = outcome.iou_min;
        summary["iou_pooled"] = outcome.iou_pooled;
        if (options.json) {
            nlohmann::json per_frame = nlohmann::json::array();
            for (const rigid::PredictedFrame& f : outcome.frames)
                per_frame.push_back({{"frame", f.frame}, {"iou", *f.iou}, {"xor_px", *f.xor_px}});
            summary["per_frame"] = per_frame;
        }
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
        add_frame_options(app, options->frames, "frames A to B to predict (inclusive, numbered as in capture.json)", "the first N frames", "all");
        app.add_flag("--json", options->json, "print the summary as JSON, with per-frame IoU");
        return [options](const GlobalOptions& global) { return run_predict_rigid(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
