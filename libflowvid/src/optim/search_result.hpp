#pragma once
// How every search (annealing, CMA-ES) closes its result. Private to optim.

#include "flowvid/optim/annealing.hpp"

#include <cmath>

namespace flowvid::optim::detail {

// Status (no_finite_value when nothing finite was found, whatever stopped
// the run), reason, and the best point in unit-cube and parameter values.
inline void close_result(AnnealingResult& result, AnnealingResult::Status status, const Eigen::VectorXd& best_unit,
                         double best_value, const ParameterSpace& space) {
    if (!std::isfinite(best_value)) {
        status = AnnealingResult::Status::no_finite_value;
        result.reason = "no evaluated point gave a finite value";
    }
    result.status = status;
    if (result.reason.empty() && status != AnnealingResult::Status::converged) result.reason = status_name(status);
    result.best_unit = best_unit;
    result.best_values = space.to_values(best_unit);
    result.best_value = best_value;
}

}  // namespace flowvid::optim::detail
