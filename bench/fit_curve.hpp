#pragma once
// The convergence curve of a cloth fit, read from its outcome (the design's
// values, the search's stages, the polish), for the fit benchmarks.

#include "flowvid/cloth_fit/fit_cloth.hpp"

#include <algorithm>
#include <limits>
#include <vector>

namespace flowvid::bench {

namespace cf = flowvid::cloth_fit;

struct CurvePoint {
    long long evaluations = 0;
    double best = 0.0;
};

// Best error after each evaluation count: the design's points in order, then
// the search's stages (or generations), then the polish's accepted steps.
inline std::vector<CurvePoint> curve_of(const cf::ClothFitOutcome& outcome) {
    std::vector<CurvePoint> curve;
    double best = std::numeric_limits<double>::infinity();
    long long evaluations = 0;
    // A design cut short by its time budget skipped its last points (+inf, not evaluated).
    const long long design = outcome.search.evaluations - outcome.search.annealing.evaluations;
    for (double value : outcome.search.design.values) {
        if (evaluations == design) break;
        ++evaluations;
        best = std::min(best, value);
        curve.push_back({evaluations, best});
    }
    for (const flowvid::optim::AnnealingStage& stage : outcome.search.annealing.history)
        curve.push_back({design + stage.evaluations, std::min(best, stage.best_value)});
    if (outcome.polish) {
        const long long searched = outcome.search.evaluations;
        curve.push_back({searched + outcome.polish->evaluations, std::min(curve.back().best, outcome.polish->best_value)});
    }
    return curve;
}

}  // namespace flowvid::bench
