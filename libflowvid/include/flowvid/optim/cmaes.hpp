#pragma once
// CMA-ES, the covariance matrix adaptation evolution strategy (Hansen's
// (mu/mu_w, lambda) form with rank-one and rank-mu updates and cumulative
// step-size adaptation, written here from the published description): every
// generation samples `population` points from N(m, sigma^2 C), evaluates
// them as one parallel batch, moves the mean to the weighted mean of the
// best half and adapts C and sigma to the steps that paid off.
//
// Why it is here: a cloth fit's simulations cost seconds each, and the
// simplex of the annealing moves one point at a time. CMA-ES learns the
// scales and correlations of the fabric parameters (bending against drag,
// say) from every generation and evaluates a generation on all cores at
// once; on the cloth fits it reaches the annealing's final error in fewer
// simulations (bench/bench_cloth_search.cpp, docs/cloth_fitting.md "Search").
//
// It searches the unit cube of a ParameterSpace. A sample outside the cube
// is reflected back into it (and the reflected point is what the update
// sees), so every evaluated point is feasible.
//
// Determinism: samples come from the seed only (a portable generator), and
// a generation's values do not depend on which thread evaluated which
// point: the same seed gives bit-identical results for any thread count.

#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/objective.hpp"

#include <Eigen/Core>

#include <atomic>
#include <cstdint>
#include <limits>

namespace flowvid::optim {

struct CmaesSettings {
    std::uint64_t seed = 1;
    int population = 0;            // lambda; 0: 4 + floor(3 ln n)
    double initial_sigma = 0.2;    // step size, unit-cube units
    double step_tolerance = 1e-7;  // stop when sigma times the largest axis of C is below this (unit cube)
    double tolerance = 1e-10;      // ... or a generation's values and the best differ by less than this, relatively
    long long max_evaluations = 20000;  // the last generation is cut to what is left
    double budget_seconds = 0.0;        // wall-clock limit, 0 = none; a generation that cannot finish is not started
    // Wall seconds of one round of a batch (one point per thread), until the
    // run has measured its own: a generation of lambda points costs
    // ceil(lambda / threads) rounds.
    double evaluation_seconds_hint = 0.0;
    // After every generation: stage "cmaes", the fraction done and
    // "N evaluations, best V, sigma s, ETA s"; false cancels. The
    // generations themselves are in AnnealingResult::history.
    Progress progress;
    const std::atomic<bool>* cancel = nullptr;
};

// One CMA-ES run from the mean `start_unit` (unit cube), whose value is
// `start_value` when known (NaN: evaluated first). Fills the result shape
// the annealing uses: `stages` and `history` count generations (temperature
// there: sigma), `iterations` too, `resets` is 0.
AnnealingResult cmaes(Evaluator& evaluator, const Eigen::VectorXd& start_unit, const CmaesSettings& settings,
                      double start_value = std::numeric_limits<double>::quiet_NaN());

}  // namespace flowvid::optim
