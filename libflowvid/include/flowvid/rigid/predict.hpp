#pragma once
// What a rigid fit predicts, as `flowvid predict rigid` and the Python module
// run it: the fitted motion simulated forwards or backwards to any frames of
// the toss, its silhouettes written as masks, and, where the capture has
// masks, how well they agree (fit on the first frames, predict the rest to
// see how far the fit carries).

#include "flowvid/error.hpp"
#include "flowvid/progress.hpp"

#include <optional>
#include <string>
#include <vector>

namespace flowvid::rigid {

struct PredictRequest {
    std::string fit_path;      // fit.json written by `flowvid fit rigid`
    std::string capture_path;  // the rigid.toss capture (camera and body)
    int first_frame = 0;       // frames to predict, as capture.json numbers them (0: the capture's first ...
    int last_frame = 0;        // ... and last)
    std::string masks_folder;  // write each predicted silhouette as FOLDER/NNNNNN.png (255 = object); empty: none
};

struct PredictedFrame {
    int frame = 0;
    std::optional<double> iou;      // with the capture's mask, when it has masks
    std::optional<long long> xor_px;
};

struct PredictOutcome {
    std::vector<PredictedFrame> frames;
    bool compared = false;  // the capture has masks: the IoU figures below are measured
    double iou_mean = 0.0;
    double iou_min = 1.0;
    double iou_pooled = 1.0;  // intersection over union of all frames' pixels together
    int first_fitted_frame = 0;
    int last_fitted_frame = 0;
    std::vector<Problem> warnings;  // e.g. the fit was made on a capture.json with other content
};

// Progress: stage "predict" per frame. Throws the readers' errors, UsageError
// for frames outside the capture, IoError for a masks folder that cannot be
// written, and flowvid::Cancelled.
PredictOutcome predict_toss(const PredictRequest& request, const Progress& progress = {});

}  // namespace flowvid::rigid
