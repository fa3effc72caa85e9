#include "bindings.hpp"

#include "flowvid/rigid/predict.hpp"

#include <pybind11/stl.h>

namespace py = pybind11;

namespace flowvid::python {

namespace {

// flowvid predict rigid, in process (rigid::predict_toss).
py::object predict(const std::string& fit, const std::string& capture, const std::pair<int, int>& frames,
                   const std::string& masks, const py::object& progress) {
    rigid::PredictRequest request;
    request.fit_path = fit;
    request.capture_path = capture;
    request.first_frame = frames.first;
    request.last_frame = frames.second;
    request.masks_folder = masks;
    const Progress report = progress_from_python(progress);
    rigid::PredictOutcome outcome;
    {
        py::gil_scoped_release release;
        outcome = rigid::predict_toss(request, report);
    }
    py::dict result;
    py::list per_frame;
    for (const rigid::PredictedFrame& f : outcome.frames) {
        py::dict frame;
        frame["frame"] = f.frame;
        frame["iou"] = f.iou ? py::object(py::float_(*f.iou)) : py::none();
        frame["xor_px"] = f.xor_px ? py::object(py::int_(*f.xor_px)) : py::none();
        per_frame.append(frame);
    }
    result["frames"] = per_frame;
    result["iou_mean"] = outcome.compared ? py::object(py::float_(outcome.iou_mean)) : py::none();
    result["iou_min"] = outcome.compared ? py::object(py::float_(outcome.iou_min)) : py::none();
    result["iou_pooled"] = outcome.compared ? py::object(py::float_(outcome.iou_pooled)) : py::none();
    result["fitted_frames"] = py::make_tuple(outcome.first_fitted_frame, outcome.last_fitted_frame);
    py::list warnings;
    for (const Problem& w : outcome.warnings) warnings.append(text_to_python(w.to_string()));
    result["warnings"] = warnings;
    return result;
}

}  // namespace

void bind_rigid(py::module_& module) {
    py::module_ rigid_module = module.def_submodule("rigid", "Rigid bodies: what a fitted toss predicts");
    rigid_module.def("predict", &predict, py::arg("fit"), py::arg("capture"), py::arg("frames") = std::pair<int, int>{0, 0},
                     py::arg("masks") = "", py::arg("progress") = py::none(),
                     R"(The silhouettes a rigid fit predicts, as `flowvid predict rigid` (rigid::predict_toss).

fit: fit.json from `flowvid fit rigid`; capture: the rigid.toss capture; frames: (first, last) as
capture.json numbers them ((0, 0): all); masks: also write each predicted silhouette as
masks/NNNNNN.png. Returns {"frames": [{"frame", "iou", "xor_px"}], "iou_mean", "iou_min",
"iou_pooled" (None without the capture's masks), "fitted_frames", "warnings"}.)");
}

}  // namespace flowvid::python
