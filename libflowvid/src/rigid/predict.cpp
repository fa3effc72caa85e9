#include "flowvid/rigid/predict.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/rigid/fit.hpp"
#include "flowvid/rigid/fit_file.hpp"
#include "flowvid/rigid/rectify.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace flowvid::rigid {

namespace {

std::string numbered(const std::string& folder, int frame) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    return (std::filesystem::path(folder) / name).string();
}

}  // namespace

PredictOutcome predict_toss(const PredictRequest& request, const Progress& progress) {
    PredictOutcome out;
    const RigidFitRecord record = read_rigid_fit(request.fit_path);
    const formats::Capture capture = formats::read_capture_of_kind(request.capture_path, {"rigid.toss"}, "flowvid predict rigid");
    if (!record.capture_json_sha256.empty() && record.capture_json_sha256 != capture.capture_json_sha256)
        out.warnings.push_back({Problem::Severity::warning, request.fit_path, "/capture_json_sha256",
                                "fitted to a capture.json with other content than " + capture.json_path,
                                "fit that capture again if it has changed"});
    const int first = request.first_frame > 0 ? request.first_frame : capture.frames.first;
    const int last = request.last_frame > 0 ? request.last_frame : capture.frames.last();
    if (first < capture.frames.first || last > capture.frames.last() || first > last)
        throw UsageError(capture.json_path, "frames",
                         "frames " + std::to_string(first) + ":" + std::to_string(last) + " are not within the capture's " +
                             std::to_string(capture.frames.first) + ":" + std::to_string(capture.frames.last()),
                         "predict frames the capture has");
    if (!request.masks_folder.empty()) formats::create_parent_folder(numbered(request.masks_folder, first));
    out.first_fitted_frame = record.first_fitted_frame;
    out.last_fitted_frame = record.last_fitted_frame;

    const RigidBody body = RigidBody::from_capture(*capture.rigid);
    std::vector<int> numbers;
    for (int f = first; f <= last; ++f) numbers.push_back(f);
    const std::vector<metrics::Silhouette> predicted = predict_silhouettes(body, *capture.camera, record.as_fit_result(), numbers);
    std::unique_ptr<formats::FrameSource> source;
    if (!capture.masks.empty()) source = std::make_unique<formats::FrameSource>(capture);
    out.compared = source != nullptr;
    long long both = 0, either = 0;
    for (std::size_t i = 0; i < numbers.size(); ++i) {
        if (!request.masks_folder.empty())
            write_png(numbered(request.masks_folder, numbers[i]), metrics::silhouette_to_image(predicted[i]));
        PredictedFrame frame;
        frame.frame = numbers[i];
        if (source) {
            const metrics::Silhouette observed = metrics::silhouette_from_image(source->mask(numbers[i]));
            const double iou = metrics::silhouette_iou(predicted[i], observed);
            for (std::size_t p = 0; p < observed.pixels.size(); ++p) {
                both += observed.pixels[p] && predicted[i].pixels[p];
                either += observed.pixels[p] || predicted[i].pixels[p];
            }
            out.iou_mean += iou / static_cast<double>(numbers.size());
            out.iou_min = std::min(out.iou_min, iou);
            frame.iou = iou;
            frame.xor_px = metrics::silhouette_xor(predicted[i], observed);
        }
        out.frames.push_back(frame);
        report_progress(progress, "predict", static_cast<double>(i + 1) / static_cast<double>(numbers.size()));
    }
    if (source) out.iou_pooled = either ? static_cast<double>(both) / static_cast<double>(either) : 1.0;
    return out;
}

}  // namespace flowvid::rigid
