#pragma once
// report.html of `flowvid diagnose`: a diagnosis (flowvid.diagnosis, version 1,
// the JSON the diagnosis writes beside it) rendered as one self-contained page.

#include <nlohmann/json.hpp>

#include <string>

namespace flowvid::cli {

// The page, top to bottom: a verdict box (gap or not, the named effect or
// "unexplained", the equivalence-class note, the fraction of the held-out gap
// closed), the model, per trial the residual over time (error, floor, error
// with the named effect, the driver -- pin or body speed -- on a second axis,
// held-out frames shaded), the residual maps, the residual spectrum, the
// ablation of every candidate (ranked chart and table), the fitted effect
// parameters and how the base parameters moved.
//
// Every part but the verdict is optional: a diagnosis without maps, spectrum,
// candidates, refits or a named effect renders without those sections, and a
// missing or mistyped value shows as a dash rather than failing (the report is
// written after a long run; it must not lose the run over one odd value).
std::string diagnosis_report_html(const nlohmann::json& diagnosis);

}  // namespace flowvid::cli
